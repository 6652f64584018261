"""The single-robot view in Gymnasium's registry: `gymnasium.make` and `gymnasium.make_vec` (sync
and async, fork and spawn) build it, the autoreset mode is declared, its infos suit
`RecordEpisodeStatistics`, same seed gives the same arrays whether vectorised in this process or in
workers, the env pickles mid-episode, and registering again is a no-op or a clear error."""

from __future__ import annotations

import pickle

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers.vector import RecordEpisodeStatistics

from tavc_agents.envs.single_robot import SingleRobotEnv
from tavc_env.registration import (
    SINGLE_ROBOT_ENTRY_POINT,
    SINGLE_ROBOT_IDS,
    register_single_robot_envs,
)

GYM_ID = "tavc/dahl2004-v0"
SHORT_S = 600.0  # an episode of about 7 learner steps


def rollout(envs: gymnasium.vector.VectorEnv, seed: int, steps: int) -> list[np.ndarray]:
    obs, infos = envs.reset(seed=seed)
    out = [obs, *(np.asarray(infos[k]) for k in sorted(infos))]
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, rewards, terminated, truncated, infos = envs.step(rng.integers(0, 2, envs.num_envs))
        out += [obs, rewards, terminated, truncated]
        # (nested dicts: Gymnasium's "episode" and the env's "episode_statistics")
        out += [np.asarray(infos[k]) for k in sorted(infos) if not isinstance(infos[k], dict)]
    return out


def test_the_id_is_registered_with_the_single_robot_view() -> None:
    assert GYM_ID in SINGLE_ROBOT_IDS
    spec = gymnasium.spec(GYM_ID)
    assert spec.entry_point == SINGLE_ROBOT_ENTRY_POINT and spec.kwargs == {"scenario": "dahl2004"}
    env = gymnasium.make(GYM_ID, episode_s=SHORT_S)
    assert isinstance(env.unwrapped, SingleRobotEnv)
    assert env.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_registering_again_is_a_no_op_and_a_clash_is_refused() -> None:
    register_single_robot_envs(SINGLE_ROBOT_IDS)
    with pytest.raises(ValueError, match=r"gymnasium id 'tavc/dahl2004-v0' = .* is invalid"):
        register_single_robot_envs({GYM_ID: {"preset": "dahl2004_homogeneous"}})
    assert gymnasium.spec(GYM_ID).kwargs == {"scenario": "dahl2004"}


@pytest.mark.parametrize(
    ("mode", "vector_kwargs"),
    [("sync", {}), ("async", {}), ("async", {"context": "spawn"})],
    ids=["sync", "async-fork", "async-spawn"],
)
def test_make_vec_resets_steps_and_autoresets(mode: str, vector_kwargs: dict[str, str]) -> None:
    envs = gymnasium.make_vec(
        GYM_ID, 2, vectorization_mode=mode, vector_kwargs=vector_kwargs, episode_s=SHORT_S
    )
    envs = RecordEpisodeStatistics(envs)  # refuses infos that are not a dict of arrays
    assert envs.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    obs, infos = envs.reset(seed=0)
    assert obs.shape == (2, 2) and obs.dtype == np.float32
    assert infos["action_required"].tolist() == [True, True]
    ended = np.zeros(2, bool)
    episodes = 0
    for _ in range(40):
        obs, rewards, terminated, truncated, infos = envs.step(np.array([0, 1]))
        # NEXT_STEP: the step after an episode's end is its reset (reward 0, time 0)
        assert (rewards[ended] == 0).all() and (infos["sim_time_s"][ended] == 0).all()
        ended = terminated | truncated
        if "episode" in infos:
            episodes += int(infos["_episode"].sum())
            assert (infos["episode"]["r"][infos["_episode"]] > 0).all()
    assert episodes >= 4
    envs.close()


def test_sync_and_async_give_the_same_arrays() -> None:
    sync = gymnasium.make_vec(GYM_ID, 2, vectorization_mode="sync", episode_s=SHORT_S)
    workers = gymnasium.make_vec(GYM_ID, 2, vectorization_mode="async", episode_s=SHORT_S)
    expected, found = rollout(sync, 4, 20), rollout(workers, 4, 20)
    again = rollout(sync, 4, 20)
    sync.close()
    workers.close()
    assert len(found) == len(expected)
    assert all(np.array_equal(a, b) for a, b in zip(found, expected))
    assert all(np.array_equal(a, b) for a, b in zip(again, expected))


def test_the_env_pickles_mid_episode() -> None:
    env = SingleRobotEnv(episode_s=SHORT_S)
    env.reset(seed=2)
    env.step(0)
    twin = pickle.loads(pickle.dumps(env))
    for action in (1, 0, 1):
        mine, theirs = env.step(action), twin.step(action)
        assert np.array_equal(mine[0], theirs[0]) and mine[1:] == theirs[1:]


def test_a_reset_without_seed_continues_the_seeded_run() -> None:
    """Autoreset calls `reset()` without a seed: the episodes after a seeded one repeat too."""
    env, twin = SingleRobotEnv(episode_s=SHORT_S), SingleRobotEnv(episode_s=SHORT_S)
    env.reset(seed=9)
    twin.reset(seed=9)
    first, _ = env.reset()
    again, _ = twin.reset()
    assert np.array_equal(first, again)
    assert [env.step(1)[1] for _ in range(4)] == [twin.step(1)[1] for _ in range(4)]


def test_every_scenario_has_its_single_robot_view_in_gymnasium() -> None:
    # the same ids as in PettingZoo's registry; the episode is the scenario's unless given
    from tavc_env import SCENARIOS

    for scenario in SCENARIOS.values():
        env = gymnasium.make(scenario.id)
        assert env.unwrapped.env.scenario == scenario
        assert env.unwrapped.env.options.max_sim_time_s == scenario.episode_s
        env.close()
    short = gymnasium.make("tavc/priority_shifts-v0", episode_s=SHORT_S)
    observation, _ = short.reset(seed=0)
    assert short.unwrapped.env.value_plan == () or short.unwrapped.env.value_plan[0][0] > 0
    short.step(int(np.argmax(observation)))
    short.close()
