"""The deep leaderboard without training (no TorchRL): the read-out job (a saved network read out
sampled, reproducibly from its episode's seed, or greedy, as `NetworkTeam` reads it), resumed
without running again and never mixed with another network's; the rule that picks the headline
read-out from the training-side episodes; the study run on a saved training run (its read-outs
evaluated, its training never rerun); and the reports that show both read-outs, labelled."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import deep_leaderboard as study
from tavc_agents.evaluation import value_per_hour
from tavc_agents.experiments.runner import run_trial
from tavc_agents.experiments.sweep import run_jobs
from tavc_agents.learners.network import Mlp, NetworkTeam

REFS = {"dahl2004": {"random": 100.0, "optimum": 200.0}}
EPISODE_S = 120.0  # two simulated minutes: a few decisions per robot


def _run(algorithm: str, seed: int) -> study.Run:
    return study.Run(algorithm, "dahl2004", seed, 100, 50, 1, 50, 60.0, (0,))


def _result(curve: list[float], choices: list[list[int]], score: float) -> dict[str, Any]:
    points = [{"decisions": 50 * k, "value_per_h": v} for k, v in enumerate(curve)]
    times = {"decisions": 100, "train_cpu_s": 1.0, "cpu_s": 1.0, "wall_s": 1.0}
    return {"curve": points, "choices": choices, "eval_values_per_h": [score, score], **times}


def _readout(evaluation: list[float], choice: list[float], stay: float) -> dict[str, Any]:
    return {
        "eval_values_per_h": evaluation,
        "choice_values_per_h": choice,
        "probabilities": [[[stay, 1 - stay], [1 - stay, stay]], [[1.0, 0.0], [0.5, 0.5]]],
        "cpu_s": 1.0,
        "wall_s": 1.0,
    }


def tiny_network(path: Path, seed: int = 0) -> Mlp:
    """A random network for dahl2004's 6 robots and 2 circuits (8 inputs, 2 scores), saved."""
    rng = np.random.default_rng(seed)
    mlp = Mlp(
        (rng.normal(0, 1.0, (4, 8)), rng.normal(0, 1.0, (2, 4))),
        (rng.normal(0, 0.1, 4), rng.normal(0, 0.1, 2)),
    )
    mlp.save(path)
    return mlp


def _job(folder: Path, readout: str, key: str = "dahl2004__ippo__seed0") -> study.Readout:
    return study.Readout(
        key,
        "dahl2004",
        readout,
        EPISODE_S,
        (10_000, 10_001),
        (0,),
        study.file_digest(folder / f"{key}.npz"),
        str(folder),
    )


def _value(mlp: Mlp, readout: str, seed: int) -> float:
    result = run_trial(
        NetworkTeam(mlp, readout=readout),
        seed=seed,
        convergence_s=0.0,
        measured_s=EPISODE_S,
        snapshot_every_s=EPISODE_S,
        arena={"scenario": "dahl2004"},
    )
    return value_per_hour(result)


def test_a_readout_is_the_network_team_on_the_episodes_sampled_reproducibly(
    tmp_path: Path,
) -> None:
    mlp = tiny_network(tmp_path / "dahl2004__ippo__seed0.npz")
    greedy = study.run_readout(_job(tmp_path, "greedy"))
    assert greedy["eval_values_per_h"] == [_value(mlp, "greedy", s) for s in (10_000, 10_001)]
    assert greedy["choice_values_per_h"] == [_value(mlp, "greedy", 0)]
    sampled = study.run_readout(_job(tmp_path, "sampled"))
    assert sampled["eval_values_per_h"] == [_value(mlp, "sampled", s) for s in (10_000, 10_001)]
    again = study.run_readout(_job(tmp_path, "sampled"))  # the episode's seed fixes the draws
    assert again["eval_values_per_h"] == sampled["eval_values_per_h"]
    assert again["choice_values_per_h"] == sampled["choice_values_per_h"]
    # the policy: each robot's softmax after each circuit; greedy is its argmax
    probabilities = np.array(sampled["probabilities"])
    assert probabilities.shape == (6, 2, 2)
    assert np.allclose(probabilities.sum(axis=-1), 1.0, atol=1e-5)
    config_inputs = np.eye(2)
    for robot in range(6):
        for last in range(2):
            x = np.concatenate([config_inputs[last], np.eye(6)[robot]])
            assert np.argmax(probabilities[robot, last]) == np.argmax(mlp.scores(x))


def test_readouts_are_saved_resumed_and_refused_for_another_network(tmp_path: Path) -> None:
    networks = tmp_path / "networks"
    networks.mkdir()
    tiny_network(networks / "dahl2004__ippo__seed0.npz")
    planned = [_job(networks, r) for r in study.READOUTS]
    first = run_jobs(planned, study.EVALUATIONS, tmp_path / "readouts", workers=1)
    assert sorted(first) == ["dahl2004__ippo__seed0__greedy", "dahl2004__ippo__seed0__sampled"]

    def refuse(job: study.Readout) -> dict[str, Any]:
        raise AssertionError(f"{job} was read out again")

    resumed = dataclasses.replace(study.EVALUATIONS, run=refuse)
    assert run_jobs(planned, resumed, tmp_path / "readouts", workers=1) == first
    # a network trained again (another file) is not taken for the one read out
    tiny_network(networks / "dahl2004__ippo__seed0.npz", seed=1)
    with pytest.raises(ValueError, match="run with different settings"):
        run_jobs([_job(networks, "sampled")], resumed, tmp_path / "readouts", workers=1)


def test_the_training_side_episodes_choose_the_readout_ties_go_to_sampled() -> None:
    assert study.chosen_readout({"sampled": 0.2, "greedy": 0.5}) == "greedy"
    assert study.chosen_readout({"sampled": 0.5, "greedy": 0.2}) == "sampled"
    assert study.chosen_readout({"sampled": 0.3, "greedy": 0.3}) == "sampled"


def test_the_headline_is_the_chosen_readouts_iqm_not_the_better_on_evaluation() -> None:
    settings = study.Settings(algorithms=("mappo",), scenarios=("dahl2004",), seeds=3)
    runs = [_run("mappo", k) for k in range(3)]
    results = {study.run_key(j): _result([150.0], [[0, 1]] * 2, 150.0) for j in runs}
    # greedy is better on the evaluation seeds, sampled on the training-side episodes
    evaluations = {}
    for k, job in enumerate(runs):
        evaluations[f"{study.run_key(job)}__sampled"] = _readout([150.0 + k], [190.0], 0.8)
        evaluations[f"{study.run_key(job)}__greedy"] = _readout([180.0 + k], [120.0], 0.8)
    rows = study.rows_of(runs, results, REFS, evaluations)
    cell = study.cells(settings, rows, np.random.default_rng(0))["dahl2004/mappo"]
    assert cell["readout"] == "sampled"
    assert cell["choice_mean"] == pytest.approx({"sampled": 0.9, "greedy": 0.2})
    assert cell["iqm"] == cell["sampled"]["iqm"] == pytest.approx(0.51)
    assert cell["greedy"]["iqm"] == pytest.approx(0.81)
    assert cell["n"] == 3


def test_every_run_is_a_row_in_order_with_both_readouts_and_its_policies() -> None:
    settings = study.Settings(algorithms=("mappo", "ippo"), scenarios=("dahl2004",), seeds=2)
    runs = [_run("ippo", 0), _run("mappo", 1), _run("mappo", 0)]
    results = {
        study.run_key(runs[0]): _result([150.0, 190.0, 120.0], [[1, 1], [0, 1]], 120.0),
        study.run_key(runs[2]): _result([100.0, 180.0, 180.0], [[0, 1], [0, 1]], 180.0),
    }  # mappo seed 1 is not saved yet
    evaluations = {
        "dahl2004__mappo__seed0__sampled": _readout([190.0, 170.0], [160.0], 0.75),
        "dahl2004__mappo__seed0__greedy": _readout([130.0, 130.0], [140.0], 0.75),
    }  # ippo seed 0's read-outs are not saved yet
    table = study.runs_table(settings, runs, results, REFS, evaluations).splitlines()
    assert "score, sampled" in table[0] and "score, greedy" in table[0]
    assert "curve (greedy)" in table[0] and "greedy policy" in table[0]
    assert table[2:] == [
        "| dahl2004 | mappo | 0 | 0.00 | 0.80 at 50 | 0.80 | 0.800 | 0.300 | 0.600 | 0.400 "
        "| stay | 0.75 (0.50-1.00) | 1.5 / 0.5 |",
        "| dahl2004 | ippo | 0 | 0.50 | 0.90 at 50 | 0.20 | - | - | - | - | moves | - | - |",
    ]


def test_the_long_run_follows_each_robots_chain_from_its_start() -> None:
    """Where a sampled policy sends the team: a robot that always moves on alternates, one that
    is absorbed stays absorbed, and a fixed start decides which of two closed classes a robot
    ends in (a drawn start weighs both)."""
    alternate = [[0.0, 1.0], [1.0, 0.0]]
    absorbed = [[1.0, 0.0], [0.5, 0.5]]
    keep = [[1.0, 0.0], [0.0, 1.0]]  # two closed classes: where it starts, it stays
    share = study.long_run_share([alternate, absorbed, keep], starts=[0, 1, 1])
    assert share == pytest.approx([0.5 + 1.0, 0.5 + 0.0 + 1.0], abs=1e-3)
    drawn = study.long_run_share([keep], starts=None)
    assert drawn == pytest.approx([0.5, 0.5])


def test_no_saved_run_says_so() -> None:
    settings = study.Settings(algorithms=("mappo",), scenarios=("dahl2004",), seeds=1)
    assert study.runs_table(settings, [_run("mappo", 0)], {}, REFS) == "(no run saved yet)"


def tiny(out: Path, **changes: Any) -> study.Settings:
    """One IPPO run on the paper's scenario, of 2 evaluation seeds and 1 choice episode of two
    simulated minutes, with no training allowed."""
    fields: dict[str, Any] = {
        "out": out,
        "workers": 1,
        "algorithms": ("ippo",),
        "scenarios": ("dahl2004",),
        "seeds": 1,
        "eval_seeds": 2,
        "episode_h": EPISODE_S / 3600.0,
        "choice_episodes": 1,
        "resamples": 100,
        "max_jobs": 0,
    }
    return study.Settings(**{**fields, **changes})


def saved_training(settings: study.Settings) -> None:
    """A training run saved as the study saves one, with its network: what read-outs start from."""
    (job,) = study.jobs(settings, settings.out_dir() / study.NETWORKS)
    result = {
        "decisions": 100_000,
        "steps": 100_000,
        "curve": [{"decisions": 0, "steps": 0, "value_per_h": 500_000.0}],
        "eval_values_per_h": [500_000.0, 500_000.0],
        "choices": [[0, 1]] * 6,
        "train_wall_s": 1.0,
        "train_cpu_s": 1.0,
        "curve_cpu_s": 0.0,
        "wall_s": 1.0,
        "cpu_s": 1.0,
    }
    folder = settings.out_dir() / study.JOBS
    folder.mkdir(parents=True)
    key = study.run_key(job)
    study.RUNS.save(result, study.RUNS.record(job), folder / f"{key}.json")
    (settings.out_dir() / study.NETWORKS).mkdir()
    tiny_network(settings.out_dir() / study.NETWORKS / f"{key}.npz")


def test_the_study_reads_out_saved_networks_without_training_and_reports_both(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def refuse(job: Any) -> dict[str, Any]:
        raise AssertionError(f"{job} ran again")

    monkeypatch.setattr(study, "RUNS", dataclasses.replace(study.RUNS, run=refuse))
    settings = tiny(tmp_path)
    saved_training(settings)
    nothing = study.run(tiny(tmp_path, max_evaluations=0))  # only the report
    assert not (tmp_path / "readouts").exists()
    assert "| tavc/dahl2004-v0 | ippo | 1 | 0 | - | - | - | - | - |" in nothing.text

    outcome = study.run(settings)
    saved = sorted(p.name for p in (tmp_path / "readouts").glob("*__*.json"))
    assert saved == ["dahl2004__ippo__seed0__greedy.json", "dahl2004__ippo__seed0__sampled.json"]
    summary = json.loads((tmp_path / "deep_leaderboard.json").read_text())["summary"]
    cell = summary["dahl2004/ippo"]
    assert cell["readout"] in study.READOUTS and cell["iqm"] == cell[cell["readout"]]["iqm"]
    assert "sampled (as trained): IQM score [95 % CI]" in outcome.text
    assert "greedy (argmax): IQM score [95 % CI]" in outcome.text
    assert "headline: chosen read-out's IQM [95 % CI]" in outcome.text
    assert f"({cell['readout']}) |" in outcome.text
    csv = (tmp_path / "deep_leaderboard.csv").read_text().splitlines()
    assert {"score_sampled", "score_greedy", "readout_chosen"} <= set(csv[0].split(","))

    monkeypatch.setattr(study, "EVALUATIONS", dataclasses.replace(study.EVALUATIONS, run=refuse))
    assert study.run(settings).text == outcome.text  # resumed: nothing runs again


def test_bad_readout_settings_are_refused_by_name(tmp_path: Path) -> None:
    for field, value in (("choice_episodes", 0), ("max_evaluations", -1)):
        with pytest.raises(ValueError, match=f"{field} = .* is invalid; allowed: "):
            tiny(tmp_path, **{field: value})
