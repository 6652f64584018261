"""A study's output folder is refused before any work when it cannot be used (in one line, exit 2),
a second run on a folder that a run is writing is refused naming its pid, a refused save ends the
run in one line naming the resume command, and `table1.draw_figure` redraws without ever computing:
missing trials are counted and the command that finishes them is named."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import types
from pathlib import Path
from typing import Any

import pytest

import scenarios
import table1
from tavc_agents.experiments import sweep
from tavc_agents.experiments.folders import LOCK_FILE
from tavc_agents.experiments.study import run_study
from tavc_agents.experiments.sweep import SaveError

ROOT = Path(__file__).resolve().parents[2]
QUICK = ["--quick", "--workers", "1", "--conditions", "softmax,random"]


def never_run(settings: object) -> None:
    raise AssertionError("the study ran although its folder was refused")


NEVER = types.SimpleNamespace(Settings=scenarios.Settings, run=never_run)


@pytest.mark.parametrize(
    ("argv", "reason"),
    [
        (["--out", ""], "--out '' is invalid: an empty name"),
        (["--out="], "--out '' is invalid: an empty name"),
        (["--resume", ""], "--resume '' is invalid: an empty name"),
        (["--out", "{tmp}/afile"], "is not a folder"),
        (["--out", "{tmp}/dangling"], "which does not exist"),
        (["--out", "{tmp}/" + "n" * 300], "300 bytes long"),
    ],
    ids=["empty", "empty-equals", "empty-resume", "file", "dangling-link", "long-name"],
)
def test_an_unusable_output_folder_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], reason: str
) -> None:
    (tmp_path / "afile").write_text("x")
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    given = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code = run_study(NEVER, given, "", prog="python benchmarks/scenarios.py")  # type: ignore[arg-type]
    out, err = capsys.readouterr()
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and reason in err
    assert err.startswith("python benchmarks/scenarios.py: ") and "Writing to" not in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "dangling"]


HOLDER = """
import sys, time
from tavc_agents.experiments.folders import hold_folder
with hold_folder(sys.argv[1]):
    print("HELD", flush=True)
    time.sleep(30)
"""


def test_a_second_run_on_a_folder_being_written_is_refused_naming_the_pid(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(tmp_path)], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "HELD"
        code = run_study(NEVER, ["--out", str(tmp_path)], "", prog="python benchmarks/scenarios.py")  # type: ignore[arg-type]
    finally:
        holder.kill()
        holder.wait(timeout=10)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert f"is being written by another sweep (pid {holder.pid} holds" in err[0]


def test_a_refused_save_ends_the_run_in_one_line_naming_the_resume_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def disk_full(settings: object) -> None:
        raise SaveError("could not save trial 't' to T (No space left on device); ...")

    module = types.SimpleNamespace(Settings=scenarios.Settings, run=disk_full)
    code = run_study(module, ["--out", str(tmp_path)], "", prog="python benchmarks/scenarios.py")  # type: ignore[arg-type]
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1
    assert "No space left on device" in err[0]
    assert err[0].endswith(f"continue with `python benchmarks/scenarios.py --resume {tmp_path}`")
    assert (tmp_path / LOCK_FILE).is_file()  # held while it ran (and git ignores it)


# -- a redraw never computes -------------------------------------------------------------------------
@pytest.fixture(scope="module")
def table1_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = tmp_path_factory.mktemp("table1") / "run"
    assert run_study(table1, [*QUICK, "--out", str(run)], "") == 0
    return run


@pytest.fixture
def folder(table1_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A copy of a finished quick table1 run, in which nothing may compute."""

    def computing(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("a redraw computed a trial")

    monkeypatch.setattr(sweep, "run_trial", computing)
    return Path(shutil.copytree(table1_run, tmp_path / "run"))


def redraw(folder: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    before = sorted(p.name for p in (folder / "trials").iterdir())
    try:
        table1.draw_figure(folder, "figure2.png", folder / "figure.png")
    except ValueError as error:
        code, message = 2, str(error)
    else:
        code, message = 0, ""
    assert sorted(p.name for p in (folder / "trials").iterdir()) == before  # nothing written
    return code, message


def test_a_redraw_of_a_complete_folder_draws(
    folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _ = redraw(folder, capsys)
    assert code == 0 and (folder / "figure.png").is_file()


def test_a_redraw_with_more_trials_in_the_provenance_computes_nothing(
    folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    meta = json.loads((folder / "provenance.json").read_text())
    meta["settings"]["trials"] = 40
    (folder / "provenance.json").write_text(json.dumps(meta))
    code, line = redraw(folder, capsys)
    assert code == 2 and not (folder / "figure.png").exists()
    assert "holds 4 of the 80 trials its provenance records (76 missing" in line
    assert f"`python benchmarks/table1.py --resume {folder} --preset dahl2004 --trials 40 " in line


def test_a_redraw_of_an_incomplete_folder_names_what_finishes_it(
    folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (folder / "trials" / "random_seed1.json").unlink()
    code, line = redraw(folder, capsys)
    assert code == 2 and "holds 3 of the 4 trials" in line and "e.g. random_seed1" in line
    assert "--convergence-h 0.3 --measured-h 0.2 --conditions softmax,random" in line


@pytest.mark.parametrize("settings", ["absent", [], {"preset": "dahl2004"}])
def test_a_provenance_without_settings_is_named_in_one_line(
    folder: Path, capsys: pytest.CaptureFixture[str], settings: object
) -> None:
    meta = json.loads((folder / "provenance.json").read_text())
    if settings == "absent":
        del meta["settings"]
    else:
        meta["settings"] = settings
    (folder / "provenance.json").write_text(json.dumps(meta))
    code, line = redraw(folder, capsys)
    assert code == 2 and f"{folder / 'provenance.json'} records no settings" in line
