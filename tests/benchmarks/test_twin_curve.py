"""The twin's curve: its settings, the break-even arithmetic, the figure's sources (the passing
arena drawn only once committed), a short run end to end, and the committed report."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

import twin_curve as study
from tavc_agents.experiments.study import RESULTS_DIR


def test_bad_settings_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"^elasticities = '0.7,1' is invalid; allowed: dist"):
        study.Settings(elasticities="0.7,1")
    with pytest.raises(ValueError, match=r"^elasticities = '1.5' is invalid"):
        study.Settings(elasticities="1.5", above="wait")  # the wait reaches only 1.17
    with pytest.raises(ValueError, match=r"^elasticities = 'x' is invalid"):
        study.Settings(elasticities="x")
    with pytest.raises(ValueError, match=r"^trials = 1 is invalid"):
        study.Settings(trials=1)
    with pytest.raises(ValueError, match=r"^regime_map_dir = .* is invalid"):
        study.Settings(regime_map_dir=tmp_path)
    assert study.Settings().grid[0] == 0.75 and len(study.Settings().grid) == 14


def test_the_crossing_is_interpolated_where_the_curve_falls_through_zero() -> None:
    assert study.crossing([1.0, 2.0, 3.0], [0.2, 0.1, -0.1]) == pytest.approx(2.5)
    assert study.crossing([1.0, 2.0], [0.0, -0.1]) == 1.0
    assert math.isnan(study.crossing([1.0, 2.0], [-0.1, -0.2]))  # never above
    assert math.isnan(study.crossing([1.0, 2.0], [-0.1, 0.2]))  # rises: not a break-even


def test_the_break_even_interval_holds_the_true_crossing() -> None:
    rng = np.random.default_rng(0)
    e = [1.0, 1.2, 1.4, 1.6]
    truth = [0.1, 0.05, -0.05, -0.1]  # crosses at 1.3
    trials = [m + 0.2 * rng.standard_normal(4000) for m in truth]
    b = study.break_even(e, trials, np.random.default_rng(1), 400)
    assert b["break_even_lo"] < 1.3 < b["break_even_hi"] and b["no_crossing"] == 0.0
    assert b["break_even_e"] == pytest.approx(1.3, abs=0.03)
    assert b["break_even_hi"] - b["break_even_lo"] < 0.1


def _passing_files(folder: Path) -> tuple[Path, Path]:
    row = {"fast_minus_slow": 0.05, "fast_minus_slow_lo": 0.01, "fast_minus_slow_hi": 0.09}
    prediction = folder / "prediction.json"
    prediction.write_text(
        json.dumps(
            {
                "summary": {
                    "elasticity": {"e": 0.93, "low": 0.9, "high": 0.96},
                    "conditions": [
                        {"condition": c, "twin_trials": 2000, **row} for c in study.CONDITIONS
                    ]
                    + [{"condition": "random", "twin_trials": 2000, **row}],
                }
            }
        )
    )
    result = folder / "passing.csv"
    with result.open("w", newline="") as f:
        writer = csv.DictWriter(f, ["condition", "trials", *row])
        writer.writeheader()
        writer.writerow({"condition": "softmax_T0.005", "trials": 430, **row})
    return prediction, result


def test_the_figure_sources(tmp_path: Path) -> None:
    physics = study.physics_points(RESULTS_DIR / "regime_map")
    assert len(physics) == 6 * len(study.CONDITIONS)  # every arena, the curve's conditions
    assert min(p.e for p in physics) > 1.1 and all(p.low <= p.mean <= p.high for p in physics)
    assert study.passing_points(tmp_path / "none.json", tmp_path / "none.csv") == ([], [])
    prediction, result = _passing_files(tmp_path)
    predicted, physical = study.passing_points(prediction, tmp_path / "none.csv")
    assert len(predicted) == 4 and physical == []  # random is not drawn
    assert predicted[0].e == 0.93 and predicted[0].trials == 2000
    predicted, physical = study.passing_points(prediction, result)
    assert [(p.condition, p.trials, p.e) for p in physical] == [("softmax_T0.005", 430, 0.93)]


def test_a_short_run_end_to_end_and_the_redraw(tmp_path: Path) -> None:
    prediction, result = _passing_files(tmp_path)
    s = study.Settings(
        out=tmp_path / "run",
        elasticities="0.8,1.3",
        trials=6,
        convergence_h=0.2,
        measured_h=0.1,
        resamples=20,
        workers=1,
        passing_prediction=tmp_path / "missing.json",
    )
    outcome = study.run(s)
    rows = list(csv.DictReader((tmp_path / "run" / "twin_curve.csv").open()))
    assert len(rows) == 2 * len(study.CONDITIONS) and {r["trials"] for r in rows} == {"6"}
    assert float(rows[0]["handling_s"]) > 0 and float(rows[-1]["pace"]) > 0
    with (tmp_path / "run" / "twin_curve_trials.csv").open() as f:
        assert sum(1 for _ in f) == 1 + 2 * len(study.CONDITIONS) * 6
    assert (tmp_path / "run" / study.FIGURE).stat().st_size > 10_000
    assert "dahl2004_passing`: pending" in outcome.text
    again = study.run(
        dataclasses.replace(
            s, figure_only=True, passing_prediction=prediction, passing_result=result
        )
    )
    assert again.written == [tmp_path / "run" / study.FIGURE]
    assert "with the physics result beside it" in again.text
    with pytest.raises(ValueError, match=r"^figure_only: there is no report"):
        study.run(dataclasses.replace(s, out=tmp_path / "empty", figure_only=True))


def test_the_committed_report_covers_the_grid() -> None:
    folder = RESULTS_DIR / "twin_curve"
    report = json.loads((folder / "twin_curve.json").read_text())
    s = study.Settings(update_reference=True)
    assert report["metadata"]["settings"] == s.recorded()
    rows = list(csv.DictReader((folder / "twin_curve.csv").open()))
    assert len(rows) == len(s.grid) * len(study.CONDITIONS)
    assert all(r["trials"] == "2000" for r in rows)
    assert all(float(r["knee"]) >= 1.1 for r in rows)
    assert {b["condition"] for b in report["summary"]["break_even"]} == set(study.CONDITIONS)
    assert (folder / study.FIGURE).is_file()
