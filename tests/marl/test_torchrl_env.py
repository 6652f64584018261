"""The TorchRL-native batched env (`tavc_env.adapters.torchrl_env`): TorchRL's spec check, the
plain env's trajectories arena by arena, seeding, partial resets and a plain `Collector`
(marker `marl`: needs the `marl` extra)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tavc_env.arena import make_env

pytestmark = pytest.mark.marl
torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from torchrl.collectors import Collector  # noqa: E402
from torchrl.envs.utils import check_env_specs  # noqa: E402

from tavc_env.adapters.torchrl_env import GROUP, TorchArenaEnv  # noqa: E402

KWARGS: dict[str, Any] = {"scenario": "bad_start", "reward": "value", "max_sim_time_s": 300.0}


def first_deciders(td: Any) -> Any:
    """A policy for `rollout`: every robot picks circuit 0 (only deciders' actions are read)."""
    td[GROUP, "action"] = torch.zeros_like(td[GROUP, "index"])
    return td


def test_torchrl_accepts_the_specs_and_a_rollout_matches_the_spec_shapes() -> None:
    env = TorchArenaEnv(3, env_kwargs=KWARGS, seed=0)
    check_env_specs(env)
    td = env.rollout(50, first_deciders, break_when_any_done=False)
    n, m = env.n_robots, env.n_circuits
    assert td[GROUP, "action_mask"].shape == (3, 50, n, m)
    assert td["next", GROUP, "reward"].shape == (3, 50, n, 1)
    assert td["state"].shape == (3, 50, env.envs[0].state_space.shape[0])
    # every row has a decider (event-driven steps), and a decider may choose every circuit
    decides = td[GROUP, "decides"]
    assert decides.any(-1).all()
    assert td[GROUP, "action_mask"][decides].all()
    assert (td[GROUP, "action_mask"][~decides].sum(-1) == 1).all()


def test_each_arena_is_the_plain_env_seeded_with_its_spawned_seed() -> None:
    """Arena k follows the plain env reset with SeedSequence(seed).spawn(K)[k], step for step,
    through a time-limit end and the partial reset that follows it."""
    K, steps = 2, 120
    env = TorchArenaEnv(K, env_kwargs=KWARGS, seed=7)
    td = env.rollout(steps, first_deciders, break_when_any_done=False)
    assert td["next", "done"].any(), "the episode is short enough to end within the rollout"
    seeds = [int(c.generate_state(1)[0]) for c in np.random.SeedSequence(7).spawn(K)]
    for k in range(K):
        plain = make_env(observation_mode="paper_id", **KWARGS)
        obs, infos = plain.reset(seed=seeds[k])
        for t in range(steps):
            row = td[k, t]
            expected = np.stack([o["observation"] for o in obs.values()])
            np.testing.assert_array_equal(row[GROUP, "observation"].numpy(), expected)
            np.testing.assert_array_equal(row["state"].numpy(), plain.state())
            actions = {a: 0 for a in plain.agents if infos[a]["action_required"]}
            obs, rewards, _, truncations, infos = plain.step(actions)
            reward = np.array(list(rewards.values()), np.float32)
            np.testing.assert_array_equal(row["next", GROUP, "reward"][:, 0].numpy(), reward)
            elapsed = np.array([i["elapsed_s"] for i in infos.values()], np.float32)
            np.testing.assert_array_equal(row["next", GROUP, "elapsed_s"][:, 0].numpy(), elapsed)
            assert bool(row["next", "truncated"]) == any(truncations.values())
            if not plain.agents:  # reset as the env resets it: continuing its own generator
                obs, infos = plain.reset()


def test_the_final_step_marks_only_robots_that_delivered_as_at_an_epoch() -> None:
    """A limit of 25 steps ends each episode in a step that ended with a delivery (a time limit
    almost never does: a step stops at the first delivery)."""
    env = TorchArenaEnv(
        2, env_kwargs={**KWARGS, "max_sim_time_s": 3600.0, "max_cycles": 25}, seed=1
    )
    td = env.rollout(100, first_deciders, break_when_any_done=False)
    ended = td["next", "done"][..., 0]
    final, other = td["next"][ended], td["next"][~ended]
    assert len(final) == 8
    assert not final[GROUP, "decides"].any()  # nobody decides at a time limit
    delivered = final[GROUP, "reward"][..., 0] > 0
    assert (final[GROUP, "epoch"] == delivered).all() and delivered.any()
    assert (other[GROUP, "epoch"] == other[GROUP, "decides"]).all()
    after = td[:, 1:][td["next", "done"][:, :-1, 0]]  # the row after an end: a fresh episode
    assert after[GROUP, "decides"].all() and (after[GROUP, "elapsed_s"] == 0).all()


def test_a_plain_collector_runs_it_and_the_same_seed_gives_the_same_batches() -> None:
    def batches(seed: int) -> list[Any]:
        env = TorchArenaEnv(2, env_kwargs=KWARGS, seed=seed)
        collector = Collector(env, first_deciders, frames_per_batch=2 * 40, total_frames=2 * 80)
        out = [data.clone() for data in collector]
        collector.shutdown()
        return out

    a, b, c = batches(3), batches(3), batches(4)
    assert len(a) == 2 and a[0].batch_size == (2, 40)
    for x, y in zip(a, b):
        assert (x["next", GROUP, "observation"] == y["next", GROUP, "observation"]).all()
    assert not all(
        (x["next", GROUP, "elapsed_s"] == z["next", GROUP, "elapsed_s"]).all() for x, z in zip(a, c)
    )


def test_bad_arguments_are_refused_naming_the_value() -> None:
    with pytest.raises(ValueError, match="n_envs = 0"):
        TorchArenaEnv(0, env_kwargs=KWARGS)
    with pytest.raises(ValueError, match="observation_format"):
        TorchArenaEnv(1, env_kwargs={**KWARGS, "observation_format": "box"})
    with pytest.raises(ValueError, match="seed"):
        TorchArenaEnv(1, env_kwargs=KWARGS, seed=-1)


def test_an_out_of_range_action_of_a_deciding_robot_is_refused_before_any_arena_moves() -> None:
    env = TorchArenaEnv(2, env_kwargs=KWARGS, seed=0)
    td = env.reset()
    times = [e.sim_time_s for e in env.envs]
    td[GROUP, "action"] = torch.zeros_like(td[GROUP, "index"])
    td[GROUP, "action"][1, 2] = env.n_circuits  # every robot decides at reset
    with pytest.raises(ValueError, match=r"actions\[1, 2\] = 2.*\[0, 1\]"):
        env.step(td)
    assert [e.sim_time_s for e in env.envs] == times
