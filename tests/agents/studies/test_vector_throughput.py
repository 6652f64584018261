"""The vector throughput study: its settings, the verdict it draws from measured rows, and a smoke
run. Nothing here is timed: speed is judged by the benchmark itself, as ratios of figures measured
in the same run (the committed results are figures of their machine)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tavc_agents.studies import vector_throughput as study

ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"repeats": 0}, "repeats"),
        ({"steps": 0}, "steps"),
        ({"arenas_per_worker": 0}, "arenas_per_worker"),
        ({"episode_s": -1.0}, "episode_s"),
        ({"workers": 2}, "workers"),
    ],
)
def test_bad_settings_are_refused(changes: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field} = .* is invalid; allowed: "):
        study.Settings(**changes)


def _rows(settings: study.Settings, async_two: float) -> list[dict[str, Any]]:
    """Two rounds of every case: 100 decisions per second, async 2 at `async_two`."""
    rows = []
    for rep in range(2):
        for case in settings.cases:
            speed = async_two if case.name == "make_vec async, 2 envs" else 100.0
            rows.append(
                {
                    "case": case.name,
                    "repeat": rep,
                    "decisions_per_s": speed * (1 + 0.01 * rep),
                    "decisions": 100,
                    "wall_s": 1.0,
                    "cpu_s": 0.5,
                    "workers_cpu_s": 0.5 * case.workers,
                    "load_1min": 0.5,
                }
            )
    return rows


def test_the_verdicts_are_two_workers_over_one_paired_by_round() -> None:
    settings = study.Settings(out=Path("unused"))
    passed = study.build_report(_rows(settings, 170.0), settings).summary["cases"]
    assert passed["make_vec async, 2 envs"]["ratio_to_one_worker"] == pytest.approx(1.7)
    assert passed["make_vec async, 2 envs"]["verdict"].startswith("PASS")
    assert passed["batched 2 workers x 4 arenas"]["verdict"].startswith("FAIL")  # 1.0 x 1 worker
    assert passed["batched 1 worker x 4 arenas"]["verdict"] == "-"
    failed = study.build_report(_rows(settings, 150.0), settings).summary["cases"]
    assert failed["make_vec async, 2 envs"]["verdict"].startswith("FAIL")


def test_quick_run(tmp_path: Path) -> None:
    command = [sys.executable, "benchmarks/vector_throughput.py", "--quick", "--out", str(tmp_path)]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode in (0, 1), done.stderr  # 1: the goal missed (not judged here)
    summary = json.loads((tmp_path / "vector_throughput.json").read_text())["summary"]
    assert len(summary["cases"]) == 6
    assert all(found["decisions_per_s"] > 0 for found in summary["cases"].values())
    assert summary["transport"]["shared_memory_us"] > 0 and summary["transport"]["pickled_us"] > 0
    lines = (tmp_path / "vector_throughput.csv").read_text().splitlines()
    assert len(lines) == 1 + 2 * 6  # every case in both rounds
