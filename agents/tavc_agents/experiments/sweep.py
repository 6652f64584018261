"""The sweep runner: many independent trials in parallel, saved as they finish, resumable.

A sweep is a list of `TrialSpec`s (plain data: allocator name and parameters, env arguments,
seed, periods). Each finished trial is written to `<out_dir>/<key>.json` (atomically, with a
checksum) by the process that ran it, before its result travels anywhere, so nothing that happens
to the sweep afterwards can lose it: a worker's error (the other trials go on; the error names the
trial, its seed and how to rerun just it), Ctrl-C, SIGTERM, or SIGKILL of the driver (the local
pool's workers die with it). Rerunning the same sweep loads the finished trials and runs only the
rest; a stored trial that is corrupt or was edited is reported and run again. A sweep holds its
folder's lock while it writes (`folders.hold_folder`: a second sweep there is refused at once); a
save the folder refuses (a full disk) stops the sweep at once (`SaveError`), and Ctrl-C or SIGTERM
end the pool's workers at once, dropping the queued trials. A pool worker that dies abruptly (the
kernel's out-of-memory killer sends SIGKILL) fails only the trial it was running (`WorkerDied`);
the trials the broken pool was also running or had queued run in a fresh pool. A trial that
finishes removes the `<key>.failed.json` an earlier run left for it.

Backends: `"local"` (default) runs trials in a process pool over this machine's cores and needs
nothing extra; `"ray"` runs the same trials as Ray tasks (the `ray` extra), on a local Ray instance
or, with `RAY_ADDRESS` set, on a cluster whose nodes have this package installed. Either way the
driver writes each result the moment it arrives, so the two backends resume each other's sweeps.

Allocators are named through `tavc_agents.experiments.registry`: every process finds the
`tavc.allocators` entry points itself; the local pool's workers also receive the driver's run-time
registrations (a spawned worker only those it can unpickle: refused by name before any job runs
otherwise); Ray workers see entry points only.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import hashlib
import json
import multiprocessing
import multiprocessing.connection
import os
import pickle
import re
import signal
import stat
import sys
import time
import traceback
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

from tqdm import tqdm

from tavc_agents.experiments import packs
from tavc_agents.experiments.files import (
    RECORD_MAX_BYTES,
    CorruptFileError,
    read_json,
    read_record,
    write_record,
)
from tavc_agents.experiments.folders import forget_inherited, hold_folder
from tavc_agents.experiments.registry import REGISTRY, Allocator, make_allocator
from tavc_agents.experiments.runner import Event, TrialResult, env_arguments, run_trial
from tavc_env import ArenaConfig
from tavc_env.arena import resolve_env_kwargs

_KEY = re.compile(r"^[A-Za-z0-9_.=-]+$")
BACKENDS = ("local", "ray")


TagValue = str | int | float | bool | tuple[str | int | float | bool, ...]


@dataclass(frozen=True)
class TrialSpec:
    """One trial as data. `key` names its result file and must be unique within a sweep.

    `tags` say what the trial stands for in its study (condition, arena, temperature, seed, ...):
    reports group trials by them. A study derives `key` from its tags; nothing parses a key back.
    Tags are labels, not settings: a saved trial resumes whatever its tags.

    `env_kwargs` say which arena and how the env presents it, as plain data: `{"scenario": name}`,
    or a `preset` (or `config`) with arena overrides, and env options; `tavc_env.resolve_arena`
    resolves the arena (the one place that refuses a clash).
    """

    key: str
    allocator: str
    seed: int
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    allocator_kwargs: Mapping[str, Any] = field(default_factory=dict)
    convergence_s: float = 15 * 3600.0
    measured_s: float = 5 * 3600.0
    snapshot_every_s: float = 3600.0
    events: tuple[Event, ...] = ()
    tags: Mapping[str, TagValue] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not _KEY.match(self.key):
            raise ValueError(
                f"key = {self.key!r} is invalid; allowed: letters, digits and _ . = - (a file name)"
            )
        scalar = (str, int, float, bool)
        for name, value in dict(self.tags).items():
            ok = isinstance(name, str) and (
                isinstance(value, scalar)
                or (isinstance(value, (tuple, list)) and all(isinstance(v, scalar) for v in value))
            )
            if not ok:
                raise ValueError(
                    f"tag {name!r} = {value!r} of trial {self.key!r} is invalid; allowed: a text "
                    "name and a str, int, float or bool value (or a tuple of them)"
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
        **env_arguments(spec.env_kwargs),
    )


def result_path(out_dir: Path, key: str) -> Path:
    return out_dir / f"{key}.json"


def spec_record(spec: TrialSpec) -> dict[str, Any]:
    """The spec as plain JSON data (what a saved result is checked against on resume), with a
    digest of the arena it resolves to: a preset whose definition changed (a new default physics
    step, say) no longer matches the trials saved under the old one."""
    data: dict[str, Any] = json.loads(json.dumps(asdict(spec), default=repr))
    if not data["events"]:
        del data["events"]  # trials saved before events existed had none; they still resume
    if not data["tags"]:
        del data["tags"]
    data["arena"] = arena_digest(spec.env_kwargs)
    if resolve_env_kwargs(spec.env_kwargs)[0].scenario is not None:
        # a scenario trial's env is reset with its seed itself (runner.reset_seed); trials saved
        # before that drew the env's seed from its stream, ran other episodes, and must not resume
        data["reset_seed"] = "episode"
    return data


DERIVED_KEYS = ("arena", "reset_seed")
"""What `spec_record` adds to a spec's fields: facts derived from them, not arguments."""


def spec_from_record(record: Mapping[str, Any]) -> TrialSpec:
    """The `TrialSpec` a saved spec record (`spec_record`) was made from."""
    fields = {k: v for k, v in record.items() if k not in DERIVED_KEYS}
    fields["events"] = tuple(Event(**e) for e in fields.get("events", ()))
    return TrialSpec(**fields)


def arena_digest(env_kwargs: Mapping[str, Any]) -> str:
    """A short digest of the arena configuration that `env_kwargs` resolve to (the env's own
    options, such as time limits, are not part of the arena)."""
    arena = resolve_env_kwargs(env_kwargs)[0]  # a scenario: its arena, and its priority shifts
    text = digest_text(arena.config)
    if arena.scenario is not None and arena.scenario.value_shifts is not None:
        text += repr(arena.scenario.value_shifts)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# The fields ArenaConfig had when trial records began to carry digests (November 2026). Frozen:
# every field added since is neutral at its default (the arena behaves as before it existed), so
# it enters the digest only when it is set, and trials stored before it came keep their digest.
# A new field therefore needs no entry here.
FIELDS_OF_FIRST_DIGESTS = frozenset(
    {
        "width",
        "height",
        "circuits",
        "robots",
        "robot_radius",
        "source_service_s",
        "sink_service_s",
        "service_scales_with_speed",
        "service_reference_speed",
        "queue_offset_m",
        "queue_spacing_m",
        "join_radius_m",
        "dock_tolerance_m",
        "speed_noise",
        "max_turn_rate",
        "sensing_range_m",
        "dt",
        "breakdowns",
    }
)


def digest_text(config: ArenaConfig) -> str:
    """What `arena_digest` hashes: the config's repr, less the fields added after
    `FIELDS_OF_FIRST_DIGESTS` that are at their defaults."""
    parts = [
        f"{f.name}={getattr(config, f.name)!r}"
        for f in dataclasses.fields(config)
        if f.repr and (f.name in FIELDS_OF_FIRST_DIGESTS or getattr(config, f.name) != f.default)
    ]
    return f"{type(config).__qualname__}({', '.join(parts)})"


J = TypeVar("J")
R = TypeVar("R")


@dataclass(frozen=True)
class JobKind(Generic[J, R]):
    """How one kind of job is run, named, saved and checked on resume.

    `run` must be a module-level function (it is sent to worker processes or Ray tasks);
    `record(job)` is the job as plain JSON data, stored beside the result: a saved result is only
    resumed for a job whose record it matches (`same(stored, wanted)`, equality by default). `save(result, record, path)` writes atomically and
    `load(path)` returns the result and its stored record.
    """

    run: Callable[[J], R]
    key: Callable[[J], str]
    record: Callable[[J], dict[str, Any]]
    save: Callable[[R, dict[str, Any], Path], None]
    load: Callable[[Path], tuple[R, dict[str, Any] | None]]
    unit: str = "job"
    same: Callable[[dict[str, Any] | None, dict[str, Any]], bool] = field(
        default=lambda stored, wanted: stored == wanted
    )
    check: Callable[[J], None] = field(default=lambda job: None)
    """Raise a ValueError for a job that cannot run (called for every job before any runs)."""
    parse: Callable[[dict[str, Any]], tuple[R, dict[str, Any] | None]] | None = None
    """The result and its stored record from a saved record's data (what `load` reads from a
    file), for results packed into the folder's `pack.jsonl` (`tavc_agents.experiments.packs`);
    None: this kind's results are never packed."""


def run_jobs(
    jobs: Sequence[J],
    kind: JobKind[J, R],
    out_dir: str | Path,
    workers: int | None = None,
    on_done: Callable[[J, R, bool], None] | None = None,
    progress_bar: bool = False,
    backend: str = "local",
) -> dict[str, R]:
    """Run every job not already finished in `out_dir` (one file per job key); return all results
    by key. See `run_sweep` for the arguments; `run_sweep` is this for trials."""
    if backend not in BACKENDS:
        raise ValueError(f"backend = {backend!r} is invalid; allowed: {list(BACKENDS)}")
    if progress_bar:
        bar = tqdm(total=len(jobs), unit=kind.unit, dynamic_ncols=True, file=sys.stderr)
        user_on_done = on_done

        def on_done(job: J, result: R, resumed: bool) -> None:
            bar.update(1)
            bar.set_postfix_str(f"{kind.key(job)}{' (resumed)' if resumed else ''}")
            if user_on_done is not None:
                user_on_done(job, result, resumed)

        try:
            return run_jobs(jobs, kind, out_dir, workers, on_done, backend=backend)
        finally:
            bar.close()

    keys = [kind.key(j) for j in jobs]
    duplicates = sorted({k for k in keys if keys.count(k) > 1})
    if duplicates:
        raise ValueError(f"duplicate {kind.unit} keys {duplicates}; allowed: unique keys")
    bad = [k for k in keys if not _KEY.match(k)]
    if bad:
        raise ValueError(
            f"{kind.unit} keys {bad} are invalid; allowed: letters, digits and _ . = - (file names)"
        )
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    if not isinstance(n_workers, int) or n_workers < 1:
        raise ValueError(f"workers = {workers!r} is invalid; allowed: an integer >= 1")
    out = Path(out_dir)
    with hold_folder(out):  # made if needed, and refused at once if another sweep writes it
        _remove_temporaries(out, keys)  # left by a sweep that was killed while saving
        try:
            return _run_unfinished(
                jobs, kind, out, n_workers, workers is not None, on_done, backend
            )
        finally:
            _remove_temporaries(out, keys)  # left by workers ended mid-save (Ctrl-C, SIGTERM)


def _run_unfinished(
    jobs: Sequence[J],
    kind: JobKind[J, R],
    out: Path,
    n_workers: int,
    workers_given: bool,
    on_done: Callable[[J, R, bool], None] | None,
    backend: str,
) -> dict[str, R]:
    """`run_jobs` in the folder `out`, which this process holds."""
    results: dict[str, R] = {}
    todo: list[J] = []
    for job in jobs:
        stored = _saved(job, kind, out)
        if stored is None:
            todo.append(job)
            continue
        results[kind.key(job)] = stored[0]
        _forget_failure(out, kind.key(job))
        if on_done is not None:
            on_done(job, stored[0], True)

    records = {}
    for job in todo:  # bad input is refused before anything runs
        kind.check(job)
        if backend == "ray":
            _refuse_run_time_allocator_on_ray(job)
        records[kind.key(job)] = kind.record(job)
    failures: list[Failure] = []

    def finish(job: J, result: R, saved: bool) -> None:
        key = kind.key(job)
        if not saved:
            _save(kind.save, result, kind.record(job), result_path(out, key), kind.unit)
        _forget_failure(out, key)  # an earlier run's failure record is stale now
        results[key] = result
        if on_done is not None:
            on_done(job, result, False)

    def fail(job: J, error: BaseException) -> None:
        failures.append(_failure(kind, job, error, out))

    with _stop_on_sigterm():
        if backend == "ray":
            _run_on_ray(todo, kind.run, n_workers if workers_given else None, finish, fail)
        elif n_workers == 1 or len(todo) <= 1:
            for job in todo:
                task = _Task(
                    kind.run,
                    kind.save,
                    job,
                    records[kind.key(job)],
                    result_path(out, kind.key(job)),
                    kind.unit,
                )
                try:
                    result = task()
                except SaveError:
                    raise  # a folder that refuses one save refuses the next: stop here
                except Exception as error:
                    fail(job, error)
                else:
                    finish(job, result, True)
        else:
            _run_in_pool(todo, kind, records, out, min(n_workers, len(todo)), finish, fail)
    if failures:
        raise SweepError(failures, kind.unit)
    return results


def _refuse_run_time_allocator_on_ray(job: object) -> None:
    """A ValueError for a trial whose allocator was registered at run time: Ray workers find
    allocators by entry point only, so every task would fail (or, for a name that replaced an
    entry point or built-in, silently run that one instead)."""
    if not isinstance(job, TrialSpec):
        return
    here = {entry.name for entry in REGISTRY.registered_at_run_time()}
    if job.allocator in here:
        raise ValueError(
            f"allocator {job.allocator!r} of trial {job.key!r} was registered at run time "
            "(register_allocator), which Ray workers do not see; allowed with backend 'ray': a "
            "built-in allocator or a tavc.allocators entry point of an installed package (or "
            "backend 'local')"
        )


def _saved(job: J, kind: JobKind[J, R], out: Path, move_aside: bool = True) -> tuple[R] | None:
    """The saved result of `job` in `out`, as a 1-tuple, if a run would resume it; None if it
    must run (no file, or a damaged slot, which is named in one line and, with `move_aside`,
    moved aside by `set_aside` so that the rerun can save there). A result saved with other
    settings is a ValueError: it is never overwritten or mixed in."""
    key = kind.key(job)
    path = result_path(out, key)
    if not os.path.lexists(path):  # lexists: a dangling link in the slot is damage, not absence
        return _packed(job, kind, out)
    try:
        stored, record = kind.load(path)
    except CorruptFileError as error:
        if not move_aside:
            print(f"{error}; not used", file=sys.stderr)
            return None
        aside = set_aside(path)
        print(
            f"{error}; moved aside to {aside.name}; running {kind.unit} {key!r} again",
            file=sys.stderr,
        )
        return None
    _refuse_other_settings(job, kind, record, str(path), " (or delete the file)")
    return (stored,)


def set_aside(path: Path) -> Path:
    """Rename the damaged slot `path` (whatever it is: a file, a folder, a FIFO, a link) to a
    free `<name>.not-a-file` (anything but a regular file) or `<name>.damaged` name beside it,
    never deleting it (it may be worth a look); return the new path. A ValueError naming it if it
    cannot be renamed."""
    try:
        regular = stat.S_ISREG(path.lstat().st_mode)
    except OSError:
        regular = False
    base = f"{path.name}.{'damaged' if regular else 'not-a-file'}"
    for n in range(1000):
        aside = path.with_name(base if n == 0 else f"{base}.{n}")
        if os.path.lexists(aside):
            continue
        try:
            os.rename(path, aside)  # a link is renamed, not followed; a folder moves whole
        except OSError as error:
            raise ValueError(
                f"{path} is damaged and cannot be moved aside to {aside.name} ({error}); "
                "allowed: a writable output folder (or remove the file and run again)"
            ) from None
        return aside
    raise ValueError(f"{path} is damaged and {base}.1 to .999 are taken; remove some")


def saved_results(jobs: Sequence[J], kind: JobKind[J, R], out_dir: str | Path) -> dict[str, R]:
    """The results of `jobs` already saved in `out_dir` (those a run would resume), by key,
    without running anything or changing the folder: what an interim report of an unfinished
    sweep is made from (a damaged slot is named in one line and left where it is)."""
    out = Path(out_dir)
    found = {}
    for job in jobs:
        stored = _saved(job, kind, out, move_aside=False)
        if stored is not None:
            found[kind.key(job)] = stored[0]
    return found


def _packed(job: J, kind: JobKind[J, R], out: Path) -> tuple[R] | None:
    """`_saved` for a job without its own file: its line in the folder's pack, if it has one
    (`tavc_agents.experiments.packs`; a damaged line is named and the job runs again)."""
    key = kind.key(job)
    if kind.parse is None:
        return None
    try:
        found = packs.find(out, key)
        if found is None:
            return None
        stored, record = packs.parsed(found, kind.parse, kind.unit)
    except CorruptFileError as error:
        print(f"{error}; running {kind.unit} {key!r} again", file=sys.stderr)
        return None
    _refuse_other_settings(job, kind, record, str(found[1]))
    return (stored,)


def _refuse_other_settings(
    job: J, kind: JobKind[J, R], record: dict[str, Any] | None, where: str, remedy: str = ""
) -> None:
    """A ValueError if the result of `job` stored at `where` was run with other settings: it is
    never overwritten or mixed in."""
    if not kind.same(record, kind.record(job)):
        raise ValueError(
            f"{where} holds {kind.unit} {kind.key(job)!r} run with different settings "
            f"({record or 'unknown'}); allowed: the same settings to resume, or another "
            f"output folder{remedy} for new ones"
        )


@dataclass(frozen=True)
class Failure:
    """A job that raised: its key, its record (settings, seed) and the error."""

    key: str
    record: dict[str, Any]
    error: str
    record_path: Path


class SweepError(RuntimeError):
    """Some jobs of a sweep raised; every other job finished and was saved."""

    def __init__(self, failures: Sequence[Failure], unit: str) -> None:
        self.failures = list(failures)
        first = self.failures[0]
        lines = [
            f"{len(self.failures)} {unit}(s) failed; every other {unit} finished and is saved:"
        ]
        for f in self.failures:
            seed = f.record.get("seed", "-")
            lines.append(f"  {f.key} (seed {seed}): {f.error.strip().splitlines()[-1]}")
        lines.append(
            f"To rerun just one: python -m tavc_agents.experiments.sweep {first.record_path} "
            "(or rerun the whole command: finished ones are resumed, not recomputed)."
        )
        lines.append(f"First traceback:\n{first.error}")
        super().__init__("\n".join(lines))


def _forget_failure(out: Path, key: str) -> None:
    """Remove the failure record an earlier run left for `key`, which has now finished."""
    path = out / f"{key}.failed.json"
    if os.path.lexists(path):
        with contextlib.suppress(OSError):
            os.unlink(path)


class WorkerDied(RuntimeError):
    """A job whose pool worker process ended abruptly while running it (killed by a signal: the
    kernel's out-of-memory killer sends SIGKILL)."""


def _failure(kind: JobKind[J, R], job: J, error: BaseException, out: Path) -> Failure:
    key = kind.key(job)
    text = "".join(traceback.format_exception(error))
    record = kind.record(job)
    path = out / f"{key}.failed.json"
    with contextlib.suppress(OSError, ValueError):
        from tavc_agents.experiments.files import write_text

        write_text(path, json.dumps({"unit": kind.unit, "record": record, "error": text}))
    return Failure(key, record, text, path)


class SaveError(RuntimeError):
    """A finished job whose result could not be saved (a full disk, a folder made read-only): the
    sweep stops at the first one, since every later job would run only to fail at its save too."""


def _save(
    save: Callable[[R, dict[str, Any], Path], None],
    result: R,
    record: dict[str, Any],
    path: Path,
    unit: str,
) -> None:
    try:
        save(result, record, path)
    except OSError as error:
        key = path.name.removesuffix(".json")
        raise SaveError(
            f"could not save {unit} {key!r} to {path} ({error.strerror or error}); the sweep "
            f"stopped at this first refused save, and every {unit} saved before it is kept"
        ) from None


@dataclass(frozen=True)
class _Task(Generic[J, R]):
    """One job as a worker runs it: run, then save the result before returning it."""

    run: Callable[[J], R]
    save: Callable[[R, dict[str, Any], Path], None]
    job: J
    record: dict[str, Any]
    path: Path
    unit: str = "job"

    def __call__(self) -> R:
        _mark_started(self.path.name)
        result = self.run(self.job)
        _save(self.save, result, self.record, self.path, self.unit)
        return result


def _remove_temporaries(out: Path, keys: Collection[str]) -> None:
    """Remove the temporary files that saving one of `keys` in `out` leaves if its process is
    killed mid-save (`files.atomic_path` names them `.<key>.json.<random>.tmp.json`). Called only
    by the sweep holding the folder, when none of its own saves is under way."""
    wanted = set(keys)
    with contextlib.suppress(OSError), os.scandir(out) as entries:
        for entry in entries:
            name = entry.name
            if not (name.startswith(".") and name.endswith(".tmp.json")):
                continue
            key, found, _ = name[1 : -len(".tmp.json")].rpartition(".json.")
            if found and key in wanted and entry.is_file(follow_symlinks=False):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)


def _registered_for_workers() -> tuple[Allocator, ...]:
    """The allocators registered at run time, for the pool's workers; a ValueError naming one that
    a spawned (not forked) worker cannot receive, before any job starts."""
    registered = REGISTRY.registered_at_run_time()
    if multiprocessing.get_start_method() == "fork":
        return registered  # a forked worker has them in its copy of the memory: nothing is sent
    for entry in registered:
        try:
            pickle.dumps(entry)
        except Exception as error:  # pickling errors have no one type (PicklingError, ...)
            raise ValueError(
                f"allocator {entry.name!r} was registered at run time with a factory that worker "
                f"processes cannot receive ({type(error).__name__}: {error}); allowed: a factory "
                "defined at the top level of an importable module, a tavc.allocators entry point, "
                "or workers=1"
            ) from None
    return registered


_started: multiprocessing.connection.Connection | None = None
"""In a pool worker: the write end of the driver's pipe on which each job says it started."""


def _mark_started(name: str) -> None:
    """In a pool worker: tell the driver that this process starts the job saved to `name`, so
    that if this process dies abruptly the driver knows which job it was running. One write of a
    short line to a pipe is atomic; a full pipe drops the line (the job is then not blamed)."""
    if _started is not None:
        with contextlib.suppress(OSError):
            os.write(_started.fileno(), f"{os.getpid()} {name}\n".encode())


def _init_worker(
    parent: int,
    registered: Sequence[Allocator] = (),
    started: multiprocessing.connection.Connection | None = None,
) -> None:
    """Pool worker initialiser: the allocators the driver registered at run time (a worker that is
    spawned rather than forked starts without them; entry points it finds itself), then
    `_die_with_parent`. A forked worker lets go of the driver's folder locks it inherited.
    `started`: where each job says it started (`_mark_started`)."""
    global _started
    forget_inherited()
    if started is not None:
        os.set_blocking(started.fileno(), False)
        _started = started
    for entry in registered:
        REGISTRY.register(entry.name, entry.factory, team=entry.team, replace=True)
    _die_with_parent(parent)


def _die_with_parent(parent: int) -> None:
    """Ask Linux to kill this worker when its parent dies (SIGKILL of the driver leaves no orphan
    burning a core); elsewhere a no-op."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the request took effect
        os._exit(1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's to handle
    # The driver terminates its workers to stop a sweep: end at once (not with the driver's
    # KeyboardInterrupt, which the pool would report back and then run the next queued job). A
    # save cut short leaves only a temporary file, which the driver removes.
    signal.signal(signal.SIGTERM, _end_worker)


def _end_worker(signum: int, frame: Any) -> None:
    os._exit(128 + signum)


def _run_in_pool(
    todo: Sequence[J],
    kind: JobKind[J, R],
    records: Mapping[str, dict[str, Any]],
    out: Path,
    n_workers: int,
    finish: Callable[[J, R, bool], None],
    fail: Callable[[J, BaseException], None],
) -> None:
    """Run `todo` in a process pool. A worker that dies abruptly breaks the pool (CPython then
    fails every job it holds and ends its other workers): only the job that worker was running
    fails (`WorkerDied`); the others run again in a fresh pool. A break that blames no job twice
    in a row fails what is left (a pool that cannot start its workers must not loop)."""
    queue, fruitless = list(todo), 0
    while queue:
        broken = _pool_round(queue, kind, records, out, min(n_workers, len(queue)), finish, fail)
        if broken is None:
            return
        blamed, queue = broken
        fruitless = 0 if blamed else fruitless + 1
        if fruitless >= 2:
            for job in queue:
                fail(job, WorkerDied("the process pool broke again before the job could run"))
            return


def _pool_round(
    todo: Sequence[J],
    kind: JobKind[J, R],
    records: Mapping[str, dict[str, Any]],
    out: Path,
    n_workers: int,
    finish: Callable[[J, R, bool], None],
    fail: Callable[[J, BaseException], None],
) -> tuple[int, list[J]] | None:
    """One pool over `todo`: None if it did not break; else how many jobs were failed for the
    break and the jobs to run again."""
    reader, writer = multiprocessing.Pipe(duplex=False)
    pool = ProcessPoolExecutor(
        max_workers=n_workers,
        initializer=_init_worker,
        initargs=(os.getpid(), _registered_for_workers(), writer),
    )
    futures: dict[Future[R], J] = {}
    started: dict[str, int] = {}  # result file name -> the pid of the worker that started it
    broken: list[J] = []
    try:
        for job in todo:
            key = kind.key(job)
            task = _Task(kind.run, kind.save, job, records[key], result_path(out, key), kind.unit)
            futures[pool.submit(task)] = job
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                error = future.exception()
                if isinstance(error, SaveError):
                    raise error  # a folder that refuses one save refuses the next: stop here
                if isinstance(error, BrokenProcessPool):
                    broken.append(futures[future])
                elif error is not None:
                    fail(futures[future], error)
                else:
                    finish(futures[future], future.result(), True)
        if not broken:
            return None
        _read_started(reader, started)
        died = _abruptly_ended(pool)
        blamed, again = 0, []
        for job in broken:
            name = result_path(out, kind.key(job)).name
            pid = started.get(name)
            if pid is not None and pid in died:
                fail(
                    job,
                    WorkerDied(
                        f"its worker process (pid {pid}) {died[pid]}; the other "
                        f"{kind.unit}s went on in a fresh pool"
                    ),
                )
                blamed += 1
            else:
                again.append(job)
        return blamed, again
    except BaseException:
        # Ctrl-C, SIGTERM or a refused save: every finished job was saved by its worker before it
        # reported back; the queued ones are dropped and the running ones end with their workers
        # now, rather than run to their end first.
        _end_workers(pool)
        raise
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
        reader.close()
        writer.close()


def _read_started(reader: multiprocessing.connection.Connection, started: dict[str, int]) -> None:
    """Every line the workers wrote on the `started` pipe so far, into `started` (the last job
    each result file's worker started)."""
    os.set_blocking(reader.fileno(), False)
    data = b""
    while True:
        try:
            chunk = os.read(reader.fileno(), 65536)
        except BlockingIOError:
            break
        if not chunk:
            break
        data += chunk
    for line in data.decode(errors="replace").splitlines():
        pid, _, name = line.partition(" ")
        if pid.isdigit() and name:
            started[name] = int(pid)


def _abruptly_ended(pool: ProcessPoolExecutor, timeout_s: float = 30.0) -> dict[int, str]:
    """The workers of the broken `pool` that ended abruptly (not by the SIGTERM with which the
    pool ends the others), by pid, with how they ended. Waits for the pool's manager thread,
    which reaps them."""
    # CPython's pool keeps these here (it has no public way to see its workers).
    thread = getattr(pool, "_executor_manager_thread", None)
    if thread is not None:
        thread.join(timeout_s)
    ended = {}
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        code = process.exitcode
        if code is None or code in (0, -signal.SIGTERM, 128 + signal.SIGTERM):
            continue
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            how = f"was killed by {name}"
            if -code == signal.SIGKILL:
                how += " (the kernel's out-of-memory killer sends it: too little memory?)"
        else:
            how = f"exited with code {code}"
        if process.pid is not None:
            ended[process.pid] = how
    return ended


def _end_workers(pool: ProcessPoolExecutor, grace_s: float = 0.5) -> None:
    """Cancel the queued jobs of `pool` and end its workers: SIGTERM, then SIGKILL after
    `grace_s`. Further Ctrl-C or SIGTERM are ignored meanwhile (the stop is under way)."""
    with _signals_ignored():
        # CPython's pool keeps its worker processes here (it has no public way to end them).
        workers = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in workers:
            process.terminate()
        deadline = time.monotonic() + grace_s
        for process in workers:
            process.join(max(0.0, deadline - time.monotonic()))
        for process in workers:
            if process.is_alive():
                process.kill()
                process.join(grace_s)


@contextlib.contextmanager
def _signals_ignored() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM are ignored (in the main thread; elsewhere no-op)."""
    try:
        previous = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


@contextlib.contextmanager
def _stop_on_sigterm() -> Iterator[None]:
    """Within the block, SIGTERM stops the sweep as Ctrl-C does (with KeyboardInterrupt)."""

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _save_trial(result: TrialResult, record: dict[str, Any], path: Path) -> None:
    result.spec = record
    result.save(path)


def _load_trial(path: Path) -> tuple[TrialResult, dict[str, Any] | None]:
    result = TrialResult.load(path)
    return result, result.spec


def _save_json(result: dict[str, Any], record: dict[str, Any], path: Path) -> None:
    # NaN is allowed in job results: some studies' results use it for "undefined" (a Q gap with
    # no robot of a class, in the committed regime-map and passing records); infinity is not.
    write_record(path, {"record": record, "result": result}, nan=True)


def _load_json(path: Path) -> tuple[dict[str, Any], dict[str, Any] | None]:
    data = read_record(path, nan=True)
    try:
        return data["result"], data.get("record")
    except KeyError:
        raise CorruptFileError(f"{path} has no 'result'; it is not a saved job") from None


def _same_trial(stored: dict[str, Any] | None, wanted: dict[str, Any]) -> bool:
    if stored is None:
        return False
    # Tags are labels, not settings (and trials saved before tags existed have none).
    stored = {k: v for k, v in stored.items() if k != "tags"}
    wanted = {k: v for k, v in wanted.items() if k != "tags"}
    if "arena" not in stored:
        # Saved before records carried the arena's digest (November 2026), when every preset
        # still had its original definition: taken as made with the arena it names today.
        return stored == {k: v for k, v in wanted.items() if k != "arena"}
    return stored == wanted


def _check_spec(spec: TrialSpec) -> None:
    make_allocator(spec.allocator, **spec.allocator_kwargs)  # names a bad allocator or parameter
    env_arguments(spec.env_kwargs)  # names a key that is neither an arena field nor an option


TRIALS: JobKind[TrialSpec, TrialResult] = JobKind(
    check=_check_spec,
    run=run_spec,
    key=lambda spec: spec.key,
    record=spec_record,
    save=_save_trial,
    load=_load_trial,
    parse=packs.trial_from_data,
    unit="trial",
    same=_same_trial,
)


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
    return run_jobs(specs, TRIALS, out_dir, workers, on_done, progress_bar, backend)


def json_jobs(
    run: Callable[[J], dict[str, Any]],
    key: Callable[[J], str],
    unit: str = "run",
    omit: Collection[str] = (),
    added: Mapping[str, Any] | None = None,
) -> JobKind[J, dict[str, Any]]:
    """A `JobKind` for jobs that are frozen dataclasses and results that are JSON data: each is
    saved as `{"record": <the job>, "result": <the result>}`. Fields named in `omit` stay out of
    the record (bulky inputs; the job must then carry a digest of them in another field, so that
    a changed input still fails to resume). `added`: fields added to the job after some were
    saved, with the value that does what the job did before them; a record without such a field
    is taken as made with that value."""
    before = dict(added or {})

    def record(job: J) -> dict[str, Any]:
        fields = {k: v for k, v in asdict(job).items() if k not in omit}  # type: ignore[call-overload]
        data: dict[str, Any] = json.loads(json.dumps(fields, default=repr))
        return data

    def same(stored: dict[str, Any] | None, wanted: dict[str, Any]) -> bool:
        return stored is not None and {**before, **stored} == wanted

    return JobKind(
        run=run,
        key=key,
        record=record,
        save=_save_json,
        load=_load_json,
        parse=packs.json_from_data,
        unit=unit,
        same=same,
    )


def _run_on_ray(
    todo: Sequence[J],
    run: Callable[[J], R],
    workers: int | None,
    finish: Callable[[J, R, bool], None],
    fail: Callable[[J, BaseException], None],
) -> None:
    """Run `todo` as Ray tasks (one CPU each), saving each result here as soon as it arrives (the
    tasks may run on other machines); on Ctrl-C or SIGTERM the results that are ready are saved
    before the rest are cancelled."""
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
            # Job functions live in the installed package, so workers import them as we do.
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1, max_retries=0)(run)
    pending = {task.remote(job): job for job in todo}

    def collect(refs: Sequence[Any]) -> None:
        for ref in refs:
            job = pending.pop(ref)
            try:
                result = ray.get(ref)
            except ray.exceptions.RayTaskError as error:
                fail(job, error.as_instanceof_cause())
            except ray.exceptions.RayError as error:
                fail(job, error)
            else:
                finish(job, result, False)

    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            collect(done)
    finally:
        # Interrupted: save what is ready before cancelling the rest.
        if pending:
            ready, _ = ray.wait(list(pending), num_returns=len(pending), timeout=0)
            with contextlib.suppress(Exception):
                collect(ready)
        for ref in pending:
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()


def rerun_failed(path: str | Path) -> TrialResult:
    """Run again the trial recorded in a `<key>.failed.json` that a sweep wrote, in this process
    (for debugging one failure), and save it beside, as `<key>.json`, if it now succeeds."""
    data = read_failed(path)
    spec = spec_from_record(data["record"])
    result = run_spec(spec)
    _save_trial(result, data["record"], Path(path).with_name(f"{spec.key}.json"))
    _forget_failure(Path(path).parent, spec.key)  # the failure is stale now
    return result


def read_failed(path: str | Path) -> dict[str, Any]:
    data = read_json(path, RECORD_MAX_BYTES, "failed-trial record")
    if not isinstance(data, dict):
        raise CorruptFileError(f"{path} holds {type(data).__name__}, not a failed-trial record")
    if data.get("unit") != "trial":
        raise ValueError(
            f"{path} records a failed {data.get('unit')!r}; allowed: a failed trial "
            "(other jobs rerun by rerunning their command)"
        )
    return data


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: python -m tavc_agents.experiments.sweep <key>.failed.json")
    done = rerun_failed(sys.argv[1])
    print(
        f"{done.label}: ran again without error and was saved beside {sys.argv[1]} "
        "(that failure record is removed)"
    )
