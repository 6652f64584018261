"""Packing stopped at every step loses no trial (defect 1 of issue 35).

A repack cut off between replacing `pack.jsonl` and writing `CHECKSUMS.sha256` left a folder whose
packed trials no reader would take. Here packing is stopped before each of its file system calls
in turn, the way a kill stops it (nothing after that point runs: no `finally` removes a temporary
file), and on a full disk (that call raises ENOSPC); after each stop every trial must read, and
packing again must finish the job and leave no temporary file behind.
"""

from __future__ import annotations

import errno
import json
import math
import os
import shutil
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from unittest import mock

import pytest

from tavc_agents.experiments import packs
from tavc_agents.experiments.files import MANIFEST
from tavc_agents.experiments.folders import LOCK_FILE
from tavc_agents.experiments.sweep import json_jobs, run_jobs


@dataclass(frozen=True)
class Job:
    key: str
    x: float


def work(job: Job) -> dict[str, object]:
    return {"x": job.x, "nan": math.nan}


KIND = json_jobs(work, lambda j: j.key)


class Killed(BaseException):
    """The process was stopped here (a BaseException: no `except Exception` catches it)."""


# The calls through which packing changes the folder or makes it durable: a stop before any of
# them is a stop between two steps.
CALLS = ("replace", "unlink", "fsync", "rename")


@contextmanager
def stopped_at(step: int, error: Callable[[], BaseException]) -> Iterator[list[str]]:
    """Make the `step`-th call (from 1) of `CALLS` raise `error()`; with `Killed`, every call
    after it raises too (a killed process runs no cleanup). Yields the calls seen."""
    seen: list[str] = []
    real = {name: getattr(os, name) for name in CALLS}
    dead = False

    def wrap(name: str) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            nonlocal dead
            if dead:
                raise Killed(name)
            seen.append(name)
            if len(seen) == step:
                failure = error()
                dead = isinstance(failure, Killed)
                raise failure
            return real[name](*args, **kwargs)

        return call

    with mock.patch.multiple(os, **{name: wrap(name) for name in CALLS}):
        yield seen


def folder_with_a_pack_and_loose_files(root: Path) -> tuple[Path, str]:
    """A packed folder of three jobs with two more loose ones, and its records as JSON text."""
    folder = root / "runs"
    run_jobs([Job(f"job{k}", float(k)) for k in range(3)], KIND, folder, workers=1)
    packs.pack_folder(folder)
    run_jobs([Job(f"job{k}", float(k)) for k in range(5)], KIND, folder, workers=1)
    return folder, json.dumps(packs.load_trials(folder))


def steps_of_a_whole_packing(tmp_path: Path) -> int:
    folder, _ = folder_with_a_pack_and_loose_files(tmp_path / "count")
    with stopped_at(0, lambda: Killed()) as seen:
        packs.pack_folder(folder)
    return len(seen)


def test_a_packing_has_steps_to_stop_at(tmp_path: Path) -> None:
    assert steps_of_a_whole_packing(tmp_path) >= 8


@pytest.mark.parametrize("how", ["killed", "disk full"])
def test_packing_stopped_at_every_step_loses_no_trial(tmp_path: Path, how: str) -> None:
    steps = steps_of_a_whole_packing(tmp_path)
    for step in range(1, steps + 1):
        folder, before = folder_with_a_pack_and_loose_files(tmp_path / f"{how}{step}")
        if how == "killed":
            with pytest.raises(Killed), stopped_at(step, Killed):
                packs.pack_folder(folder)
        else:
            with stopped_at(step, lambda: OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))):
                try:
                    packs.pack_folder(folder)
                except packs.PackError as error:  # one line naming the folder and the cause
                    assert "No space left on device" in str(error) and "\n" not in str(error)
        packs._CACHE.clear()  # a new process reads the folder afresh
        assert json.dumps(packs.load_trials(folder)) == before, f"{how} at step {step}"
        done = packs.pack_folder(folder)  # the next packing finishes the job
        assert done.trials == 5
        assert json.dumps(packs.load_trials(folder)) == before
        assert sorted(p.name for p in folder.iterdir()) == [LOCK_FILE, MANIFEST, packs.PACK]
        assert packs.PENDING not in (folder / MANIFEST).read_text()
        shutil.rmtree(folder.parent)
