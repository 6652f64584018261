"""The scenario suite's references: an episode's phases, the model's random / stay / optimum values,
and both stages end to end on a short run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

import scenarios as study
from tavc_agents.model import SpeedClasses, load_model
from tavc_env import SCENARIOS


def test_the_breakdown_scenarios_phases_follow_its_breakdowns_and_repairs() -> None:
    start, phases = study.episode(SCENARIOS["breakdowns"], 10_000, 8 * 3600.0)
    assert start == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    assert [(p.start_s, p.end_s) for p in phases] == [
        (0.0, 3600.0),
        (3600.0, 7 * 3600.0),
        (7 * 3600.0, 8 * 3600.0),
    ]
    assert [p.working for p in phases] == [tuple(range(9)), tuple(range(3, 9)), tuple(range(9))]


def test_priority_shift_phases_alternate_the_profiles_as_the_trial_would_play_them() -> None:
    scenario = SCENARIOS["priority_shifts"]
    _, phases = study.episode(scenario, 10_001, scenario.episode_s)
    assert phases[0].start_s == 0.0 and phases[-1].end_s == scenario.episode_s
    profiles = scenario.value_shifts.profiles  # type: ignore[union-attr]
    assert [p.values for p in phases] == [profiles[k % 2] for k in range(len(phases))]
    assert all(5400.0 <= p.end_s - p.start_s <= 9000.1 for p in phases[:-1])


def test_the_random_expectation_equals_the_enumeration_of_every_split() -> None:
    model = load_model("three_circuits_three_classes")
    team = (2, 1, 3)
    enumerated = 0.0
    for allocation in model.allocations(team):
        chance = 1.0
        for k in range(3):
            counts = [g[k] for g in allocation]
            chance *= math.factorial(sum(counts)) / math.prod(math.factorial(c) for c in counts)
            chance *= 3.0 ** -sum(counts)
        enumerated += chance * model.value_rate(allocation)
    assert study.random_value_rate(model, team) == pytest.approx(enumerated, rel=1e-12)


def test_the_model_ranks_optimum_over_stay_and_random_in_every_phase() -> None:
    for scenario in SCENARIOS.values():
        model = load_model(scenario.model)
        classes = SpeedClasses.of(scenario.config())
        start, phases = study.episode(scenario, 10_000, scenario.episode_s)
        for phase in phases:
            v = study.phase_values(model, classes, start, phase)
            assert v["optimum"] >= v["stay"] - 1e-6 and v["optimum"] >= v["random"] - 1e-6


def test_a_crowded_start_is_worth_one_circuits_rate() -> None:
    # passing: all six robots on circuit 1, so stay is circuit 1's rate of the whole team, x 2000
    model = load_model("dahl2004_passing")
    row = study.predicted(SCENARIOS["passing"], 10_000, 3600.0)
    assert row["stay_per_h"] == pytest.approx(2000.0 * model.rate(1, (3, 3)) * 3600.0)
    assert 0.0 < row["headroom"] < 1.0


def test_both_stages_end_to_end_on_a_short_run(tmp_path: Path) -> None:
    predict = study.Settings(stage="predict", out=tmp_path / "p", scenarios=("bad_start",))
    outcome = study.run(predict)
    assert "tavc/bad_start-v0" in outcome.text
    assert (tmp_path / "p" / "prediction.csv").is_file()
    settings = study.Settings(
        stage="measure",
        quick=True,
        scenarios=("bad_start", "priority_shifts"),
        workers=1,
        out=tmp_path / "m",
    )
    study.run(settings)
    summary = json.loads((tmp_path / "m" / "references.json").read_text())["summary"]
    assert set(summary) == {"bad_start", "priority_shifts"}
    for entry in summary.values():
        assert entry["seeds"] == 2 and math.isfinite(entry["stay_per_h"])
        assert entry["random_per_h"] > 0
    assert len(list((tmp_path / "m" / "trials").glob("*.json"))) == 2 * 2 * 3


def test_settings_refuse_unknown_scenarios_and_stages() -> None:
    with pytest.raises(ValueError, match="scenarios"):
        study.Settings(scenarios=("nope",))
    with pytest.raises(ValueError, match="seeds"):
        study.Settings(seeds=0)
