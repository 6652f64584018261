"""The sweep runner: many independent trials in parallel, saved as they finish, resumable.

A sweep is a list of `TrialSpec`s (plain data: allocator name and parameters, env arguments,
seed, periods). Each finished trial is written at once to `<out_dir>/<key>.json` (atomically), so a
killed sweep loses at most the trials that were running; rerunning the same sweep loads the
finished ones and runs only the rest.

Backends: `"local"` (default) runs trials in a process pool over this machine's cores and needs
nothing extra; `"ray"` runs the same trials as Ray tasks (the `ray` extra), on a local Ray instance
or, with `RAY_ADDRESS` set, on a cluster whose nodes have this package installed. Either way the
driver writes each result the moment it arrives, so the two backends resume each other's sweeps.
"""

from __future__ import annotations

import json
import os
import re
import sys
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from agents.registry import make_allocator
from agents.runner import Event, TrialResult, run_trial

_KEY = re.compile(r"^[A-Za-z0-9_.=-]+$")
BACKENDS = ("local", "ray")


@dataclass(frozen=True)
class TrialSpec:
    """One trial as data. `key` names its result file and must be unique within a sweep."""

    key: str
    allocator: str
    seed: int
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    allocator_kwargs: Mapping[str, Any] = field(default_factory=dict)
    convergence_s: float = 15 * 3600.0
    measured_s: float = 5 * 3600.0
    snapshot_every_s: float = 3600.0
    events: tuple[Event, ...] = ()

    def __post_init__(self) -> None:
        if not _KEY.match(self.key):
            raise ValueError(
                f"key = {self.key!r} is invalid; allowed: letters, digits and _ . = - (a file name)"
            )


def run_spec(spec: TrialSpec) -> TrialResult:
    """Run one trial described by `spec` (in whatever process calls it)."""
    return run_trial(
        make_allocator(spec.allocator, **spec.allocator_kwargs),
        seed=spec.seed,
        convergence_s=spec.convergence_s,
        measured_s=spec.measured_s,
        snapshot_every_s=spec.snapshot_every_s,
        label=spec.key,
        events=spec.events,
        **dict(spec.env_kwargs),
    )


def result_path(out_dir: Path, key: str) -> Path:
    return out_dir / f"{key}.json"


def spec_record(spec: TrialSpec) -> dict[str, Any]:
    """The spec as plain JSON data (what a saved result is checked against on resume)."""
    data: dict[str, Any] = json.loads(json.dumps(asdict(spec), default=repr))
    if not data["events"]:
        del data["events"]  # trials saved before events existed had none; they still resume
    return data


def run_sweep(
    specs: Sequence[TrialSpec],
    out_dir: str | Path,
    workers: int | None = None,
    on_done: Callable[[TrialSpec, TrialResult, bool], None] | None = None,
    progress_bar: bool = False,
    backend: str = "local",
) -> dict[str, TrialResult]:
    """Run every spec not already finished in `out_dir`; return all results by key.

    `workers`: processes (default: all cores; 1 runs in this process). `on_done(spec, result,
    resumed)` is called for each trial as it becomes available (resumed: loaded from disk).
    `progress_bar`: show a tqdm bar over trials on standard output. `backend`: one of `BACKENDS`
    (with `"ray"`, `workers` caps the CPUs of a Ray instance started here; ignored when joining
    a running cluster through `RAY_ADDRESS`).
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend = {backend!r} is invalid; allowed: {list(BACKENDS)}")
    if progress_bar:
        bar = tqdm(total=len(specs), unit="trial", dynamic_ncols=True, file=sys.stdout)
        user_on_done = on_done

        def on_done(spec: TrialSpec, result: TrialResult, resumed: bool) -> None:
            bar.update(1)
            bar.set_postfix_str(f"{spec.key}{' (resumed)' if resumed else ''}")
            if user_on_done is not None:
                user_on_done(spec, result, resumed)

        try:
            return run_sweep(specs, out_dir, workers, on_done, backend=backend)
        finally:
            bar.close()

    keys = [s.key for s in specs]
    duplicates = sorted({k for k in keys if keys.count(k) > 1})
    if duplicates:
        raise ValueError(f"duplicate trial keys {duplicates}; allowed: unique keys")
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    if not isinstance(n_workers, int) or n_workers < 1:
        raise ValueError(f"workers = {workers!r} is invalid; allowed: an integer >= 1")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, TrialResult] = {}
    todo: list[TrialSpec] = []
    for spec in specs:
        path = result_path(out, spec.key)
        if not path.exists():
            todo.append(spec)
            continue
        stored = TrialResult.load(path)
        if stored.spec != spec_record(spec):
            raise ValueError(
                f"{path} holds trial {spec.key!r} run with different settings "
                f"({stored.spec or 'unknown'}); allowed: the same settings to resume, or another "
                "output folder (or delete the file) for new ones"
            )
        results[spec.key] = stored
        if on_done is not None:
            on_done(spec, stored, True)

    def finish(spec: TrialSpec, result: TrialResult) -> None:
        result.spec = spec_record(spec)
        result.save(result_path(out, spec.key))
        results[spec.key] = result
        if on_done is not None:
            on_done(spec, result, False)

    if backend == "ray":
        _run_on_ray(todo, n_workers if workers is not None else None, finish)
        return results
    if n_workers == 1 or len(todo) <= 1:
        for spec in todo:
            finish(spec, run_spec(spec))
        return results
    with ProcessPoolExecutor(max_workers=min(n_workers, len(todo))) as pool:
        futures = {pool.submit(run_spec, spec): spec for spec in todo}
        for future in as_completed(futures):
            finish(futures[future], future.result())
    return results


def _run_on_ray(
    todo: Sequence[TrialSpec],
    workers: int | None,
    finish: Callable[[TrialSpec, TrialResult], None],
) -> None:
    """Run `todo` as Ray tasks (one CPU each), finishing each result as soon as it arrives."""
    if not todo:
        return
    try:
        import ray
    except ImportError as error:
        raise ImportError(
            "backend 'ray' needs Ray; install it with: pip install 'tavc-env[ray]' "
            "(or pip install ray)"
        ) from error
    started_here = not ray.is_initialized()
    if started_here:
        address = os.environ.get("RAY_ADDRESS")
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1)(run_spec)
    pending = {task.remote(spec): spec for spec in todo}
    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                finish(pending.pop(ref), ray.get(ref))
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()
