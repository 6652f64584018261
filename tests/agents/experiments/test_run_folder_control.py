"""A sweep's hold on its run folder: the folder is checked before any work, locked while it is
written (a second sweep is refused at once, naming the holder's pid), a refused save stops the
sweep at once, Ctrl-C and SIGTERM stop a pool sweep within seconds, and a trial's record carries
its periods. Every wait here has a short timeout, so no case can hang."""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tavc_agents.experiments import folders
from tavc_agents.experiments.files import read_record
from tavc_agents.experiments.folders import (
    LOCK_FILE,
    FolderError,
    FolderInUseError,
    check_out_folder,
    hold_folder,
)
from tavc_agents.experiments.sweep import (
    TRIALS,
    JobKind,
    SaveError,
    TrialSpec,
    json_jobs,
    run_jobs,
    spec_record,
)

ROOT = Path(__file__).resolve().parents[3]


# -- the output folder, checked before any work -----------------------------------------------------
def test_a_folder_that_cannot_be_written_is_refused_in_one_line(tmp_path: Path) -> None:
    afile = tmp_path / "afile"
    afile.write_text("x")
    dangling = tmp_path / "dangling"
    dangling.symlink_to(tmp_path / "nowhere")
    cases = {
        "": "an empty name",
        str(afile): "is not a folder",
        str(afile / "below"): "is not a folder",
        str(dangling): "which does not exist",
        str(dangling / "below"): "which does not exist",
        str(tmp_path / ("x" * 300)): "300 bytes long",
    }
    for given, reason in cases.items():
        with pytest.raises(FolderError) as caught:
            check_out_folder(given)
        message = str(caught.value)
        assert reason in message and "\n" not in message and message.startswith("--out "), given
    assert afile.read_text() == "x" and not (tmp_path / "nowhere").exists()


def test_a_folder_this_user_may_not_write_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # os.access answers as the kernel would for this user: a superuser passes it except on a
    # read-only file system (EROFS), so the permission case is played by os.access itself
    monkeypatch.setattr(folders.os, "access", lambda path, mode: False)
    with pytest.raises(FolderError, match="may not write in"):
        check_out_folder(tmp_path / "new")
    with (
        pytest.raises(FolderError, match="cannot write in the output folder"),
        hold_folder(tmp_path / "new"),
    ):
        pass


@pytest.mark.skipif(os.geteuid() == 0, reason="a superuser writes in a read-only folder")
def test_a_read_only_folder_is_refused_before_any_job(tmp_path: Path) -> None:
    trials = tmp_path / "trials"
    trials.mkdir()
    trials.chmod(0o555)
    try:
        with pytest.raises(FolderError, match="cannot write in"):
            run_jobs([Marked("a", 0.0, str(tmp_path))], MARKED, trials, workers=1)
    finally:
        trials.chmod(0o755)
    assert not (tmp_path / "started").exists()


def test_good_folders_pass(tmp_path: Path) -> None:
    (tmp_path / "there").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "there")
    for given in ("new/and/deeper", "there", "link", "link/new"):
        assert check_out_folder(tmp_path / given) == tmp_path / given


# -- the lock --------------------------------------------------------------------------------------
HOLDER = """
import sys, time
from tavc_agents.experiments.folders import hold_folder
with hold_folder(sys.argv[1]):
    print("HELD", flush=True)
    time.sleep(30)
"""


@dataclass(frozen=True)
class Marked:
    """A job that marks when it starts and when it has run (before its result is saved)."""

    key: str
    seconds: float
    folder: str


def marked(job: Marked) -> dict[str, Any]:
    for stage in ("started", "ran"):
        folder = Path(job.folder) / stage
        folder.mkdir(parents=True, exist_ok=True)
        if stage == "ran":
            time.sleep(job.seconds)
        (folder / job.key).write_text(str(os.getpid()))
    return {"key": job.key}


MARKED: JobKind[Marked, dict[str, Any]] = json_jobs(marked, lambda job: job.key, omit=("folder",))


def test_a_second_sweep_on_a_held_folder_is_refused_at_once_naming_the_holder(
    tmp_path: Path,
) -> None:
    out = tmp_path / "run"
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(out)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "HELD"
        assert (out / LOCK_FILE).read_text().strip() == str(holder.pid)
        started = time.monotonic()
        with pytest.raises(FolderInUseError) as caught:
            run_jobs([Marked("a", 0.0, str(tmp_path))], MARKED, out, workers=1)
        assert time.monotonic() - started < 5.0
        message = str(caught.value)
        assert f"pid {holder.pid}" in message and "\n" not in message
        assert not (tmp_path / "started").exists()  # nothing ran
    finally:
        holder.kill()
        holder.wait(timeout=10)
    # the holder's end releases the lock, even by SIGKILL: the folder is free again
    assert run_jobs([Marked("a", 0.0, str(tmp_path))], MARKED, out, workers=1) == {
        "a": {"key": "a"}
    }
    assert (out / LOCK_FILE).read_text().strip() == str(os.getpid())


def test_the_lock_is_reentrant_within_a_process(tmp_path: Path) -> None:
    # a study holds its run folder and runs sweeps that hold it (or a folder inside) again
    with hold_folder(tmp_path), hold_folder(tmp_path):
        run_jobs([Marked("a", 0.0, str(tmp_path / "m"))], MARKED, tmp_path, workers=1)
    assert not folders._held


@pytest.mark.parametrize("kind", ["fifo", "folder", "link"])
def test_a_lock_file_that_is_not_a_regular_file_is_refused_in_one_line(
    tmp_path: Path, kind: str
) -> None:
    # defect 3 of issue 35: a FIFO there gave a raw OSError (EINVAL) from every sweep and the packer
    from tavc_agents.experiments import packs

    out = tmp_path / "run"
    out.mkdir()
    lock = out / LOCK_FILE
    if kind == "fifo":
        os.mkfifo(lock)
    elif kind == "folder":
        lock.mkdir()
    else:
        lock.symlink_to(tmp_path / "elsewhere")
    what = {"fifo": "it is a FIFO", "folder": "it is a folder", "link": "a symbolic link"}[kind]
    with pytest.raises(FolderError) as caught:
        run_jobs([Marked("a", 0.0, str(tmp_path))], MARKED, out, workers=1)
    message = str(caught.value)
    assert str(lock) in message and what in message and "allowed: a regular file" in message
    assert "\n" not in message
    assert not (tmp_path / "started").exists()  # nothing ran
    with pytest.raises(FolderError, match=what):
        packs.pack_folder(out)
    assert not folders._held


def test_a_full_disk_at_the_lock_pid_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # defect 3 of issue 35: the pid write on a full disk was a raw OSError traceback
    from tavc_agents.experiments import packs

    def no_room(*args: object) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    out = tmp_path / "run"
    out.mkdir()
    monkeypatch.setattr(folders.os, "pwrite", no_room)
    for attempt in (
        lambda: run_jobs([Marked("a", 0.0, str(tmp_path))], MARKED, out, workers=1),
        lambda: packs.pack_folder(out),
    ):
        with pytest.raises(FolderError) as caught:
            attempt()
        message = str(caught.value)
        assert "No space left on device" in message and LOCK_FILE in message
        assert "\n" not in message
    assert packs.main([str(out)]) == 2
    assert not folders._held and not (tmp_path / "started").exists()
    monkeypatch.undo()
    with hold_folder(out):  # the failed attempts left the lock free
        pass


# -- a refused save stops the sweep ----------------------------------------------------------------
def full_disk(result: dict[str, Any], record: dict[str, Any], path: Path) -> None:
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))


FULL = JobKind(
    run=marked,
    key=MARKED.key,
    record=MARKED.record,
    save=full_disk,
    load=MARKED.load,
    unit="trial",
)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_refused_save_stops_the_sweep_at_once_in_one_line(tmp_path: Path, workers: int) -> None:
    marks = tmp_path / "marks"
    jobs = [Marked("j0", 0.2, str(marks))] + [Marked(f"j{i}", 8.0, str(marks)) for i in range(1, 6)]
    started = time.monotonic()
    with pytest.raises(SaveError) as caught:
        run_jobs(jobs, FULL, tmp_path / "trials", workers=workers)
    assert time.monotonic() - started < 6.0  # the running job was ended, not waited for
    message = str(caught.value)
    assert "could not save trial 'j0'" in message and "No space left on device" in message
    assert "\n" not in message
    assert sorted(p.name for p in (marks / "ran").iterdir()) == ["j0"]  # nothing ran after it
    assert sorted(p.name for p in (tmp_path / "trials").iterdir()) == [LOCK_FILE]


# -- Ctrl-C and SIGTERM ----------------------------------------------------------------------------
DRIVER = """
import os, signal, sys, time
from dataclasses import dataclass
from pathlib import Path
from tavc_agents.experiments.sweep import json_jobs, run_jobs

@dataclass(frozen=True)
class Marked:
    key: str
    seconds: float
    folder: str

def marked(job):
    for stage in ("started", "ran"):
        folder = Path(job.folder) / stage
        folder.mkdir(parents=True, exist_ok=True)
        if stage == "ran":
            time.sleep(job.seconds)
        (folder / job.key).write_text(str(os.getpid()))
    return {"key": job.key}

MARKED = json_jobs(marked, lambda job: job.key, omit=("folder",))

signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal (see the other tests)
out = Path(sys.argv[1])
jobs = [Marked(f"short{i}", 0.1, str(out / "marks")) for i in range(2)]
jobs += [Marked(f"long{i}", 60.0, str(out / "marks")) for i in range(4)]
def done(job, result, resumed):
    print("DONE", job.key, flush=True)
try:
    run_jobs(jobs, MARKED, out / "jobs", workers=2, on_done=done)
except KeyboardInterrupt:
    print("INTERRUPTED", flush=True)
    sys.exit(130)
"""


@pytest.mark.parametrize(
    ("how", "to_group"), [(signal.SIGINT, True), (signal.SIGTERM, False)], ids=["ctrl-c", "sigterm"]
)
def test_a_signal_stops_a_pool_sweep_within_seconds(
    tmp_path: Path, how: signal.Signals, to_group: bool
) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-c", DRIVER, str(tmp_path)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        start_new_session=True,
    )
    try:
        assert proc.stdout is not None
        done = [proc.stdout.readline().split()[-1] for _ in range(2)]
        assert sorted(done) == ["short0", "short1"]
        deadline = time.monotonic() + 30
        while len(list((tmp_path / "marks" / "started").glob("long*"))) < 2:
            assert time.monotonic() < deadline, "the long jobs never started"
            time.sleep(0.05)
        signalled = time.monotonic()
        if to_group:
            os.killpg(proc.pid, how)
        else:
            os.kill(proc.pid, how)
        rest, _ = proc.communicate(timeout=20)
        took = time.monotonic() - signalled
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
    assert "INTERRUPTED" in rest and proc.returncode == 130
    assert took < 5.0, f"took {took:.1f} s to stop"  # 60 s jobs: they were ended, not awaited
    started = sorted(p.name for p in (tmp_path / "marks" / "started").iterdir())
    assert started == ["long0", "long1", "short0", "short1"]  # the queued ones were dropped
    assert not (tmp_path / "marks" / "ran").joinpath("long0").exists()
    jobs = tmp_path / "jobs"
    assert sorted(p.name for p in jobs.iterdir()) == [LOCK_FILE, "short0.json", "short1.json"]
    for name in ("short0", "short1"):
        assert read_record(jobs / f"{name}.json")["result"] == {"key": name}


def test_temporaries_of_a_killed_save_are_removed_under_the_lock(tmp_path: Path) -> None:
    left = tmp_path / ".a.json.x1y2.tmp.json"  # as files.atomic_path names them
    other = tmp_path / ".other.json.x1y2.tmp.json"  # not a job of this sweep: kept
    left.write_text("{")
    other.write_text("{")
    run_jobs([Marked("a", 0.0, str(tmp_path / "m"))], MARKED, tmp_path, workers=1)
    assert not left.exists() and other.exists()


# -- a trial's record carries its periods ----------------------------------------------------------
def test_a_trial_record_carries_its_periods() -> None:
    spec = TrialSpec(key="t", allocator="random", seed=1, convergence_s=3600.0, measured_s=3600.0)
    half = TrialSpec(key="t", allocator="random", seed=1, convergence_s=1800.0, measured_s=1800.0)
    wanted = spec_record(spec)
    assert wanted["convergence_s"] == 3600.0 and wanted["measured_s"] == 3600.0
    assert TRIALS.same(wanted, json.loads(json.dumps(wanted)))  # the same settings resume
    assert not TRIALS.same(spec_record(half), wanted)  # other periods: refused on resume
    old = {k: v for k, v in wanted.items() if k != "arena"}  # saved before arena digests
    assert TRIALS.same(old, wanted) and not TRIALS.same(old, spec_record(half))


def test_git_ignores_the_lock_in_committed_result_folders() -> None:
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    for folder in ("benchmarks/results/passing/trials", "benchmarks/results", "runs/x"):
        checked = subprocess.run(
            ["git", "check-ignore", "-q", f"{folder}/{LOCK_FILE}"], cwd=ROOT, timeout=30
        )
        assert checked.returncode == 0, folder


# -- Ctrl-C before a study's sweep starts ----------------------------------------------------------
@pytest.mark.parametrize("phase", ["reading the settings", "the folder"])
def test_ctrl_c_before_the_sweep_starts_is_one_line(
    phase: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # issue 35: Ctrl-C in the first seconds of a study was a KeyboardInterrupt traceback
    import table1
    from tavc_agents.experiments import study

    def interrupted(*args: object, **kwargs: object) -> Any:
        raise KeyboardInterrupt

    target = {
        "reading the settings": (study, "parse_settings"),
        "the folder": (study, "check_out_folder"),
    }[phase]
    monkeypatch.setattr(*target, interrupted)
    ran = []
    monkeypatch.setattr(table1, "run", lambda settings: ran.append(settings))
    code = study.run_study(
        table1, ["--out", str(tmp_path / "run")], "", "python benchmarks/table1.py"
    )
    err = capsys.readouterr().err
    assert code == 130 and not ran
    assert err.strip() == (
        "python benchmarks/table1.py: interrupted before the study started; nothing was written."
    )
