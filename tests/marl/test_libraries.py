"""The arena through each deep MARL library's own adapter, with no user wrapper, taking learning
steps; the package's adapters; and the shipped examples at a small size (marker `marl`: needs the
`marl` extra, skipped where a library is missing)."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_agents.learners.network import Mlp
from tavc_agents.learning_runs import RunOptions, write_learning_run
from tests.docs.test_examples import load as example

pytestmark = pytest.mark.marl
SMALL = RunOptions(eval_every=1, eval_hours=0.2, final_seeds=2)  # two checkpoints, two seeds


def paper_id_inputs(n_robots: int = 6, n_circuits: int = 2) -> np.ndarray:
    """Every `paper_id` observation: each last circuit for each robot."""
    rows = [
        np.concatenate([np.eye(n_circuits)[c], np.eye(n_robots)[i]])
        for c, i in itertools.product(range(n_circuits), range(n_robots))
    ]
    return np.asarray(rows, np.float32)


def log_softmax(x: np.ndarray) -> np.ndarray:
    x = x - x.max(axis=-1, keepdims=True)
    return x - np.log(np.exp(x).sum(axis=-1, keepdims=True))


def assert_same_policy(mlp: Mlp, library_logits: np.ndarray, x: np.ndarray) -> None:
    """The exported network gives the library's action distribution on every input."""
    np.testing.assert_allclose(log_softmax(mlp.scores(x)), log_softmax(library_logits), atol=1e-5)


def check_run(run: Any, checkpoints: int) -> None:
    assert len(run.curve) == checkpoints + 1 and run.final  # (+ the untrained network)
    for row in run.curve:
        assert 0.0 < row.evaluation.performance < 1.0
        assert 0.0 <= row.evaluation.fast_share <= 1.0


# -- TorchRL -------------------------------------------------------------------------------------
def test_torchrl_wrapper_takes_the_env_as_it_is_and_mappo_learns(tmp_path: Path) -> None:
    pytest.importorskip("torchrl")
    import torch
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    env = PettingZooWrapper(tavc_env.parallel_env(), categorical_actions=True, seed=0)
    data = env.rollout(20)
    assert data["next", "robot", "reward"].shape == (20, 6, 1)
    assert data["robot", "action_mask"].dtype == torch.bool
    assert data["next", "robot", "info", "phase"].dtype == torch.float32  # the infos, as tensors

    mappo = example("torchrl_mappo")
    run = mappo.train(updates=2, batch=200, options=SMALL)
    check_run(run, 2)
    # the export gives the actor's distribution (checked on a fresh actor)
    actor_env = mappo.make_env(0)
    _, _, actor_net = mappo.make_mappo(actor_env)
    x = paper_id_inputs()
    with torch.no_grad():
        logits = actor_net(torch.as_tensor(x).reshape(2, 6, 8)).reshape(12, 2).numpy()
    assert_same_policy(mappo.network(actor_net), logits, x)
    files = write_learning_run(run, tmp_path)
    assert {p.name for p in files} >= {"curve.csv", "curve.png", "evaluation.md", "network.npz"}
    saved = Mlp.load(tmp_path / "network.npz")
    assert all(map(np.array_equal, saved.weights, run.mlp.weights))
    assert np.array_equal(saved.scores(x), run.mlp.scores(x))


# -- RLlib ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ray_session() -> Any:
    ray = pytest.importorskip("ray")
    pytest.importorskip("ray.rllib")
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    yield ray
    ray.shutdown()


def test_rllib_own_pettingzoo_adapter_trains_ppo_on_the_box_observation(ray_session: Any) -> None:
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
    from ray.tune.registry import register_env

    kwargs = {"observation_mode": "paper_id", "observation_format": "box", "max_sim_time_s": 1800.0}
    register_env("tavc_box", lambda _: ParallelPettingZooEnv(tavc_env.parallel_env(**kwargs)))
    config = (
        PPOConfig()
        .environment("tavc_box")
        .env_runners(num_env_runners=0, rollout_fragment_length=100)
        .multi_agent(policies={"shared"}, policy_mapping_fn=lambda agent, *a, **k: "shared")
        .training(train_batch_size_per_learner=200, minibatch_size=100, num_epochs=1)
    )
    algo = config.build_algo()
    result = algo.train()
    assert result["learners"]["shared"]["num_module_steps_trained"] > 0
    algo.stop()


def test_rllib_deciders_only_adapter_and_example(ray_session: Any) -> None:
    import torch

    from tavc_env.adapters.rllib import RllibArenaEnv

    env = RllibArenaEnv({"max_sim_time_s": 900.0, "observation_mode": "paper_id"})
    obs, _ = env.reset(seed=1)
    assert set(obs) == set(env.possible_agents)  # everybody decides at the start
    assert set(obs["robot_0"]) == {"observations", "action_mask"}
    steps = 0
    while True:
        obs, rewards, _, truncs, _ = env.step(dict.fromkeys(obs, 0))
        steps += 1
        assert set(rewards) == set(obs)
        if truncs["__all__"]:
            assert set(obs) == set(env.possible_agents)  # a last observation for every robot
            break
        assert 0 < len(obs) < 6 or steps == 1
    ppo = example("rllib_ppo")
    run = ppo.train(iterations=2, batch=200, options=SMALL)
    check_run(run, 2)
    # the export gives the policy module's distribution (checked on a fresh module)
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    module = RLModuleSpec(
        module_class=ppo.ActionMaskingTorchRLModule,
        observation_space=env.observation_spaces["robot_0"],
        action_space=env.action_spaces["robot_0"],
        model_config=ppo.MODEL,
    ).build()
    x = paper_id_inputs()
    batch = {"obs": {"observations": torch.as_tensor(x), "action_mask": torch.ones(12, 2)}}
    with torch.no_grad():
        logits = module.forward_inference(batch)["action_dist_inputs"].numpy()
    assert_same_policy(ppo.network(module), logits, x)


# -- Stable-Baselines3 -----------------------------------------------------------------------------
def test_supersuit_recipe_trains_sb3_ppo_on_the_box_observation() -> None:
    pytest.importorskip("stable_baselines3")
    ss = pytest.importorskip("supersuit")
    from stable_baselines3 import PPO

    env = tavc_env.parallel_env(
        observation_mode="paper_id", observation_format="box", max_sim_time_s=1800.0
    )
    venv = ss.concat_vec_envs_v1(
        ss.pettingzoo_env_to_vec_env_v1(env), 1, base_class="stable_baselines3"
    )
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, verbose=0)
    model.learn(total_timesteps=384)
    assert model.num_timesteps >= 384


def test_sb3_shared_policy_vec_env_masks_and_the_maskable_ppo_example(tmp_path: Path) -> None:
    pytest.importorskip("sb3_contrib")
    import torch

    from tavc_env.adapters.sb3 import SharedPolicyVecEnv

    venv = SharedPolicyVecEnv(n_envs=2, observation_mode="paper_id", max_sim_time_s=600.0)
    venv.seed(5)
    obs = venv.reset()
    assert obs.shape == (12, 8) and venv.action_masks().all()  # everyone decides at the start
    masks = venv.env_method("action_masks")
    assert len(masks) == 12 and masks[0].dtype == bool
    ends = 0
    for _ in range(200):
        _, _, dones, infos = venv.step(np.zeros(12, np.int64))
        for slot in np.flatnonzero(dones):  # (the copies' episodes end at different steps)
            ends += 1
            assert infos[slot]["TimeLimit.truncated"]
            assert infos[slot]["terminal_observation"].shape == (8,)
    assert ends >= 1
    with pytest.raises(ValueError, match="observation_format = 'dict' is invalid"):
        SharedPolicyVecEnv(observation_format="dict")

    sb3 = example("sb3_maskable_ppo")
    run = sb3.train(updates=2, options=SMALL)
    check_run(run, 2)
    x = paper_id_inputs()
    model = sb3.MaskablePPO("MlpPolicy", SharedPolicyVecEnv(observation_mode="paper_id"), seed=0)
    with torch.no_grad():
        logits = model.policy.get_distribution(torch.as_tensor(x)).distribution.logits.numpy()
    assert_same_policy(sb3.network(model), logits, x)


# -- the CleanRL-style semi-MDP example (PyTorch only) -----------------------------------------------
def test_cleanrl_smdp_ippo_trains_and_prints_its_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("torch")
    import torch

    ippo = example("cleanrl_smdp_ippo")
    settings = ippo.Settings(
        total_hours=0.5,
        rollout_hours=0.25,
        eval_hours=0.2,
        eval_seeds=(1, 2),
        out=tmp_path / "t.md",
    )
    agent, table = ippo.train(settings)
    printed = capsys.readouterr().out
    assert "update 2/2" in printed and table in printed
    assert (tmp_path / "t.md").read_text() == table + "\n"
    rows = {
        cells[0]: [float(c) for c in cells[1:]]
        for line in table.split("\n\n")[1].splitlines()[2:]
        for cells in [[c.strip() for c in line.strip("|").split("|")]]
    }
    assert set(rows) == {"random", "stay", "static (model optimum)", "ippo greedy", "ippo sampled"}
    assert all(np.isfinite(v).all() for v in rows.values())
    assert rows["random"][2] == 0.0 and rows["static (model optimum)"][2] == 1.0
    assert 300_000 < rows["stay"][0] < 700_000  # value / h of six robots
    assert all(torch.isfinite(p).all() for p in agent.parameters())
    assert table.count("| robot_") == 12  # the policy, by robot and last circuit
    assert ippo.train(settings)[1] == table  # seeded: the same run again
    with pytest.raises(ValueError, match=r"^rollout_hours = 2\.0 is invalid; allowed: at most"):
        ippo.Settings(total_hours=1.0, rollout_hours=2.0)
