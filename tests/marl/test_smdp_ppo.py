"""PPO on the semi-MDP contract (`tavc_agents.learners.smdp_ppo`): the advantages by hand on a
tiny sequence, busy rows out of the loss, settings refused with their value, and a short training
run whose network the trial runner drives (marker `marl`: needs the `marl` extra)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

pytestmark = pytest.mark.marl
torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from tavc_agents.learners import smdp_ppo  # noqa: E402
from tavc_agents.learners.network import NetworkTeam  # noqa: E402
from tavc_env.adapters.torchrl_env import GROUP, TorchArenaEnv  # noqa: E402

KWARGS: dict[str, Any] = {"scenario": "bad_start", "reward": "value", "max_sim_time_s": 600.0}


def tiny_sequences(settings: smdp_ppo.PpoSettings) -> tuple[Any, Any]:
    """Two arenas of one robot each, five env steps (`(K=2, T=5, n=1)`).

    Arena 0: decisions at rows 0 and 3; the first ends after step 2 (30 min, reward 2), the
    second after step 4 (1 h, reward 3), the last step of the batch: it bootstraps from the
    value of the observation after it (4). Arena 1: decisions at rows 0 and 1 (the first ends
    after step 0: 10 min, reward 1); the episode ends at its time limit after step 2, where the
    robot delivered (20 min, reward 5): it bootstraps from its final observation's value (10);
    the new episode's decision at row 3 has no outcome in the batch."""
    decides = torch.tensor([[1, 0, 0, 1, 0], [1, 1, 0, 1, 0]], dtype=torch.bool)
    next_epoch = torch.tensor([[0, 0, 1, 0, 1], [1, 0, 1, 0, 0]], dtype=torch.bool)
    done = torch.tensor([[0, 0, 0, 0, 0], [0, 0, 1, 0, 0]], dtype=torch.bool)
    reward = torch.tensor([[0, 0, 2, 0, 3], [1, 0, 5, 0, 0]], dtype=torch.float64)
    next_elapsed = torch.tensor([[600, 1200, 1800, 900, 3600], [600, 600, 1200, 300, 600.0]])
    value = torch.tensor([[1, 9, 9, 2, 9], [0, 1, 9, 7, 9]], dtype=torch.float64)
    next_value = torch.tensor([[9, 9, 9, 9, 4], [9, 9, 10, 9, 9]], dtype=torch.float64)
    discount, step = smdp_ppo.discounts(next_elapsed.unsqueeze(-1).double(), settings)
    return smdp_ppo.smdp_gae(
        reward.unsqueeze(-1),
        value.unsqueeze(-1),
        next_value.unsqueeze(-1),
        decides.unsqueeze(-1),
        next_epoch.unsqueeze(-1),
        done.unsqueeze(-1),
        discount,
        step,
        lmbda=0.5,
    )


def test_the_semi_mdp_advantages_equal_the_hand_computed_ones() -> None:
    advantage, rows = tiny_sequences(smdp_ppo.PpoSettings(gamma_h=0.25, discount="time"))
    # arena 0: decision 1: 3 + 0.25 ** 1 * 4 - 2 = 2 (bootstrap: A_next = 0);
    # decision 0: delta = 2 + 0.25 ** 0.5 * 2 - 1 = 2, A = 2 + 0.5 * 0.5 * 2 = 2.5
    # arena 1: decision 1: 5 + 0.25 ** (1/3) * 10 - 1; decision 0: 1 + 0.25 ** (1/6) * 1 - 0,
    # plus 0.25 ** (1/6) * 0.5 * A_1
    a1 = 5 + 0.25 ** (1 / 3) * 10 - 1
    a0 = 1 + 0.25 ** (1 / 6) * 1 - 0 + 0.25 ** (1 / 6) * 0.5 * a1
    expected = torch.tensor([[2.5, 0, 0, 2, 0], [a0, a1, 0, 0, 0]], dtype=torch.float64)
    assert torch.allclose(advantage[..., 0], expected, atol=1e-6)
    assert rows[..., 0].tolist() == [[1, 0, 0, 1, 0], [1, 1, 0, 0, 0]]
    assert math.isclose(float(advantage[1, 1, 0]), 10.2996, abs_tol=1e-4)


def test_discounting_per_env_step_gives_other_advantages() -> None:
    """The same sequences discounted per env step (gamma 0.25 a step): arena 0's first decision
    lasts three steps (0.25 ** 3), not half an hour (0.25 ** 0.5), its second two steps (0.25 ** 2),
    not an hour (0.25); the hand values above fail."""
    advantage, _ = tiny_sequences(smdp_ppo.PpoSettings(gamma_step=0.25, discount="step"))
    a1 = 3 + 0.25**2 * 4 - 2
    assert math.isclose(float(advantage[0, 3, 0]), a1)
    assert math.isclose(float(advantage[0, 0, 0]), 2 + 0.25**3 * 2 - 1 + 0.25**3 * 0.5 * a1)
    assert not math.isclose(float(advantage[0, 0, 0]), 2.5)


def collected(settings: smdp_ppo.PpoSettings, seed: int = 0) -> tuple[Any, Any]:
    """One collector batch of a small run, with the learner it was collected by."""
    torch.manual_seed(seed)
    env = TorchArenaEnv(settings.n_envs, env_kwargs=KWARGS, seed=seed)
    learner = smdp_ppo.make_learner(env, settings)
    with torch.no_grad():
        data = env.rollout(settings.steps_per_batch, learner.actor, break_when_any_done=False)
    return data, learner


def loss_of(rows: Any, learner: Any) -> float:
    torch.manual_seed(0)  # the entropy is a sampled estimate
    out = learner.loss(rows)
    return float((out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]).detach())


def test_busy_rows_do_not_affect_the_loss() -> None:
    """Scrambling every busy row (observation, mask, action, log-probability) leaves the rows
    trained on and the loss as they were; with `rows="all"` (busy rows in) the loss changes."""
    for rows_setting, unchanged in (("decisions", True), ("all", False)):
        s = smdp_ppo.PpoSettings(n_envs=2, steps_per_batch=60, rows=rows_setting)
        data, learner = collected(s)
        before = smdp_ppo.training_rows(data, learner, s)
        busy = ~data[GROUP, "decides"]
        assert busy.any()
        scrambled = data.clone()
        robots = scrambled[GROUP]
        robots["observation"][busy] = torch.rand_like(robots["observation"][busy])
        robots["action_mask"][busy] = True
        robots["action"][busy] = 1 - robots["action"][busy]
        robots["sample_log_prob"][busy] = -3.0
        after = smdp_ppo.training_rows(scrambled, learner, s)
        same = len(after) == len(before) and math.isclose(
            loss_of(before, learner), loss_of(after, learner), rel_tol=1e-6
        )
        assert same == unchanged, rows_setting


def short_trial(team: NetworkTeam) -> Any:
    """Five simulated minutes of `bad_start` driven by `team` (the trial runner's result)."""
    from tavc_agents.experiments.runner import run_trial

    return run_trial(
        team,
        seed=10_000,
        convergence_s=0.0,
        measured_s=300.0,
        snapshot_every_s=300.0,
        arena={"scenario": "bad_start"},
    )


def test_a_short_run_trains_and_its_network_drives_a_trial() -> None:
    s = smdp_ppo.PpoSettings(n_envs=4, steps_per_batch=50, epochs=2, minibatch=64)
    torch.manual_seed(0)
    env = TorchArenaEnv(s.n_envs, env_kwargs=KWARGS, seed=0)
    seen: list[smdp_ppo.Progress] = []
    learner, progress = smdp_ppo.train(env, s, 600, lambda p, _: seen.append(p))
    assert progress.decisions >= 600 and len(seen) >= 2
    assert progress.steps == len(seen) * s.n_envs * s.steps_per_batch
    before = [p.detach().clone() for p in learner.actor_net.parameters()]
    assert any(float(p.abs().sum()) > 0 for p in before)
    mlp = smdp_ppo.network(learner.actor_net)
    assert mlp.group_of is None  # shared: saved as one network, as before sets existed
    x = torch.eye(8)[:4]  # some paper_id-wide inputs
    logits = learner.actor_net(x, torch.zeros(4, dtype=torch.int64)).detach().numpy()
    np.testing.assert_allclose(mlp.mlps[0].scores(x.numpy()), logits, atol=1e-5)
    assert short_trial(NetworkTeam(mlp, readout="sampled")) is not None


def test_per_class_parameters_route_each_robot_to_its_speed_class() -> None:
    env = TorchArenaEnv(1, env_kwargs=KWARGS, seed=0)
    speeds = [r.speed for r in env.config.robots]
    groups = smdp_ppo.groups_of(env, "class")
    assert len(set(groups)) == len(set(speeds)) >= 2
    assert all(
        (groups[i] == groups[j]) == (speeds[i] == speeds[j]) for i in range(6) for j in range(6)
    )
    net = smdp_ppo.ParameterSets(8, 2, groups, hidden=16)
    x = torch.rand(3, 6, 8)
    index = torch.arange(6).expand(3, 6)
    out = net(x, index)
    for i in range(6):
        np.testing.assert_allclose(
            out[:, i].detach(), net.mlps[groups[i]](x[:, i]).detach(), atol=1e-6
        )
    exported = smdp_ppo.network(net)
    assert exported.group_of == tuple(groups)
    for i in range(6):
        np.testing.assert_allclose(
            exported.mlp_of(i).scores(x[:, i].numpy()), out[:, i].detach(), atol=1e-5
        )


def test_a_short_per_class_run_exports_a_network_set_that_drives_a_trial(tmp_path: Any) -> None:
    """Smoke size: `parameters="class"` trained a few batches, its sets saved as one file, loaded
    and run by the trial runner, each robot through its class's set as the torch actor does."""
    from tavc_agents.learners.network import NetworkSet

    s = smdp_ppo.PpoSettings(
        parameters="class", n_envs=2, steps_per_batch=40, epochs=1, minibatch=64
    )
    torch.manual_seed(0)
    env = TorchArenaEnv(s.n_envs, env_kwargs=KWARGS, seed=0)
    learner, progress = smdp_ppo.train(env, s, 200)
    assert progress.decisions >= 200
    path = smdp_ppo.network(learner.actor_net).save(tmp_path / "class.npz")
    loaded = NetworkSet.load(path, n_inputs=8, n_outputs=2)
    groups = smdp_ppo.groups_of(env, "class")
    assert loaded.group_of == tuple(groups) and len(loaded.mlps) == len(set(groups)) >= 2
    x = torch.cat([torch.eye(2)[[0, 1, 0, 1, 0, 1]], torch.eye(6)], -1)  # robot i's input
    logits = learner.actor_net(x, torch.arange(6)).detach().numpy()
    for i in range(6):
        np.testing.assert_allclose(loaded.mlp_of(i).scores(x[i].numpy()), logits[i], atol=1e-5)
    assert short_trial(NetworkTeam(path, readout="sampled")) is not None


@pytest.mark.parametrize(
    ("field", "value"),
    [("algorithm", "qmix"), ("gamma_h", 0.0), ("gamma_h", 1.5), ("n_envs", 0), ("rows", "some")],
)
def test_bad_settings_are_refused_naming_the_value(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"{field} = "):
        smdp_ppo.PpoSettings(**{field: value})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "changes",
    [
        {"algorithm": "ippo", "parameters": "robot"},
        {"parameters": "class", "credit": "team"},
        {"discount": "step", "rows": "all"},
    ],
)
def test_every_variant_trains_a_few_batches(changes: dict[str, Any]) -> None:
    """Each variant's updates change the actor it starts from (the same first draw of torch's
    generator as `make_learner` here)."""
    s = smdp_ppo.PpoSettings(n_envs=2, steps_per_batch=30, epochs=1, minibatch=32, **changes)
    env = TorchArenaEnv(2, env_kwargs=KWARGS, seed=0, with_state=s.algorithm == "mappo")
    torch.manual_seed(0)
    initial = [p.detach().clone() for p in smdp_ppo.make_learner(env, s).actor_net.parameters()]
    torch.manual_seed(0)
    learner, progress = smdp_ppo.train(env, s, 100)
    assert progress.decisions >= 100
    trained = list(learner.actor_net.parameters())
    assert all(a.shape == b.shape for a, b in zip(trained, initial))
    assert any(not torch.equal(a.detach(), b) for a, b in zip(trained, initial))
