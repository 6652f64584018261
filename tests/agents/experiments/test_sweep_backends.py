"""The sweep runner's backends and its resume after a kill.

* A sweep killed mid-run (SIGKILL to the whole process group, workers included) and then resumed
  gives exactly the results of an uninterrupted sweep, computing each trial once after the kill.
* The Ray backend on a local Ray instance gives the same results as the local process pool and
  resumes a sweep the local backend started.
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

from tavc_agents.experiments.files import write_manifest
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.sweep import TrialSpec, json_jobs, result_path, run_jobs, run_sweep

ENV = {"preset": "dahl2004"}
# The first trial is short and the others long (12 simulated hours, about 2 s of CPU with
# the compiled tick), so a kill sent when the first result appears lands while the others run,
# however fast the machine: with four short trials the sweep could finish before the kill.
LONG_CONVERGENCE_S = 12 * 3600.0


def specs(n: int = 4) -> list[TrialSpec]:
    return [
        TrialSpec(
            key=f"softmax_s{s}",
            allocator="softmax_tavc",
            seed=s,
            env_kwargs=ENV,
            convergence_s=120.0 if s == 0 else LONG_CONVERGENCE_S,
            measured_s=240.0,
        )
        for s in range(n)
    ]


def comparable(result: TrialResult) -> dict[str, Any]:
    data = result.to_dict()
    data.pop("wall_s")
    return data


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory: pytest.TempPathFactory) -> dict[str, TrialResult]:
    return run_sweep(specs(), tmp_path_factory.mktemp("whole"), workers=1)


SWEEP_SCRIPT = """
import sys
from tavc_agents.experiments.sweep import run_sweep
from tests.agents.experiments.test_sweep_backends import specs
run_sweep(specs(), sys.argv[1], workers=2)
"""


def test_killed_sweep_resumes_without_losing_or_repeating(
    uninterrupted: dict[str, TrialResult], tmp_path: Path
) -> None:
    out = tmp_path / "killed"
    proc = subprocess.Popen(
        [sys.executable, "-c", SWEEP_SCRIPT, str(out)],
        start_new_session=True,  # its own process group, so the kill reaches the pool workers
        cwd=Path(__file__).resolve().parents[3],
    )
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        if out.exists() and any(
            p.suffix == ".json" and not p.name.startswith(".") for p in out.iterdir()
        ):
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    # a write the kill cut short leaves only a hidden temporary file, never a result
    finished = sorted(
        p.stem for p in out.iterdir() if p.suffix == ".json" and not p.name.startswith(".")
    )
    assert 1 <= len(finished) < 4, "the kill must land mid-sweep"
    # no partial file ever stands in for a result
    for key in finished:
        TrialResult.load(out / f"{key}.json")

    done: list[tuple[str, bool]] = []
    resumed = run_sweep(
        specs(), out, workers=1, on_done=lambda s, r, was: done.append((s.key, was))
    )
    assert sorted(k for k, was in done if was) == finished
    assert sorted(k for k, was in done if not was) == sorted(set(uninterrupted) - set(finished))
    for key, result in uninterrupted.items():
        assert comparable(resumed[key]) == comparable(result), key


def test_ray_backend_matches_local_and_resumes_its_sweep(
    uninterrupted: dict[str, TrialResult], tmp_path: Path
) -> None:
    pytest.importorskip("ray", reason="Ray is not installed (pip install 'tavc-env[ray]')")
    out = tmp_path / "mixed"
    first_two = specs()[:2]
    run_sweep(first_two, out, workers=1)  # the local backend starts the sweep ...
    done: list[tuple[str, bool]] = []
    results = run_sweep(  # ... and Ray finishes it
        specs(),
        out,
        workers=2,
        backend="ray",
        on_done=lambda s, r, was: done.append((s.key, was)),
    )
    assert sorted(done) == [
        ("softmax_s0", True),
        ("softmax_s1", True),
        ("softmax_s2", False),
        ("softmax_s3", False),
    ]
    for key, result in uninterrupted.items():
        assert comparable(results[key]) == comparable(result), key
        assert result_path(out, key).exists()


def test_unknown_backend_raises(tmp_path: Path) -> None:
    with pytest.raises(
        ValueError, match=r"backend = 'dask' is invalid; allowed: \['local', 'ray'\]"
    ):
        run_sweep(specs(1), tmp_path, backend="dask")


def test_a_run_time_allocator_is_refused_up_front_with_ray(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """issue 35: a run-time registration passed the check and then failed in every Ray task (Ray
    workers see entry points only)."""
    from tavc_agents.experiments.registry import REGISTRY
    from tavc_agents.learners.tavc import softmax_tavc

    monkeypatch.setattr(REGISTRY, "_entries", dict(REGISTRY._entries))  # undone after the test
    monkeypatch.setattr(REGISTRY, "_runtime", {})
    REGISTRY.register("mine_here", softmax_tavc)
    spec = TrialSpec(key="t", allocator="mine_here", seed=0, convergence_s=0.0, measured_s=60.0)
    with pytest.raises(ValueError) as error:
        run_sweep([spec], tmp_path, backend="ray")  # refused before Ray is even imported
    assert str(error.value) == (
        "allocator 'mine_here' of trial 't' was registered at run time (register_allocator), "
        "which Ray workers do not see; allowed with backend 'ray': a built-in allocator or a "
        "tavc.allocators entry point of an installed package (or backend 'local')"
    )
    assert not list(tmp_path.glob("*.json"))


@dataclass(frozen=True)
class Square:
    x: int
    scale: float = 1.0


def square(job: Square) -> dict[str, Any]:
    return {"value": job.x * job.x * job.scale}


SQUARES = json_jobs(square, lambda job: f"sq{job.x}", unit="square")


def test_json_jobs_save_resume_and_refuse_other_settings(tmp_path: Path) -> None:
    jobs = [Square(x) for x in range(5)]
    done: list[tuple[str, bool]] = []
    first = run_jobs(
        jobs,
        SQUARES,
        tmp_path,
        workers=2,
        on_done=lambda j, r, was: done.append((SQUARES.key(j), was)),
    )
    assert first == {f"sq{x}": {"value": float(x * x)} for x in range(5)}
    assert sorted(done) == [(f"sq{x}", False) for x in range(5)]
    (tmp_path / "sq3.json").unlink()
    done.clear()
    again = run_jobs(
        jobs,
        SQUARES,
        tmp_path,
        workers=1,
        on_done=lambda j, r, was: done.append((SQUARES.key(j), was)),
    )
    assert again == first and sorted(k for k, was in done if not was) == ["sq3"]
    with pytest.raises(
        ValueError, match=r"sq0.json holds square 'sq0' run with different settings"
    ):
        run_jobs([Square(0, scale=2.0)], SQUARES, tmp_path, workers=1)
    with pytest.raises(ValueError, match=r"duplicate square keys \['sq1'\]"):
        run_jobs([Square(1), Square(1, 2.0)], SQUARES, tmp_path / "other", workers=1)


def test_a_changed_preset_is_not_resumed_but_old_records_still_are(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import tavc_env.config as config

    spec = specs(1)[0]
    first = run_sweep([spec], tmp_path, workers=1)
    stored = json.loads(result_path(tmp_path, spec.key).read_text())
    assert len(stored["spec"]["arena"]) == 16  # the digest of the resolved arena
    # records saved before digests existed are taken as made with today's preset (such records
    # also predate checksums)
    del stored["spec"]["arena"], stored["schema"], stored["checksum"]
    result_path(tmp_path, spec.key).write_text(json.dumps(stored))
    write_manifest(result_path(tmp_path, spec.key).parent)  # as committed old records have
    done: list[bool] = []
    again = run_sweep([spec], tmp_path, workers=1, on_done=lambda s, r, was: done.append(was))
    assert done == [True]  # resumed, not rerun
    assert again[spec.key].delivery_time_s == first[spec.key].delivery_time_s
    # a preset whose definition changed no longer matches a digest-carrying record
    run_sweep([spec], tmp_path / "new", workers=1)
    original = config.PRESETS["dahl2004"]
    monkeypatch.setitem(config.PRESETS, "dahl2004", lambda: original().replace(dt=0.2))  # type: ignore[index]
    with pytest.raises(ValueError, match="run with different settings"):
        run_sweep([spec], tmp_path / "new", workers=1)
