"""The ecosystem examples in docs/examples run, at a small size, and do what they say: SuperSuit
vectorisation, the AEC view and its conversion back, and a researcher's own agent through the
`Policy` protocol and the trial runner."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from tavc_agents.policy import Policy

EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"


def load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # (dataclasses look their module up while it loads)
    spec.loader.exec_module(module)
    return module


def test_supersuit_vectorises_every_robot_of_every_arena() -> None:
    pytest.importorskip("supersuit", reason="the example needs SuperSuit (in the dev extra)")
    example = load("supersuit_vectorised")
    venv = example.make_vector_env(arenas=2, hours=0.1)
    obs, _ = venv.reset(seed=3)
    assert obs["observation"].shape == (12, 2) and obs["action_mask"].shape == (12, 2)
    venv.close()
    out = example.run(steps=60, seed=0)
    assert out["sub_envs"] == 12 and out["reward"] > 0.0
    assert example.run(steps=60, seed=0) == out  # seeded: the same run again


def test_aec_loop_and_conversion_back_to_parallel() -> None:
    example = load("aec_view")
    totals = example.run_aec(hours=0.25, seed=0)
    assert sorted(totals) == [f"robot_{i}" for i in range(6)]
    assert all(total > 0.0 for total in totals.values())  # every robot delivered something
    assert example.round_trip_agents() == [f"robot_{i}" for i in range(6)]


def test_own_agent_follows_the_protocol_and_learns_from_rewards() -> None:
    example = load("own_agent")
    robot = example.UcbRobot(bonus=0.0)
    assert isinstance(robot, Policy)
    robot.reset(np.random.default_rng(0), 2)
    everything, busy_on_1 = np.array([1, 1], np.int8), np.array([0, 1], np.int8)
    obs = np.array([1.0, 0.0], np.float32)
    assert robot.act(obs, everything) == 0  # untried circuits first
    robot.update(obs, 0, 0.03, obs, {})
    assert robot.act(obs, everything) == 1
    robot.update(obs, 1, 0.05, obs, {})
    assert robot.act(obs, everything) == 1  # then the better mean (no bonus)
    assert robot.act(obs, busy_on_1) == 1  # and never what the mask forbids
    values = example.compare(hours=1.5, seed=0)
    assert set(values) == {"ucb1", "softmax_tavc"} and all(v > 0.05 for v in values.values())


@pytest.mark.marl
def test_tianshou_dqn_learns_to_prefer_the_high_value_circuit() -> None:
    """Opt-in: runs only where Tianshou and PyTorch are installed (see the example's docstring);
    about 2 minutes. Its committed output: docs/examples/tianshou_dqn_output.txt."""
    pytest.importorskip("tianshou", reason="Tianshou is not installed (an opt-in example)")
    example = load("tianshou_dqn")
    shares = example.train(seed=0)
    print(shares)
    assert shares["high_value_share_after"] >= 0.9
