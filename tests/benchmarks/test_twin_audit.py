"""The twin audit: its settings, its arithmetic on known runs, and its committed report."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

import arena_runs
import tavc_env
import twin_audit as study
from tavc_agents.experiments.study import RESULTS_DIR
from tavc_env.twin import InterferenceTables

TABLES = InterferenceTables.from_function(tavc_env.preset("dahl2004"), 100.0, switch_cost=1.25)


def run(perf: float, own: tuple[float, float], switch: tuple[float, float]) -> dict[str, object]:
    """A run's record: 10 own and 10 switch tasks per class with these summed times (observed,
    cells)."""
    tasks = {}
    for cls in ("fast", "slow"):
        tasks[f"{cls}:own"] = [10, *own]
        tasks[f"{cls}:switch"] = [10, *switch]
    return {"performance": perf, "tasks": tasks}


def test_the_arithmetic_on_known_runs() -> None:
    physics = [
        run(0.10, (950.0, 1000.0), (1100.0, 1000.0)),
        run(0.11, (950.0, 1000.0), (1200.0, 1000.0)),
    ]
    assert study.pooled(physics, "own") == pytest.approx([0.95, 0.95])
    assert study.pooled(physics, "switch", "fast") == pytest.approx([1.1, 1.2])
    assert study.audited_switch_cost(physics) == pytest.approx(1.15)
    assert study.switch_share(physics) == pytest.approx(0.5)
    twin = [run(0.09, (1000.0, 1000.0), (1250.0, 1000.0))] * 2
    paid = [
        run(0.1, (1000.0, 1000.0), (1150.0, 1000.0)),
        run(0.1, (1000.0, 1000.0), (1150.0, 1000.0)),
    ]
    row = study.arena_row(
        "dahl2004", TABLES, {"physics": physics, "twin_tables": twin, "twin_audited_switch": paid}
    )
    assert row["perf_physics"] == pytest.approx(0.105)
    assert row["twin_tables_over_physics"] == pytest.approx(0.09 / 0.105)
    assert row["gap_closed_by_switch_cost"] == pytest.approx(0.01 / 0.015)
    assert row["table_switch_cost"] == 1.25 and row["own_ratio"] == pytest.approx(0.95)
    assert row["switch_ratio_slow"] == pytest.approx(1.15) and row["n_physics"] == 2
    assert "| dahl2004 | 50 % | 0.950 " in study.report_body([row], study.Settings(out=Path(".")))


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^arenas = 'nowhere' is invalid"):
        study.Settings(arenas="nowhere")
    with pytest.raises(ValueError, match=r"^seeds = 1 is invalid"):
        study.Settings(seeds=1)
    with pytest.raises(ValueError, match=r"^warmup_s = 20000.0 is invalid"):
        study.Settings(hours=4.0, warmup_s=20000.0)


def test_its_tables_are_the_regime_maps() -> None:
    seeds, hours = study.Settings(out=Path(".")).table_runs
    assert seeds == (0, 1, 2) and hours == 1.0
    stored = RESULTS_DIR / "regime_map" / "twin_tables" / "tables_dahl2004.json"
    record = json.loads(stored.read_text())["record"]
    assert record["seeds"] == list(seeds) and record["hours"] == hours
    for arena in arena_runs.MAPPED:  # measured again by the audit: the very same numbers
        name = f"tables_{arena}.json"
        again = json.loads((RESULTS_DIR / "twin_audit" / "twin_tables" / name).read_text())
        first = json.loads((RESULTS_DIR / "regime_map" / "twin_tables" / name).read_text())
        assert again["result"] == first["result"]


def test_the_committed_report_has_its_settings_and_every_arena() -> None:
    folder = RESULTS_DIR / "twin_audit"
    report = json.loads((folder / "twin_audit.json").read_text())
    assert report["metadata"]["settings"] == study.Settings(update_reference=True).recorded()
    with (folder / "twin_audit.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["arena"] for r in rows] == list(arena_runs.MAPPED)
    for r in rows:
        assert r["n_physics"] == "10" and r["n_twin_tables"] == "40"
        assert 0.3 < float(r["switch_share"]) < 0.7 and math.isfinite(float(r["own_ratio"]))
