"""Damaged run folders and input files, as the package's readers meet them (issue 28, item 4).

A trial slot, a provenance.json, a model, a task YAML or a report replaced by a folder, a link
(dangling, to a good copy, to /dev/zero), a FIFO, garbled or truncated bytes, `[]`, a value that
is not finite under a valid checksum, a 5000-digit integer or a file over its size bound is named
in one line; a resumed sweep moves a damaged trial slot aside (never deleting it) and runs that
trial again, and resumes the intact ones. Every test runs under `no_hang`: a FIFO that blocked a
reader would fail the test instead of hanging the suite."""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tavc_agents.experiments.files import (
    RECORD_MAX_BYTES,
    CorruptFileError,
    read_csv,
    read_record,
    read_report,
    write_record,
)
from tavc_agents.experiments.provenance import (
    PROVENANCE_FILE,
    PROVENANCE_MAX_BYTES,
    load_provenance,
)
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import run_recorded
from tavc_agents.experiments.sweep import (
    TRIALS,
    TrialSpec,
    json_jobs,
    run_jobs,
    run_sweep,
    saved_results,
)
from tavc_agents.model import CompletionModel, model_path
from tests.damage import BAD_FILES, DAMAGES, NOT_FILES, no_hang, plant

SPECS = [
    TrialSpec(
        key=f"t{k}",
        allocator="random",
        seed=k,
        convergence_s=10.0,
        measured_s=10.0,
        snapshot_every_s=10.0,
    )
    for k in range(2)
]


@pytest.fixture(autouse=True)
def guard() -> Iterator[None]:
    with no_hang(120):
        yield


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An undisturbed run folder: trials in trials/, provenance beside them."""
    folder = tmp_path_factory.mktemp("clean_run")
    run_recorded(SPECS, TRIALS, folder / "trials", folder, {"n": 2}, workers=1)
    return folder


def _copy(clean: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "run"
    shutil.copytree(clean, folder)
    return folder


def _same(a: TrialResult, b: TrialResult) -> bool:
    da, db = a.to_dict(), b.to_dict()
    da.pop("wall_s")
    db.pop("wall_s")
    return json.dumps(da, sort_keys=True) == json.dumps(db, sort_keys=True)


def _one_line_naming(error: BaseException, path: Path) -> None:
    assert isinstance(error, ValueError)
    assert str(path) in str(error)
    assert "\n" not in str(error)


# -- trial records ----------------------------------------------------------------------------
@pytest.mark.parametrize("how", DAMAGES)
def test_a_damaged_record_is_refused_naming_it(clean: Path, tmp_path: Path, how: str) -> None:
    path = tmp_path / "t0.json"
    plant(path, how, (clean / "trials" / "t0.json").read_bytes(), RECORD_MAX_BYTES)
    with pytest.raises(CorruptFileError) as caught:
        TrialResult.load(path)
    _one_line_naming(caught.value, path)


def test_nan_under_a_valid_checksum_is_refused_and_never_saved(clean: Path, tmp_path: Path) -> None:
    raw = (clean / "trials" / "t0.json").read_bytes()
    path = tmp_path / "t0.json"
    plant(path, "nan", raw)
    with pytest.raises(CorruptFileError, match=r"t0\.json holds the value NaN"):
        read_record(path)
    result = TrialResult.load(clean / "trials" / "t0.json")
    result.jammed_s = float("inf")
    with pytest.raises(ValueError, match=r"t1\.json: the value at \.jammed_s is not a finite"):
        result.save(tmp_path / "t1.json")
    assert not (tmp_path / "t1.json").exists()


def test_job_records_may_hold_nan_for_undefined_but_not_infinity(tmp_path: Path) -> None:
    """Study jobs' results use NaN for "undefined" (committed regime-map records do)."""
    path = tmp_path / "j.json"
    write_record(path, {"result": {"q_gap": float("nan")}}, nan=True)
    assert read_record(path, nan=True)["result"]["q_gap"] != 0  # NaN read back
    with pytest.raises(CorruptFileError, match="holds the value NaN"):
        read_record(path)
    with pytest.raises(ValueError, match=r"the value at \.result\.q_gap is not a finite"):
        write_record(path, {"result": {"q_gap": float("inf")}}, nan=True)


# -- a resumed sweep ---------------------------------------------------------------------------
@pytest.mark.parametrize("how", DAMAGES)
def test_a_resumed_sweep_moves_a_damaged_slot_aside_and_runs_it_again(
    clean: Path, tmp_path: Path, how: str
) -> None:
    folder = _copy(clean, tmp_path) / "trials"
    slot = folder / "t0.json"
    plant(slot, how, (clean / "trials" / "t0.json").read_bytes(), RECORD_MAX_BYTES)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        results = run_sweep(SPECS, folder, workers=1)
    aside = "t0.json.not-a-file" if how in NOT_FILES else "t0.json.damaged"
    message = err.getvalue()
    assert f"{slot} " in message
    assert f"moved aside to {aside}; running trial 't0' again" in message
    assert len(message.strip().splitlines()) == 1  # one line
    assert os.path.lexists(folder / aside)  # kept, not deleted
    for spec in SPECS:  # the damaged one ran again, the other was resumed as it was
        assert _same(results[spec.key], TrialResult.load(clean / "trials" / f"{spec.key}.json"))
    assert (folder / "t1.json").read_bytes() == (clean / "trials" / "t1.json").read_bytes()
    assert _same(TrialResult.load(slot), results["t0"])


def test_a_second_damage_of_the_same_slot_is_kept_too(clean: Path, tmp_path: Path) -> None:
    folder = _copy(clean, tmp_path) / "trials"
    raw = (clean / "trials" / "t0.json").read_bytes()
    for _ in range(2):
        plant(folder / "t0.json", "fifo", raw)
        with contextlib.redirect_stderr(io.StringIO()):
            run_sweep(SPECS, folder, workers=1)
    assert sorted(p.name for p in folder.glob("t0.json.*")) == [
        "t0.json.not-a-file",
        "t0.json.not-a-file.1",
    ]


def test_an_interim_report_names_a_damaged_slot_and_leaves_it(clean: Path, tmp_path: Path) -> None:
    folder = _copy(clean, tmp_path) / "trials"
    plant(folder / "t0.json", "fifo", b"")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        found = saved_results(SPECS, TRIALS, folder)
    assert sorted(found) == ["t1"]
    assert f"{folder / 't0.json'} is a FIFO" in err.getvalue()
    assert (folder / "t0.json").is_fifo()


@dataclass(frozen=True)
class Half:
    x: int


def _half(job: Half) -> dict[str, Any]:
    return {"half": job.x / 2}


@pytest.mark.parametrize("how", ["fifo", "infinity", "huge_int"])
def test_a_damaged_job_record_is_moved_aside_and_rerun(tmp_path: Path, how: str) -> None:
    kind = json_jobs(_half, key=lambda job: f"j{job.x}")
    jobs = [Half(1), Half(2)]
    run_jobs(jobs, kind, tmp_path, workers=1)
    raw = (tmp_path / "j1.json").read_bytes()
    plant(tmp_path / "j1.json", how, raw)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        results = run_jobs(jobs, kind, tmp_path, workers=1)
    assert results == {"j1": {"half": 0.5}, "j2": {"half": 1.0}}
    assert "running run 'j1' again" in err.getvalue()
    assert (tmp_path / "j1.json").read_bytes() == raw


# -- provenance --------------------------------------------------------------------------------
@pytest.mark.parametrize("how", DAMAGES)
def test_a_damaged_provenance_is_named_in_one_line(clean: Path, tmp_path: Path, how: str) -> None:
    path = tmp_path / PROVENANCE_FILE
    plant(path, how, (clean / PROVENANCE_FILE).read_bytes(), PROVENANCE_MAX_BYTES)
    with pytest.raises(CorruptFileError) as caught:
        load_provenance(tmp_path)
    _one_line_naming(caught.value, path)


@pytest.mark.parametrize("how", NOT_FILES)
def test_a_provenance_that_is_not_a_file_stops_a_run_before_any_trial(
    clean: Path, tmp_path: Path, how: str
) -> None:
    folder = _copy(clean, tmp_path)
    (folder / "trials" / "t0.json").unlink()  # one trial to run
    path = folder / PROVENANCE_FILE
    plant(path, how, (clean / PROVENANCE_FILE).read_bytes())
    with pytest.raises(CorruptFileError) as caught:
        run_recorded(SPECS, TRIALS, folder / "trials", folder, {"n": 2}, workers=1)
    _one_line_naming(caught.value, path)
    assert not (folder / "trials" / "t0.json").exists()  # refused before it ran


@pytest.mark.parametrize("how", BAD_FILES)
def test_a_damaged_provenance_file_is_named_and_replaced(
    clean: Path, tmp_path: Path, how: str
) -> None:
    folder = _copy(clean, tmp_path)
    path = folder / PROVENANCE_FILE
    plant(path, how, (clean / PROVENANCE_FILE).read_bytes(), PROVENANCE_MAX_BYTES)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        _, meta = run_recorded(SPECS, TRIALS, folder / "trials", folder, {"n": 2}, workers=1)
    assert f"{path} " in err.getvalue()
    assert "replaced by this run's provenance" in err.getvalue()
    assert meta["trials_resumed"] == 2
    assert load_provenance(folder) == json.loads(json.dumps(meta))


# -- the other readers -------------------------------------------------------------------------
@pytest.mark.parametrize("how", ["fifo", "dev_zero", "list", "infinity", "too_large"])
def test_a_damaged_model_file_is_named(tmp_path: Path, how: str) -> None:
    path = tmp_path / "model.json"
    plant(path, how, model_path("dahl2004").read_bytes(), 16 * 1024 * 1024)
    with pytest.raises(ValueError) as caught:
        CompletionModel.load(path)
    _one_line_naming(caught.value, path)


@pytest.mark.parametrize("how", ["fifo", "folder", "garbled", "too_large"])
def test_a_damaged_report_or_table_is_named(tmp_path: Path, how: str) -> None:
    path = tmp_path / "references.csv"
    plant(path, how, b"scenario,stay_per_h\nx,1.0\n", 64 * 1024 * 1024)
    with pytest.raises(CorruptFileError) as caught:
        list(read_csv(path))
    _one_line_naming(caught.value, path)
    report = tmp_path / "report.json"
    plant(report, how, b'{"summary": {}}', 64 * 1024 * 1024)
    with pytest.raises(CorruptFileError) as caught:
        read_report(report)
    _one_line_naming(caught.value, report)


@pytest.mark.parametrize("how", ["fifo", "dev_zero", "garbled", "too_large"])
def test_a_damaged_task_yaml_is_named(tmp_path: Path, how: str) -> None:
    pytest.importorskip("yaml")
    from tavc_env.adapters.benchmarl.config import TASK_DIR, TASK_MAX_BYTES, load_task_config

    path = tmp_path / "dahl2004.yaml"
    good = (TASK_DIR / "dahl2004.yaml").read_bytes()
    plant(path, how, good + b"\n: [\n" if how == "garbled" else good, TASK_MAX_BYTES)
    with pytest.raises(ValueError) as caught:
        load_task_config("dahl2004", path)
    _one_line_naming(caught.value, path)


def test_plot_timeline_of_a_folder_is_one_line(tmp_path: Path) -> None:
    from tavc_agents.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), pytest.raises(SystemExit) as code:
        main(["plot", "timeline", str(tmp_path), "--out", str(tmp_path / "t.png")])
    assert code.value.code == 2
    assert f"{tmp_path} is a folder" in err.getvalue()  # refused by the command line's check
