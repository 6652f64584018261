"""The time-step study: its runs keep their keys, each step is compared with the finest, and a
small run passes at the package's steps."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

import dt_fidelity as study

ROOT = Path(__file__).resolve().parents[2]


def test_runs_keep_their_keys() -> None:
    jobs = study.make_jobs(study.Settings())
    keys = {study.run_key(j) for j in jobs}
    assert len(keys) == len(jobs) == 4 * 5 * 8
    assert "t_n_dt0.05_n3_s0_3h" in keys and "random_dt0.25_n0_s4_3h" in keys
    assert jobs[0].dt == 0.05 and jobs[-1].dt == 0.25  # the finest (slowest) first


def test_recorded_settings_are_those_of_the_committed_report() -> None:
    committed = json.loads(
        (ROOT / "benchmarks" / "results" / "dt_fidelity" / "dt_fidelity.json").read_text()
    )
    recorded = study.Settings(update_reference=True).recorded()
    stored = committed["metadata"]["settings"]
    # the output folder is recorded as an absolute path, which depends on the checkout
    assert Path(recorded.pop("out")).parts[-3:] == Path(stored.pop("out")).parts[-3:]
    assert recorded == stored


def test_each_step_is_compared_with_the_finest() -> None:
    ones = {q: [100.0, 102.0] for q in study.QUANTITIES}
    values = {
        0.1: ones,
        0.05: ones,
        0.2: {**ones, "t(4)": [104.0, 106.0]},  # 4 % longer
        0.25: {**ones, "t(1)": [101.0, 103.0]},  # 1 % longer
    }
    rows, passes = study.compare(values, tolerance=0.03)
    assert passes == {0.05: True, 0.1: True, 0.2: False, 0.25: True}
    assert study.largest_passing(passes) == 0.25
    t4 = next(r for r in rows if r["dt"] == 0.2 and r["quantity"] == "t(4)")
    assert t4["ratio_to_finest"] == pytest.approx(105 / 101) and not t4["within_tolerance"]
    assert t4["mean_s"] == pytest.approx(105.0)
    reference = [r for r in rows if r["dt"] == 0.05]
    assert all(r["ratio_to_finest"] == 1.0 for r in reference)


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^seeds = 1 is invalid"):
        study.Settings(seeds=1)
    with pytest.raises(ValueError, match=r"^dts = .* is invalid"):
        study.Settings(dts=(0.05, -1.0))


def test_a_small_run_passes_at_the_package_steps(tmp_path: Path) -> None:
    settings = study.Settings(dts=(0.2, 0.1), seeds=2, hours=0.25, out=tmp_path, workers=1)
    outcome = study.run(settings)
    assert "Largest passing step: **0.2 s**" in outcome.text
    summary = json.loads((tmp_path / "dt_fidelity.json").read_text())["summary"]
    assert summary == {"passes": {"0.1": True, "0.2": True}, "largest_passing_dt": 0.2}
    assert [p.name for p in outcome.written] == [
        "dt_fidelity.md",
        "dt_fidelity.csv",
        "dt_fidelity.json",
    ]
    rows = (tmp_path / "dt_fidelity.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * len(study.QUANTITIES)
    t6 = next(r for r in rows if r.startswith("0.1,t(6),"))
    assert 135.0 < float(t6.split(",")[2]) < 155.0 and not math.isnan(float(t6.split(",")[3]))
