"""The decisive test where robots can pass: the power analysis and the plan it makes, the physics
trials run exactly as planned, a prediction made for another arena refused, and both stages end
to end on a short run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

import passing


def _row(condition: str, d: float, sd: float) -> dict[str, object]:
    return {
        "condition": condition,
        "fast_minus_slow": d,
        "trials_for_80_power": passing.trials_for_power(sd, d),
    }


def test_trials_for_power_is_the_normal_approximation() -> None:
    # (1.96 + 0.84)^2 sd^2 / d^2: an effect of a tenth of the spread needs about 785 trials
    assert passing.trials_for_power(1.0, 0.1) == pytest.approx(784.9, abs=0.5)
    assert passing.trials_for_power(0.34, -0.05) == passing.trials_for_power(0.34, 0.05)
    assert math.isinf(passing.trials_for_power(0.3, 0.0))


def test_the_plan_gives_the_two_most_promising_temperatures_their_power() -> None:
    s = passing.Settings(arena="dahl2004_bays", min_decisive=430, max_decisive=2000)
    rows = [
        _row("softmax_T0.002", 0.02, 0.30),  # needs 1766
        _row("softmax_T0.005", 0.08, 0.30),  # needs 111: raised to 430
        _row("softmax_T0.01", -0.05, 0.30),  # reversed: not promising
        _row("epsilon_0.1", 0.0, 0.30),
        _row("random", 0.0, 0.30),
    ]
    plan = passing.plan(rows, s)
    assert plan == {
        "softmax_T0.002": 1766,
        "softmax_T0.005": 430,
        "softmax_T0.01": 60,
        "epsilon_0.1": 60,
        "random": 100,
    }
    rows[0] = _row("softmax_T0.002", 0.001, 0.30)  # far too small to see: capped
    assert passing.plan(rows, s)["softmax_T0.002"] == 2000


def test_the_test_stage_runs_the_plan_seed_by_seed() -> None:
    s = passing.Settings(arena="dahl2004_bays", stage="test")
    jobs = passing.test_jobs(s, {c: 2 for c in passing.CONDITIONS} | {"softmax_T0.005": 4})
    assert [(j.condition, j.seed) for j in jobs[:5]] == [(c, 0) for c in passing.CONDITIONS]
    assert [(j.condition, j.seed) for j in jobs[-2:]] == [
        ("softmax_T0.005", 2),
        ("softmax_T0.005", 3),
    ]
    assert len(jobs) == 12 and all(j.engine == "physics" for j in jobs)


def test_bad_settings_and_a_bad_prediction_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"^arena = 'nowhere' is invalid; allowed: one of"):
        passing.Settings(arena="nowhere")
    with pytest.raises(ValueError, match=r"^max_decisive = 10 is invalid"):
        passing.Settings(arena="dahl2004_bays", max_decisive=10)
    bad = tmp_path / "prediction.json"
    bad.write_text("[]")
    with pytest.raises(ValueError, match=r"^prediction = .* is invalid .*predict stage wrote"):
        passing.load_plan(bad)


def test_both_stages_end_to_end_and_a_prediction_for_another_arena_refused(tmp_path: Path) -> None:
    small = {
        "arena": "dahl2004_bays",
        "twin_trials": 20,
        "min_decisive": 3,
        "max_decisive": 3,
        "control_trials": 2,
        "other_trials": 2,
        "convergence_h": 0.15,
        "measured_h": 0.1,
        "e_seeds": 2,
        "e_hours": 0.3,
        "table_seeds": 2,
        "table_hours": 0.4,
        "workers": 1,
    }
    predicted = passing.run(passing.Settings(**small, out=tmp_path / "p"))
    prediction = json.loads((predicted.out_dir / "prediction.json").read_text())
    assert sum(prediction["summary"]["plan"].values()) == 3 + 3 + 2 + 2 + 2
    assert (predicted.out_dir / "prediction_trials.csv").read_text().count("\n") == 1 + 5 * 20
    tested = passing.run(
        passing.Settings(
            **small,
            stage="test",
            prediction=predicted.out_dir / "prediction.json",
            out=tmp_path / "t",
        )
    )
    report = (tested.out_dir / "passing.md").read_text()
    assert "All 12 planned trials are in." in report
    assert len(list((tested.out_dir / "trials").glob("*.json"))) == 12
    with pytest.raises(ValueError, match=r"is invalid for arena 'dahl2004_congestion'"):
        passing.run(
            passing.Settings(
                **(small | {"arena": "dahl2004_congestion"}),
                stage="test",
                prediction=predicted.out_dir / "prediction.json",
                out=tmp_path / "other",
            )
        )


def test_the_start_allocation_s_value_matches_the_allocator_study() -> None:
    import tavc_env
    from tavc_agents.model import load_model

    model = load_model("dahl2004")
    fraction = passing.start_value(model, tavc_env.preset("dahl2004")) / model.performance(
        model.optimum()
    )
    assert fraction == pytest.approx(0.966, abs=0.0005)  # the allocator study's committed figure
    lines = passing.value_lines("dahl2004_instant_docks", [])
    assert lines == [
        "No TAVC model of `dahl2004_instant_docks` to value its allocations against (overrides)."
    ]
