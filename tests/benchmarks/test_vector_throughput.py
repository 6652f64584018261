"""The vector throughput study: its settings, the verdict it draws from measured rows, and a smoke
run. Nothing here is timed: speed is judged by the benchmark itself, as ratios of figures measured
in the same run (the committed results are figures of their machine)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import vector_throughput as study

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"repeats": 0}, "repeats"),
        ({"steps": 1}, "steps"),  # the slower of two steps needs two
        ({"arenas_per_worker": ()}, "arenas_per_worker"),
        ({"arenas_per_worker": (4, 4)}, "arenas_per_worker"),
        ({"arenas_per_worker": (4, 0)}, "arenas_per_worker"),
        ({"arenas_per_worker": 4}, "arenas_per_worker"),
        ({"episode_s": -1.0}, "episode_s"),
        ({"workers": 2}, "workers"),
    ],
)
def test_bad_settings_are_refused(changes: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field} = .* is invalid; allowed: "):
        study.Settings(**changes)


def test_every_arenas_per_worker_has_its_three_batched_cases() -> None:
    settings = study.Settings(out=Path("unused"), arenas_per_worker=(4, 16))
    names = [case.name for case in settings.cases]
    assert names[:2] == ["ceiling: 1 process", "ceiling: 2 processes"]
    for k in (4, 16):
        assert f"batched in-process, {k} arenas" in names
        assert f"batched 1 worker x {k} arenas" in names
    judged = [(case.name, case.per_worker) for case in study.judged(settings)]
    assert judged == [
        ("make_vec async, 2 envs", 1),
        ("batched 2 workers x 4 arenas", 4),
        ("batched 2 workers x 16 arenas", 16),
    ]
    assert settings.recorded()["arenas_per_worker"] == [4, 16]  # readable, as JSON has it


SPEEDS = {"ceiling: 2 processes": 180.0, "make_vec async, 2 envs": 170.0}


def _rows(settings: study.Settings, speeds: dict[str, float]) -> list[dict[str, Any]]:
    """Two rounds of every case: 100 decisions per second unless `speeds` says otherwise, 100
    steps of 1 s wall (10 ms a step), the parent's CPU 0.5 s with 1 worker, 0.6 s with 2."""
    rows = []
    for rep in range(2):
        for case in settings.cases:
            speed = speeds.get(case.name, 100.0)
            rows.append(
                {
                    "case": case.name,
                    "repeat": rep,
                    "steps": 100,
                    "decisions_per_s": speed * (1 + 0.01 * rep),
                    "decisions": speed,
                    "wall_s": 1.0,
                    "cpu_s": 0.5 + 0.1 * (case.workers == 2),
                    "workers_cpu_s": 0.5 * case.workers,
                    "load_1min": 0.5,
                }
            )
    return rows


def test_the_verdicts_are_two_workers_over_one_paired_by_round() -> None:
    settings = study.Settings(out=Path("unused"), arenas_per_worker=(4,))
    passed = study.build_report(_rows(settings, SPEEDS), settings).summary
    cases = passed["cases"]
    assert cases["make_vec async, 2 envs"]["ratio_to_one_worker"] == pytest.approx(1.7)
    assert cases["make_vec async, 2 envs"]["verdict"].startswith("PASS")
    assert cases["batched 2 workers x 4 arenas"]["verdict"].startswith("FAIL")  # 1.0 x 1 worker
    assert cases["batched 1 worker x 4 arenas"]["verdict"] == "-"
    assert cases["ceiling: 2 processes"]["verdict"] == "-"  # the machine's, not a goal
    failed = study.build_report(_rows(settings, {"make_vec async, 2 envs": 150.0}), settings)
    assert failed.summary["cases"]["make_vec async, 2 envs"]["verdict"].startswith("FAIL")


def test_each_two_worker_ratio_is_a_share_of_the_ceiling_of_its_round() -> None:
    settings = study.Settings(out=Path("unused"), arenas_per_worker=(4,))
    summary = study.build_report(_rows(settings, SPEEDS), settings).summary
    assert summary["ceiling"]["ratio"] == pytest.approx(1.8)
    assert summary["cases"]["make_vec async, 2 envs"]["share_of_ceiling"] == pytest.approx(
        1.7 / 1.8
    )
    assert summary["cases"]["batched 2 workers x 4 arenas"]["share_of_ceiling"] == pytest.approx(
        1.0 / 1.8
    )
    assert "share_of_ceiling" not in summary["cases"]["make_vec async, 1 env"]


def test_slower_of_two_is_the_mean_larger_of_two_draws_over_the_mean() -> None:
    assert study.slower_of_two(np.array([1.0, 2.0, 4.0])) == pytest.approx(
        (2 + 4 + 4) / 3 / (7 / 3)
    )
    assert study.slower_of_two(np.full(5, 3.0)) == pytest.approx(1.0)  # no spread, no wait


def test_the_gap_model_adds_sharing_lockstep_and_the_parent_to_the_one_worker_step() -> None:
    settings = study.Settings(out=Path("unused"), arenas_per_worker=(4,))
    rows = _rows(settings, {**SPEEDS, "ceiling: 2 processes": 160.0})
    costs = [
        {
            "repeat": rep,
            "view": view,
            "per_worker": k,
            "cpu_ms": 8.0,
            "cv": 0.2,
            "slower_of_two": 1.1,
        }
        for rep in range(2)
        for view, k in (("make_vec", 1), ("batched", 4))
    ]
    case = study.judged(settings)[0]  # make_vec async, 2 envs
    first = study.gap_model(rows, costs, case, study.ceiling_case(settings))[0]
    # 10 ms a step with 1 worker; the worker's 8 ms slowed by 2 / 1.6 to 10 ms: 2 ms of sharing,
    # 1 ms of waiting for the slower of two, 1 ms more of the parent's CPU (6 ms - 5 ms)
    assert first["sharing_ms"] == pytest.approx(2.0)
    assert first["lockstep_ms"] == pytest.approx(1.0)
    assert first["parent_ms"] == pytest.approx(1.0)
    assert first["predicted_ratio"] == pytest.approx(1.7 * 10 / 14)  # decisions 170 over 100
    assert first["measured_ratio"] == pytest.approx(1.7)
    assert first["predicted_share"] == pytest.approx(1.7 * 10 / 14 / 1.6)
    report = study.build_report(rows, settings, costs=costs)
    assert report.summary["gaps"]["make_vec async, 2 envs"]["lockstep_ms"] == pytest.approx(1.0)
    assert "| make_vec async, 2 envs | 8.00 (0.20) | 1.10 |" in report.body


def test_quick_run(tmp_path: Path) -> None:
    command = [sys.executable, "benchmarks/vector_throughput.py", "--quick", "--out", str(tmp_path)]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode in (0, 1), done.stderr  # 1: the goal missed (not judged here)
    report = json.loads((tmp_path / "vector_throughput.json").read_text())
    summary = report["summary"]
    assert report["metadata"]["settings"]["arenas_per_worker"] == [4, 16]
    cases = summary["cases"]
    assert len(cases) == 2 + 3 + 2 * 3  # ceiling, make_vec, batched with 4 and with 16 arenas
    assert all(found["decisions_per_s"] > 0 for found in cases.values())
    assert summary["ceiling"]["ratio"] > 0
    assert cases["batched 2 workers x 16 arenas"]["share_of_ceiling"] > 0
    assert set(summary["gaps"]) == {
        "make_vec async, 2 envs",
        "batched 2 workers x 4 arenas",
        "batched 2 workers x 16 arenas",
    }
    assert all(found["worker_step_cpu_ms"] > 0 for found in summary["gaps"].values())
    assert [t["arenas"] for t in summary["transport"]] == [4, 16]
    assert all(t["shared_memory_us"] > 0 and t["pickled_us"] > 0 for t in summary["transport"])
    lines = (tmp_path / "vector_throughput.csv").read_text().splitlines()
    assert len(lines) == 1 + 2 * len(cases)  # every case in both rounds
