"""The batched twin's check: its settings, its comparison arithmetic and its committed report."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

import arena_runs
import regime_map
import twin_batch as study
from tavc_agents.experiments.study import RESULTS_DIR


def test_bad_settings_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"^trials = 1 is invalid"):
        study.Settings(trials=1)
    with pytest.raises(ValueError, match=r"^regime_map_dir = .* is invalid; allowed: a regime"):
        study.Settings(regime_map_dir=tmp_path)


def test_each_condition_has_its_learner() -> None:
    assert study.learner_of("softmax_T0.01").parameter == 0.01
    assert study.learner_of("epsilon_0.1").kind == "epsilon"
    assert study.learner_of("random").kind == "random"
    assert set(regime_map.CONDITIONS) == {
        *(regime_map.softmax_condition(t) for t in arena_runs.TEMPERATURES),
        "epsilon_0.1",
        "random",
    }


def test_the_comparison_finds_a_shift_and_not_noise() -> None:
    same = {m: [0.0, 0.1, -0.1, 0.05, -0.05] * 4 for m in study.MEASURES}
    shifted = {m: [x + 1.0 for x in values] for m, values in same.items()}
    assert all(study.compare(same, same)[f"{m}_agree"] for m in study.MEASURES)
    row = study.compare(shifted, same)
    assert not any(row[f"{m}_agree"] for m in study.MEASURES)
    assert row["fast_minus_slow_diff"] == pytest.approx(1.0) and row["n_batch"] == 20


def test_the_committed_report_covers_every_cell_and_is_fast() -> None:
    folder = RESULTS_DIR / "twin_batch"
    report = json.loads((folder / "twin_batch.json").read_text())
    assert report["metadata"]["settings"] == study.Settings(update_reference=True).recorded()
    with (folder / "twin_batch.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(arena_runs.MAPPED) * len(regime_map.CONDITIONS)
    assert all(r["n_batch"] == "2000" and int(r["n_twin"]) >= 100 for r in rows)
    speed = report["summary"]["speed"]
    # "thousands of trials in seconds": a 20-hour trial in a few CPU ms, hundreds of times faster
    # than the physics (597x since the physics' own levers; 2654x when a trial took 8 s)
    assert speed["batch_s"] < 0.01 and speed["batch_speedup"] > 300
