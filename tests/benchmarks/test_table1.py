"""Smoke runs of the main job, the table1 study (`benchmarks/table1.py`), at a tiny size through
its command line: the outputs exist and hold the paper's table (16 f:s states, the paper's
columns, Equation 3), a second identical invocation resumes without recomputing any trial and
reproduces the report byte for byte, the homogeneous preset writes the occupancy table, and bad
settings are refused before any trial runs."""

from __future__ import annotations

import contextlib
import csv
import importlib.util
import io
import json
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

import table1 as study
from tavc_agents.analysis import reports
from tavc_agents.experiments.study import parse_settings
from tavc_env import metrics

ROOT = Path(__file__).resolve().parents[2]
TINY = ["--trials", "2", "--convergence-h", "0.05", "--measured-h", "0.05", "--workers", "1"]
KEYS = [f"{c}_seed{k}" for k in range(2) for c in ("softmax", "epsilon", "random")]
STATES = [f"{f}:{s}" for f in range(4) for s in range(4)]


@pytest.fixture(scope="module")
def table1() -> ModuleType:
    return study


def run_main(table1: ModuleType, argv: list[str]) -> tuple[int, str]:
    """What `python benchmarks/table1.py ARGV` does, in this process (its progress bar, on
    stderr, in the same text)."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        outcome = table1.run(parse_settings(table1.Settings, argv, ""))
        print(outcome.text)
    return 0, buf.getvalue()


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def have_matplotlib() -> bool:
    return importlib.util.find_spec("matplotlib") is not None


@pytest.fixture(scope="module")
def first_run(table1, tmp_path_factory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("table1")
    code, printed = run_main(table1, [*TINY, "--out", str(out)])
    return {"out": out, "code": code, "printed": printed}


def test_outputs_exist(first_run) -> None:
    out: Path = first_run["out"]
    assert first_run["code"] == 0
    for name in ("table1.md", "table1.csv", "table1.json"):
        assert (out / name).stat().st_size > 0, name
    assert sorted(p.name for p in (out / "trials").glob("*.json")) == sorted(
        f"{k}.json" for k in KEYS
    )
    if have_matplotlib():
        for name in ("figure2.png", "performance.png"):
            assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    assert "(resumed)" not in first_run["printed"]  # a fresh run computes every trial
    assert "wall time" in first_run["printed"]


def test_markdown_holds_the_papers_table(first_run) -> None:
    md = (first_run["out"] / "table1.md").read_text()
    for state in STATES:
        assert f"\n| {state} |" in md, state
    header = next(line for line in md.splitlines() if line.startswith("| f:s |"))
    for column in (
        "mu softmax",
        "sd softmax",
        "mu random",
        "sd random",
        "mu epsilon",
        "| T |",
        "mu_a - mu_r",
        "(mu_a - mu_r)/mu_r",
        "mu_a - T",
        "(mu_a - T)/T",
        "paper mu_a (sd)",
        "paper mu_r (sd)",
    ):
        assert column in header, column
    # the paper's numbers sit next to ours (row 2:1: mu_a 19.4 (7.4), mu_r 15.7 (2.3))
    row = next(line for line in md.splitlines() if line.startswith("| 2:1 |"))
    assert "19.4 (7.4)" in row and "15.7 (2.3)" in row
    assert "erratum" in md
    assert "Performance" in md and "Welch" in md
    assert "Number of robots on the high-value circuit" in md


def test_csv_and_json_are_consistent(first_run) -> None:
    out: Path = first_run["out"]
    rows = read_csv(out / "table1.csv")
    assert [r["state"] for r in rows] == STATES
    expected = metrics.combinatorial_expectation(3, 3)
    for r in rows:
        f, s = map(int, r["state"].split(":"))
        assert float(r["T"]) == pytest.approx(expected[(f, s)])
        a_minus_t = float(r["mu_softmax"]) - expected[(f, s)]
        assert float(r["a_minus_T"]) == pytest.approx(a_minus_t, abs=1e-9)
        assert float(r["a_minus_r"]) == pytest.approx(
            float(r["mu_softmax"]) - float(r["mu_random"]), abs=1e-9
        )
    # every condition's mean distribution covers the whole measured period
    for cond in ("softmax", "epsilon", "random"):
        assert sum(float(r[f"mu_{cond}"]) for r in rows) == pytest.approx(100.0, abs=1e-6)
    payload = json.loads((out / "table1.json").read_text())
    settings = payload["metadata"]["settings"]
    assert settings["trials"] == 2 and settings["preset"] == "dahl2004"
    for cond in ("softmax", "epsilon", "random"):
        assert payload["summary"][f"performance_{cond}"]["n"] == 2
        assert payload["summary"][f"performance_{cond}"]["mean"] > 0


def test_second_invocation_resumes_and_reproduces(table1, first_run) -> None:
    out: Path = first_run["out"]
    trials = sorted((out / "trials").glob("*.json"))
    stamps = {p.name: p.stat().st_mtime_ns for p in trials}
    contents = {p.name: p.read_bytes() for p in trials}
    before = {name: (out / name).read_bytes() for name in ("table1.csv", "table1.md")}
    code, printed = run_main(table1, [*TINY, "--out", str(out)])
    assert code == 0
    for key in KEYS:
        assert f"{key} (resumed)" in printed, key
    after = sorted((out / "trials").glob("*.json"))
    assert {p.name: p.stat().st_mtime_ns for p in after} == stamps  # no trial recomputed
    assert {p.name: p.read_bytes() for p in after} == contents
    # the report names the run that computed the trials: regenerated, it is the same file
    assert {name: (out / name).read_bytes() for name in before} == before


def test_homogeneous_preset_writes_the_occupancy_table(table1, tmp_path, monkeypatch) -> None:
    # Plotting is covered (and currently broken) below; here only the tables.
    monkeypatch.setattr(reports, "have_matplotlib", lambda: False)
    argv = [*TINY, "--preset", "dahl2004_homogeneous", "--out", str(tmp_path)]
    code, _ = run_main(table1, argv)
    assert code == 0
    md = (tmp_path / "table1.md").read_text()
    assert "Number of robots on the high-value circuit" in md
    assert "| f:s |" not in md  # no fast / slow split in a homogeneous team
    header = next(line for line in md.splitlines() if line.startswith("| condition | 0 on high"))
    assert "6 on high" in header and "most frequent" in header
    rows = read_csv(tmp_path / "table1.csv")
    assert [r["condition"] for r in rows] == ["softmax", "epsilon", "random"]
    for r in rows:
        shares = [float(r[f"on_high_{k}"]) for k in range(7)]
        assert sum(shares) == pytest.approx(1.0, abs=1e-9)
    payload = json.loads((tmp_path / "table1.json").read_text())
    assert payload["metadata"]["settings"]["preset"] == "dahl2004_homogeneous"
    assert "performance_softmax" in payload["summary"]


@pytest.mark.skipif(not have_matplotlib(), reason="matplotlib not installed")
def test_homogeneous_preset_with_matplotlib_completes(table1, tmp_path) -> None:
    argv = [*TINY, "--preset", "dahl2004_homogeneous", "--out", str(tmp_path)]
    code, _ = run_main(table1, argv)
    assert code == 0
    assert (tmp_path / "performance.png").exists()
    assert not (tmp_path / "figure2.png").exists()  # no f:s states to compare


def test_the_script_is_the_study_on_the_command_line(tmp_path: Path) -> None:
    out = tmp_path / "q"
    done = subprocess.run(
        [
            sys.executable,
            "benchmarks/table1.py",
            *TINY,
            "--conditions",
            "random",
            "--out",
            str(out),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    assert "wall time" in done.stdout and (out / "table1.md").exists()
    assert sorted(p.name for p in (out / "trials").glob("*.json")) == [
        "random_seed0.json",
        "random_seed1.json",
    ]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--trials", "0"], "trials = 0 is invalid; allowed: an integer >= 1"),
        (["--measured-h", "inf"], "measured_h = inf is invalid"),
        (["--conditions", "softmax,bogus"], "conditions = 'softmax,bogus' is invalid"),
        (["--preset", "nowhere"], "preset = 'nowhere' is invalid; allowed: one of"),
        (["--set", "wings=2"], "unknown configuration key(s) ['wings']"),
        (["--set", "wings"], "--set 'wings' is invalid; allowed: KEY=VALUE"),
    ],
)
def test_bad_settings_are_refused_before_any_trial(
    argv: list[str], message: str, tmp_path: Path
) -> None:
    done = subprocess.run(
        [sys.executable, "benchmarks/table1.py", *argv, "--out", str(tmp_path / "x")],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert done.returncode != 0
    assert message in " ".join((done.stdout + done.stderr).split()), done.stderr
    assert not (tmp_path / "x").exists()


def test_draw_figure_writes_exactly_the_figure_asked_for(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib", reason="plots need the plot extra")
    out_dir = tmp_path / "t1"
    argv = ["--quick", "--workers", "1", "--out", str(out_dir)]
    argv += ["--conditions", "softmax,random", "--set", "source_service_s=12"]
    assert study.main(argv) == 0
    before = {p.name: p.read_bytes() for p in out_dir.rglob("*") if p.is_file()}
    target = tmp_path / "t1.png"
    study.draw_figure(out_dir, "figure2.png", target)
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # nothing else written, nothing in the output folder touched
    assert {p.name: p.read_bytes() for p in out_dir.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t1", "t1.png"]
    study.draw_figure(out_dir, "performance.png", target)
    with pytest.raises(ValueError, match="an output folder of the table1 study"):
        study.draw_figure(tmp_path, "figure2.png", tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()
