"""A field added to a kind of job after some were saved (`json_jobs(added=...)`): a saved job
without it resumes when the new field has the value it stands for, and is refused (never mixed
in, never overwritten) when it has another."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from tavc_agents.experiments.sweep import json_jobs, run_jobs


@dataclass(frozen=True)
class Before:
    key: str
    size: int


@dataclass(frozen=True)
class After:
    key: str
    size: int
    credit: str = "own"


def work(job: Before | After) -> dict[str, Any]:
    return {"size": job.size, "credit": getattr(job, "credit", "own")}


def key(job: Before | After) -> str:
    return job.key


def test_a_job_saved_before_a_field_existed_resumes_only_with_its_old_value(
    tmp_path: Path,
) -> None:
    run_jobs([Before("j0", 3)], json_jobs(work, key), tmp_path, workers=1)
    saved = (tmp_path / "j0.json").read_bytes()
    kind = json_jobs(work, key, added={"credit": "own"})
    resumed: list[bool] = []
    results = run_jobs(
        [After("j0", 3)], kind, tmp_path, workers=1, on_done=lambda j, r, was: resumed.append(was)
    )
    assert resumed == [True] and results["j0"] == {"size": 3, "credit": "own"}
    for other in (After("j0", 3, credit="team"), After("j0", 4)):
        with pytest.raises(ValueError, match="run with different settings"):
            run_jobs([other], kind, tmp_path, workers=1)
    with pytest.raises(ValueError, match="run with different settings"):  # no `added`: refused
        run_jobs([After("j0", 3)], json_jobs(work, key), tmp_path, workers=1)
    assert (tmp_path / "j0.json").read_bytes() == saved
