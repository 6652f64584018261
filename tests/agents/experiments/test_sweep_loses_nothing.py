"""A sweep loses no finished job, whatever happens to it: a worker's error, Ctrl-C (SIGINT to the
process group), SIGTERM or SIGKILL of the driver; and its pool workers die with the driver.

The sweeps here run real processes (a driver started as a subprocess with its own pool or Ray
workers) and real signals. Each job records its worker's pid, so the tests can check that no
worker outlives the driver.
"""

from __future__ import annotations

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

from tavc_agents.experiments.files import CorruptFileError, read_record
from tavc_agents.experiments.runner import Event, TrialResult
from tavc_agents.experiments.sweep import (
    SweepError,
    TrialSpec,
    json_jobs,
    read_failed,
    rerun_failed,
    result_path,
    run_jobs,
    run_sweep,
)

ROOT = Path(__file__).resolve().parents[3]

# The driver stands for a command typed in a terminal, where Ctrl-C raises KeyboardInterrupt. A
# process started in the background by a non-interactive shell inherits SIGINT ignored (as a CI
# job may be), so the driver restores Python's own handler rather than depend on its parent.
DRIVER = """
import os, signal, sys, time
from dataclasses import dataclass
from pathlib import Path
from tavc_agents.experiments.sweep import json_jobs, run_jobs

signal.signal(signal.SIGINT, signal.default_int_handler)

@dataclass(frozen=True)
class Job:
    key: str
    seconds: float
    folder: str

def work(job):
    folder = Path(job.folder) / "pids"
    folder.mkdir(exist_ok=True)
    tmp = folder / f".{job.key}.pid.tmp"
    tmp.write_text(str(os.getpid()))
    tmp.replace(folder / f"{job.key}.pid")  # whole or absent, even if the worker is killed
    time.sleep(job.seconds)
    return {"key": job.key, "pid": os.getpid()}

def done(job, result, resumed):
    print("DONE", job.key, flush=True)

jobs = [Job(f"j{i}", 0.4 + 0.3 * (i % 3), sys.argv[1]) for i in range(12)]
run_jobs(jobs, json_jobs(work, lambda j: j.key), Path(sys.argv[1]) / "jobs",
         workers=2, on_done=done, backend=sys.argv[2])
print("SWEEP FINISHED", flush=True)
"""


def start_driver(out: Path, backend: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", DRIVER, str(out), backend],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        start_new_session=True,  # its own process group, like a command in a terminal
    )


def wait_for_done(proc: subprocess.Popen[str], count: int, timeout: float = 120.0) -> list[str]:
    assert proc.stdout is not None
    seen: list[str] = []
    deadline = time.monotonic() + timeout
    while len(seen) < count and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        if line.startswith("DONE "):
            seen.append(line.split()[1])
    return seen


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"


def live_members(group: int) -> list[int]:
    """The processes of process group `group` that are still running (not zombies)."""
    members = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().split(")")[-1].split()
        except (FileNotFoundError, ProcessLookupError):
            continue
        if int(fields[2]) == group and fields[0] != "Z":
            members.append(int(stat.parent.name))
    return members


def assert_nothing_lost(out: Path, reported: list[str]) -> None:
    """Every job the driver reported finished is on disk, whole and valid; so is every other
    result file that exists; no temporary file is left to stand in for a result."""
    jobs = out / "jobs"
    for key in reported:
        data = read_record(jobs / f"{key}.json")
        assert data["result"]["key"] == key
    for path in jobs.glob("*.json"):
        read_record(path)
    assert not list(jobs.glob("*.tmp*"))


def assert_workers_gone(out: Path, grace_s: float = 5.0) -> None:
    pids = [int(p.read_text()) for p in (out / "pids").glob("*.pid")]
    assert pids, "no worker ever started"
    deadline = time.monotonic() + grace_s
    while any(alive(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [pid for pid in pids if alive(pid)], "workers outlived the driver"


@pytest.mark.parametrize(
    ("how", "to_group"),
    [(signal.SIGINT, True), (signal.SIGTERM, False), (signal.SIGKILL, False)],
    ids=["ctrl-c", "sigterm", "sigkill"],
)
def test_a_signalled_pool_sweep_keeps_every_finished_job(
    tmp_path: Path, how: signal.Signals, to_group: bool
) -> None:
    proc = start_driver(tmp_path, "local")
    reported = wait_for_done(proc, 3)
    assert len(reported) == 3, "the sweep must be signalled mid-run"
    if to_group:
        os.killpg(proc.pid, how)
    else:
        os.kill(proc.pid, how)
    rest, _ = proc.communicate(timeout=60)
    reported += [line.split()[1] for line in rest.splitlines() if line.startswith("DONE ")]
    assert "SWEEP FINISHED" not in rest
    assert proc.returncode != 0
    assert_nothing_lost(tmp_path, reported)
    assert_workers_gone(tmp_path)
    assert not live_members(proc.pid), "processes of the sweep's group are left running"


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_a_signalled_ray_sweep_keeps_every_finished_job(
    tmp_path: Path, how: signal.Signals
) -> None:
    pytest.importorskip("ray", reason="Ray is not installed (pip install 'tavc-env[ray]')")
    proc = start_driver(tmp_path, "ray")
    reported = wait_for_done(proc, 3, timeout=180)
    assert len(reported) == 3, "the sweep must be signalled mid-run"
    os.kill(proc.pid, how)
    rest, _ = proc.communicate(timeout=120)
    reported += [line.split()[1] for line in rest.splitlines() if line.startswith("DONE ")]
    assert "SWEEP FINISHED" not in rest
    assert_nothing_lost(tmp_path, reported)
    assert_workers_gone(tmp_path, grace_s=30.0)


@dataclass(frozen=True)
class FlakyJob:
    key: str
    fail: bool


def flaky(job: FlakyJob) -> dict[str, str]:
    if job.fail:
        raise RuntimeError(f"job {job.key} broke")
    time.sleep(0.2)
    return {"key": job.key}


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failing_job_does_not_lose_the_others(tmp_path: Path, workers: int) -> None:
    jobs = [FlakyJob(f"j{i}", fail=(i == 1)) for i in range(5)]
    with pytest.raises(SweepError) as caught:
        run_jobs(jobs, json_jobs(flaky, lambda j: j.key), tmp_path, workers=workers)
    message = str(caught.value)
    assert "1 run(s) failed" in message and "j1 (seed -): RuntimeError: job j1 broke" in message
    assert "python -m tavc_agents.experiments.sweep" in message and "j1.failed.json" in message
    assert sorted(p.stem for p in tmp_path.glob("j*.json") if ".failed" not in p.name) == [
        "j0",
        "j2",
        "j3",
        "j4",
    ]
    failed = json.loads((tmp_path / "j1.failed.json").read_text())
    assert failed["record"] == {"key": "j1", "fail": True} and "job j1 broke" in failed["error"]


@dataclass(frozen=True)
class MortalJob:
    key: str
    doomed: bool  # killed like the kernel's out-of-memory killer does while the flag file exists
    flag: str


def mortal(job: MortalJob) -> dict[str, Any]:
    time.sleep(0.3)
    if job.doomed and os.path.exists(job.flag):
        os.kill(os.getpid(), signal.SIGKILL)
    return {"key": job.key, "pid": os.getpid()}


def test_a_killed_worker_fails_only_its_job_and_a_resume_clears_the_failure(
    tmp_path: Path,
) -> None:
    # defect 8 of issue 35: a worker killed with SIGKILL marked every queued job failed, and the
    # stale .failed.json records survived a successful resume
    out, flag = tmp_path / "out", tmp_path / "oom"
    flag.touch()
    jobs = [MortalJob(f"j{i}", doomed=(i == 1), flag=str(flag)) for i in range(8)]
    kind = json_jobs(mortal, lambda j: j.key)
    with pytest.raises(SweepError) as caught:
        run_jobs(jobs, kind, out, workers=2)
    message = str(caught.value)
    assert "1 run(s) failed" in message
    assert (
        "j1 (seed -): tavc_agents.experiments.sweep.WorkerDied: its worker process (pid " in message
    )
    assert "was killed by SIGKILL" in message
    saved = {p.name for p in out.glob("j*.json")}
    assert saved == {f"j{i}.json" for i in range(8) if i != 1} | {"j1.failed.json"}
    flag.unlink()  # enough memory this time
    results = run_jobs(jobs, kind, out, workers=2)
    assert sorted(results) == [f"j{i}" for i in range(8)]
    assert not list(out.glob("*.failed.json"))  # the stale failure record is gone


def test_a_pool_that_keeps_breaking_fails_what_is_left_instead_of_looping(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from tavc_agents.experiments import sweep

    monkeypatch.setattr(sweep, "_abruptly_ended", lambda pool: {})  # nothing to blame
    flag = tmp_path / "oom"
    flag.touch()
    jobs = [MortalJob(f"j{i}", doomed=True, flag=str(flag)) for i in range(3)]
    with pytest.raises(SweepError, match=r"3 run\(s\) failed"):
        run_jobs(jobs, json_jobs(mortal, lambda j: j.key), tmp_path, workers=2)


def test_a_failed_trial_names_its_seed_and_reruns_alone(tmp_path: Path) -> None:
    good = TrialSpec(key="ok", allocator="random", seed=3, convergence_s=0.0, measured_s=30.0)
    bad = TrialSpec(
        key="bad",
        allocator="random",
        seed=4,
        convergence_s=0.0,
        measured_s=30.0,
        events=(Event(at_s=10.0, kind="break_down", robot=99),),  # no robot 99: fails in its run
    )
    with pytest.raises(SweepError, match=r"bad \(seed 4\): ValueError"):
        run_sweep([good, bad], tmp_path, workers=1)
    assert TrialResult.load(result_path(tmp_path, "ok")).seed == 3
    assert read_failed(tmp_path / "bad.failed.json")["record"]["seed"] == 4
    with pytest.raises(ValueError, match="robot"):  # rerunning it alone reproduces the failure
        rerun_failed(tmp_path / "bad.failed.json")


def test_a_corrupt_or_edited_trial_is_named_and_run_again(tmp_path: Path) -> None:
    spec = TrialSpec(key="t", allocator="random", seed=1, convergence_s=0.0, measured_s=60.0)
    first = run_sweep([spec], tmp_path, workers=1)["t"]
    path = result_path(tmp_path, "t")
    data = json.loads(path.read_text())
    data["delivery_time_s"][0] += 1.0  # a hand edit that still parses
    path.write_text(json.dumps(data))
    with pytest.raises(CorruptFileError, match=r"t\.json does not match its checksum"):
        TrialResult.load(path)
    again = run_sweep([spec], tmp_path, workers=1)["t"]
    assert again.delivery_time_s == first.delivery_time_s  # recomputed, not trusted
    path.write_text(path.read_text()[:100])  # truncated
    with pytest.raises(CorruptFileError, match="not valid JSON"):
        TrialResult.load(path)
    run_sweep([spec], tmp_path, workers=1)
    assert TrialResult.load(path).delivery_time_s == first.delivery_time_s
