"""The regime map: its cells, their order, its compact records, its statistics and a smoke run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import arena_runs
import regime_map as rm
from arena_analysis import Elasticity


def test_bad_settings_are_refused_naming_the_field_and_what_is_allowed() -> None:
    with pytest.raises(ValueError, match=r"^arenas = 'dahl2004,moon' is invalid; allowed: "):
        rm.Settings(arenas="dahl2004,moon")
    for field, value in (
        ("trials", 1),
        ("decisive_trials", 0),
        ("twin_trials", -1),
        ("measured_h", 0.0),
        ("convergence_h", math.nan),
        ("e_seeds", 1),
        ("seed", -3),
    ):
        with pytest.raises(ValueError, match=rf"^{field} = .* is invalid; allowed: "):
            rm.Settings(**{field: value})


def test_every_arena_is_valid_and_the_congestion_arena_is_the_preset() -> None:
    import tavc_env

    for arena in arena_runs.ARENAS:
        assert rm.arena_config(arena).n_robots == 6
    assert rm.arena_config("dahl2004_congestion") == tavc_env.preset("dahl2004_congestion")
    assert rm.arena_config("dahl2004_instant_docks").source_service_s == 0.0


def test_decisive_cells_run_first_congestion_before_dahl2004_and_seed_by_seed() -> None:
    s = rm.Settings(trials=3, decisive_trials=5)
    jobs = rm.physics_trials(s)
    assert len(jobs) == 4 * 5 + (6 * 6 - 4) * 3
    assert len({rm.trial_key(j) for j in jobs}) == len(jobs)
    head = [(j.arena, j.condition, j.seed) for j in jobs[:4]]
    assert head == [
        ("dahl2004_congestion", "softmax_T0.005", 0),
        ("dahl2004_congestion", "softmax_T0.01", 0),
        ("dahl2004_congestion", "softmax_T0.005", 1),
        ("dahl2004_congestion", "softmax_T0.01", 1),
    ]
    assert {j.arena for j in jobs[10:20]} == {"dahl2004"}
    rest = jobs[20:]
    # a sweep stopped after k * 32 of the other trials has seeds 0..k-1 in every other cell
    assert {j.seed for j in rest[:32]} == {0} and {j.seed for j in rest[32:64]} == {1}
    cells = {(j.arena, j.condition) for j in jobs}
    assert len(cells) == 36
    assert all(
        s.trials_in(a, c)
        == (5 if (a, c) in {(x, rm.softmax_condition(t)) for x, t in rm.DECISIVE} else 3)
        for a, c in cells
    )


def test_a_twin_trial_records_its_tables_by_digest_not_in_full() -> None:
    tables = {"classes": ["fast", "slow"], "cells": [1, 2, 3]}
    s = rm.Settings(arenas="dahl2004", trials=2, twin_trials=2)
    jobs = rm.twin_trials(s, {"dahl2004": tables})
    assert len(jobs) == 2 * len(rm.CONDITIONS)
    record = rm.TRIALS.record(jobs[0])
    assert "tables" not in record
    assert record["tables_sha256"] == arena_runs.tables_digest(tables)
    assert record["engine"] == "twin"
    other = rm.twin_trials(s, {"dahl2004": {**tables, "cells": [1, 2, 4]}})
    assert rm.TRIALS.record(other[0]) != record  # changed tables do not resume


def _record(fast: float, slow: float, perf: float = 0.1) -> dict[str, object]:
    return {
        "fast_share": fast,
        "slow_share": slow,
        "performance": perf,
        "q_gap_fast": 0.002,
        "q_gap_slow": 0.001,
        "states_pct": {"3:0": 10.0},
        "jams": 0,
        "wall_s": 1.0,
    }


def test_cell_statistics_and_the_verdict_words() -> None:
    rng = np.random.default_rng(0)
    diffs = rng.normal(0.05, 0.3, 400)
    records = [_record(0.5 + d / 2, 0.5 - d / 2) for d in diffs]
    random = [_record(0.5, 0.5, 0.1) for _ in range(10)]
    row = rm.cell_row(records, random)
    assert row["trials"] == 400
    assert row["fast_minus_slow"] == pytest.approx(diffs.mean())
    assert row["fast_minus_slow_lo"] < row["fast_minus_slow"] < row["fast_minus_slow_hi"]
    assert row["detectable_80"] == pytest.approx(2.8016 * diffs.std(ddof=1) / 20, rel=1e-3)
    assert row["q_gap_fast_minus_slow"] == pytest.approx(0.001)
    assert row["time_3_0_pct"] == pytest.approx(10.0)
    assert row["ratio_to_random"] == pytest.approx(1.0)
    assert rm.direction(row) == "paper's direction"
    assert (
        rm.direction({**row, "fast_minus_slow_lo": -0.1, "fast_minus_slow_hi": -0.01}) == "reversed"
    )
    assert rm.direction({**row, "fast_minus_slow_lo": -0.1}) == "not detectable"


def test_twin_agreement_is_the_welch_interval_of_the_difference() -> None:
    e = {"a": Elasticity(1.0, 0.9, 1.1, 5, 0.1, 0.1)}
    same = [_record(0.6 + 0.01 * k, 0.4) for k in range(-5, 6)]
    shifted = [_record(0.9 + 0.01 * k, 0.4) for k in range(-5, 6)]
    records = {}
    for condition in rm.CONDITIONS:
        records[("a", condition, "physics")] = same
        records[("a", condition, "twin")] = shifted if condition == "epsilon_0.1" else same
    rows = {r["condition"]: r for r in rm.summarise(records, e, ["a"])}
    assert rows["softmax_T0.005"]["agree_fast_minus_slow"] is True
    assert rows["epsilon_0.1"]["agree_fast_minus_slow"] is False
    assert rows["epsilon_0.1"]["physics_minus_twin"] == pytest.approx(-0.3)
    assert rows["softmax_T0.005"]["agree_ratio"] is True
    # without the random cells there is no performance ratio to compare: neither yes nor no
    del records[("a", "random", "physics")]
    partial = {r["condition"]: r for r in rm.summarise(records, e, ["a"])}
    assert partial["softmax_T0.005"]["agree_ratio"] is None
    assert "| a | softmax_T0.005 |" in rm.twin_table(list(partial.values()))


def test_quick_run_writes_the_report_and_resumes_everything(tmp_path: Path) -> None:
    s = rm.Settings(quick=True, arenas="dahl2004_congestion", workers=1, out=tmp_path)
    outcome = rm.run(s)
    assert "dahl2004_congestion" in outcome.text
    report = json.loads((tmp_path / "regime_map.json").read_text())
    assert set(report["summary"]["elasticity"]) == {"dahl2004_congestion"}
    md = (tmp_path / "regime_map.md").read_text()
    assert "## The twin against the physics" in md and "## Wall time" in md
    for condition in rm.CONDITIONS:
        assert f"| {condition} |" in md
    records = sorted((tmp_path / "trials").glob("*.json"))
    assert len(records) == 2 * 3 + 4 * 2 + 6 * 2  # decisive, other physics, twin
    assert max(p.stat().st_size for p in records) < 2000
    before = {p.name: p.read_bytes() for p in records}
    rm.run(s)  # resumes: no trial is run again
    assert {p.name: p.read_bytes() for p in sorted((tmp_path / "trials").glob("*.json"))} == before


def test_records_carry_the_arena_s_digest_so_a_renamed_arena_is_not_resumed() -> None:
    s = rm.Settings(arenas="dahl2004,dahl2004_congestion", trials=2, decisive_trials=2)
    jobs = rm.physics_trials(s)
    digests = {j.arena: rm.TRIALS.record(j)["arena_sha"] for j in jobs}
    assert len(set(digests.values())) == 2 and all(digests.values())
    assert (
        rm.TablesJob("dahl2004", (0,), 1.0, rm.digest("dahl2004")).arena_sha == digests["dahl2004"]
    )


def test_an_interim_report_runs_nothing_and_says_how_much_is_in(tmp_path: Path) -> None:
    s = rm.Settings(quick=True, arenas="dahl2004_congestion", workers=1, out=tmp_path)
    rm.run(s)
    trials = tmp_path / "trials"
    dropped = sorted(trials.glob("*softmax_T0.005__physics*.json"))[:1]
    dropped += sorted(trials.glob("*softmax_T0.02__physics*.json"))
    for path in dropped:
        path.unlink()
    before = sorted(p.name for p in trials.glob("*.json"))
    outcome = rm.run(
        rm.Settings(quick=True, arenas="dahl2004_congestion", workers=1, out=tmp_path, interim=True)
    )
    assert sorted(p.name for p in trials.glob("*.json")) == before  # nothing ran
    md = (tmp_path / "regime_map_interim.md").read_text()
    assert f"{len(before)} of {len(before) + len(dropped)} trials saved so far" in md
    assert "| softmax_T0.02 |" not in md.split("## Cells")[1].split("## The twin")[0]
    assert "over 2 trials" in outcome.text  # the T = 0.005 cell lost one of its three


def test_a_recomputed_cell_is_timed_and_identical_to_the_committed_trials(tmp_path: Path) -> None:
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[2] / "benchmarks" / "regime_cell.py"
    args = ["--trials", "2", "--workers", "1", "--out", str(tmp_path)]
    assert subprocess.run([sys.executable, str(script), *args], check=False).returncode == 0
    found = json.loads((tmp_path / "regime_cell.json").read_text())
    assert found["identical_to_committed"] == 2 and found["differ"] == []
    assert "2 of 2 trials are identical" in (tmp_path / "regime_cell.md").read_text()
