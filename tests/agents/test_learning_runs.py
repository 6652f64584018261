"""Learning runs without a deep-learning library: options, and what a network learned."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tavc_agents.learners.network import Mlp, NetworkTeam
from tavc_agents.learning_runs import LearningRun, RunOptions, what_it_learned
from tavc_env import make_config


def linear(weight: np.ndarray) -> Mlp:
    return Mlp((weight,), (np.zeros(weight.shape[0]),))


def test_what_a_network_learned_is_read_off_its_whole_policy() -> None:
    run = LearningRun("demo", "demo", {"preset": "dahl2004"}, {})
    # scores = the one-hot of the last circuit: every robot stays
    run.mlp = linear(np.hstack([np.eye(2), np.zeros((2, 6))]))
    assert "Every robot stays" in what_it_learned(run)
    # robots 0-2 (fast) score circuit 0, robots 3-5 (slow) circuit 1, whatever they served
    by_id = np.zeros((2, 8))
    by_id[0, 2:5] = 1.0
    by_id[1, 5:8] = 1.0
    run.mlp = linear(by_id)
    assert "Circuits chosen by class: fast: [0]; slow: [1]." in what_it_learned(run)


def test_a_network_team_checks_its_inputs_and_acts_greedily(tmp_path: Path) -> None:
    mlp = linear(np.hstack([np.eye(2), np.zeros((2, 6))]))
    path = mlp.save(tmp_path / "network.npz")
    team = NetworkTeam(str(path))
    policies = team.policies([f"robot_{i}" for i in range(6)], make_config("dahl2004"))
    robot = policies["robot_4"]
    robot.reset(np.random.default_rng(0), 2)
    assert robot.act(np.array([0.0, 1.0]), np.ones(2, np.int8)) == 1
    assert robot.act(np.array([0.0, 1.0]), np.array([1, 0], np.int8)) == 0  # the mask rules
    with pytest.raises(ValueError, match=r"network inputs = 8 is invalid; allowed: 12"):
        team.policies([f"robot_{i}" for i in range(9)], make_config("three_circuits_three_classes"))


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"eval_every": 0}, r"eval_every = 0 is invalid; allowed: >= 1"),
        ({"eval_hours": -1.0}, r"eval_hours = -1.0 is invalid; allowed: > 0"),
        ({"final_seeds": 1}, r"final_seeds = 1 is invalid; allowed: >= 2"),
    ],
)
def test_run_options_refuse_bad_values_before_training(
    kwargs: dict[str, float], pattern: str
) -> None:
    with pytest.raises(ValueError, match=pattern):
        RunOptions(**kwargs)  # type: ignore[arg-type]


def test_every_committed_learning_run_is_whole_and_says_what_it_ran() -> None:
    from allocators import NETWORK_RUNS, PRESETS
    from tavc_agents.experiments.study import RESULTS_DIR

    folders = sorted((RESULTS_DIR / "marl").iterdir())
    assert len(folders) >= 3
    for folder in folders:
        named = [(folder.name.removesuffix(f"_{p}"), p) for p in PRESETS]
        run, preset = next((r, p) for r, p in named if r != folder.name)  # <run>_<preset>
        assert run in NETWORK_RUNS, folder.name
        assert {p.name for p in folder.iterdir()} >= {
            "curve.csv",
            "curve.png",
            "evaluation.md",
            "evaluation.json",
            "evaluation.csv",
            "network.npz",
        }
        report = json.loads((folder / "evaluation.json").read_text())
        assert report["metadata"]["settings"]["preset"] == preset
        assert report["metadata"]["settings"]["final_seeds"] == 10
        config = make_config(preset)
        mlp = Mlp.load(folder / "network.npz")
        assert mlp.n_outputs == config.n_circuits
        assert mlp.n_inputs == config.n_circuits + config.n_robots  # the paper_id observation
        curve = (folder / "curve.csv").read_text().splitlines()
        assert curve[1].startswith("0,") and len(curve) == 1 + 11  # step 0, then every 10th update
