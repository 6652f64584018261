"""Where studies write: a new run folder by default (never the committed reference), an explicit
resume, `--update-reference`; and the comparison of a run's tables with the reference."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import table1
from tavc_agents.experiments.study import RESULTS_DIR, RUNS_DIR, differing_cells, run_study

QUICK = ["--quick", "--workers", "1", "--conditions", "softmax,random"]


def test_default_is_a_new_run_folder_never_the_reference(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)
    settings = table1.Settings()
    assert settings.out_dir().parent == RUNS_DIR
    assert settings.out_dir().name.startswith("table1_dahl2004_scaled-")
    assert settings.sized().out_dir() == settings.out_dir()  # chosen once
    assert (
        table1.Settings(update_reference=True).out_dir() == RESULTS_DIR / "table1_dahl2004_scaled"
    )
    assert table1.Settings(out=tmp_path / "mine").out_dir() == tmp_path / "mine"
    assert table1.Settings(resume=tmp_path).out_dir() == tmp_path


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"out": Path("a"), "resume": Path(".")}, r"--out and --resume are invalid together"),
        ({"out": Path("a"), "update_reference": True}, r"--out and --update-reference are invalid"),
        (
            {"resume": Path("no/such/run")},
            r"--resume 'no/such/run' is invalid; allowed: the folder",
        ),
    ],
)
def test_conflicting_or_missing_folders_are_refused(
    kwargs: dict[str, object], pattern: str
) -> None:
    with pytest.raises(ValueError, match=pattern):
        table1.Settings(**kwargs)  # type: ignore[arg-type]


def test_a_run_says_where_it_writes_and_compares_with_the_reference(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    first, second = tmp_path / "first", tmp_path / "second"
    assert run_study(table1, [*QUICK, "--out", str(first)], "") == 0
    said = capsys.readouterr().out
    assert said.startswith(f"Writing to {first}/\n") and f"Results in {first}/" in said
    # the same seeds and code give the same table, bit for bit
    shutil.copytree(first, second)
    assert table1.agreement(first, second) == [
        f"table1.csv: identical to the committed reference {second / 'table1.csv'}"
    ]
    # a changed cell is found, and judged against the noise of the two runs
    rows = (second / "table1.csv").read_text().splitlines()
    cells = rows[1].split(",")
    cells[2] = str(float(cells[2]) + 50.0)  # mu_softmax of the first state, 50 points off
    (second / "table1.csv").write_text("\n".join([rows[0], ",".join(cells), *rows[2:]]) + "\n")
    assert differing_cells(first / "table1.csv", second / "table1.csv")[0] == 1
    lines = table1.agreement(first, second)
    assert "1 of" in lines[0] and "cells differ" in lines[0]
    assert lines[1].startswith("Table 1: ") and "agree with the reference within 1.96" in lines[1]


def test_resume_reuses_the_saved_trials(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    assert run_study(table1, [*QUICK, "--out", str(run)], "") == 0
    saved = {p.name: p.stat().st_mtime_ns for p in (run / "trials").glob("*.json")}
    capsys.readouterr()
    assert run_study(table1, [*QUICK, "--resume", str(run)], "") == 0
    assert {p.name: p.stat().st_mtime_ns for p in (run / "trials").glob("*.json")} == saved


def test_an_interrupted_study_says_in_one_line_how_to_resume(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Ctrl-C (or SIGTERM during a sweep, which raises the same) ends with exit 130 and one line
    # naming the --resume command, not a traceback
    import types

    import scenarios

    def interrupted(settings: object) -> None:
        raise KeyboardInterrupt("signal 15")

    module = types.SimpleNamespace(Settings=scenarios.Settings, run=interrupted)
    code = run_study(module, ["--out", str(tmp_path)], "", prog="python benchmarks/scenarios.py")  # type: ignore[arg-type]
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130
    assert err == [
        f"Interrupted. The finished jobs are saved in {tmp_path}/; continue with "
        f"`python benchmarks/scenarios.py --resume {tmp_path}` (and the same other options)."
    ]
