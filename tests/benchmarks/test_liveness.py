"""The liveness study (benchmarks/liveness.py) at its quick size, and
the random arena generator it draws from (`tavc_agents.experiments.arenas`)."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import liveness as study
from liveness import (
    ROBOTS,
    arena_config,
    draw_arena,
    random_arenas,
    refusal_category,
)

ROOT = Path(__file__).resolve().parents[2]


def test_the_generator_is_deterministic_per_seed_and_yields_only_valid_arenas() -> None:
    first = random_arenas(6, np.random.default_rng(7))
    again = random_arenas(6, np.random.default_rng(7))
    other = random_arenas(6, np.random.default_rng(8))
    assert first == again and first.arenas != other.arenas
    assert first.draws == len(first.arenas) + sum(first.refused.values())
    for description in first.arenas:
        config = arena_config(json.loads(json.dumps(description)))  # survives JSON as it is
        assert ROBOTS[0] <= config.n_robots <= ROBOTS[1] and 1 <= config.n_circuits <= 4
        assert all(0.1 <= r.speed <= 0.4 for r in config.robots)
    # most draws are refused; each refusal is counted under the reason validation gave
    assert first.refused and set(first.refused) <= {
        "waiting line too short",
        "stations too close",
        "station outside the arena",
        "robots: too many for the floor",
        "dt",
    }


def test_refused_draws_are_named_by_what_validation_refused() -> None:
    rng = np.random.default_rng(0)
    reasons = set()
    for _ in range(200):
        try:
            arena_config(draw_arena(rng, robots=24, circuits=4))
        except ValueError as error:
            reasons.add(refusal_category(error))
    assert "waiting line too short" in reasons and "stations too close" in reasons
    with pytest.raises(ValueError, match=r"^count = -1 is invalid"):
        random_arenas(-1, rng)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("hours", 0.0),
        ("seeds", 0),
        ("teams", (7,)),
        ("per_circuit", ()),
        ("arenas", -1),
        ("random_hours", float("nan")),
        ("max_gap_min", -1.0),
        ("workers", 0),
    ],
)
def test_bad_settings_are_refused_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=rf"^{field} = .* is invalid; allowed: "):
        study.Settings(**{field: value})  # type: ignore[arg-type]


def test_a_team_of_fourteen_is_refused_in_dahl2004() -> None:
    assert "a team of at most 13 robots" in study.refused_team()
    assert study.dahl_team(6).n_robots == 12


def test_the_longest_gap_counts_the_start_and_the_end() -> None:
    # robot 0 delivers at 100 and 250, robot 1 at 400; robot 2 never: the run ends at 1000
    gaps = study.longest_gaps([100.0, 250.0, 400.0], [0, 0, 1], 3, 1000.0)
    assert gaps == [(250.0, 1000.0), (400.0, 1000.0), (0.0, 1000.0)]
    assert study.clopper_pearson(0, 10)[2] == pytest.approx(1 - 0.025 ** (1 / 10))


def test_quick_run_end_to_end_and_a_rerun_resumes(tmp_path: Path) -> None:
    settings = study.Settings(quick=True, quiet=True, workers=1, out=tmp_path)
    outcome = study.run(settings)
    assert not outcome.failed and outcome.text.startswith("- **PASS**: 0 unreported jams")
    jobs, drawn = study.trials(settings)
    assert len(jobs) == 2 + 2 + 3 and drawn["arenas"] == 3
    with open(tmp_path / "liveness.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["arm"] for r in rows] == ["dahl2004"] * 2 + ["lanes"] * 2 + ["random"] * 3
    assert {int(r["robots"]) for r in rows if r["arm"] == "lanes"} == {6, 48}
    for row in rows:
        assert int(row["jams"]) >= 0 and 0 < float(row["longest_gap_s"]) <= 180.0 + 1e-6
    summary = json.loads((tmp_path / "liveness.json").read_text())["summary"]
    assert summary["overall"]["trials"] == 7 and summary["refused_team"]["robots"] == 14
    assert summary["random_arenas"]["draws"] >= 3
    files = sorted((tmp_path / "trials").glob("*.json"))
    assert len(files) == 7 and max(f.stat().st_size for f in files) < 2000
    stamps = {f.name: f.stat().st_mtime_ns for f in files}
    report = (tmp_path / "liveness.md").read_text()
    # the script, run again: every trial resumed from its file, the same report
    command = [sys.executable, "benchmarks/liveness.py", "--quick", "--quiet", "--workers", "1"]
    done = subprocess.run(
        [*command, "--out", str(tmp_path)], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert {f.name: f.stat().st_mtime_ns for f in (tmp_path / "trials").glob("*.json")} == stamps
    assert (tmp_path / "liveness.md").read_text() == report
    # a tight limit turns the same (resumed) trials into unreported jams: the script fails
    tight = subprocess.run(
        [*command, "--out", str(tmp_path), "--max-gap-min", "0.5"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert tight.returncode == 1 and "FAIL: trial" in tight.stderr
