"""Decisions per second of the vectorised views against their one-process figure, in wall time.

Cases, all in one run, taking turns round after round (`repeats`), each from a fixed seed:

* `gymnasium.make_vec("tavc/dahl2004-v0", k, vectorization_mode=...)`, the single-robot view
  (`tavc_agents.envs.single_robot`): sync with 1 env, async with 1 and with 2 (one worker process
  each). A decision is one step of one sub-env (one of the learner's tasks; the reset steps of
  NEXT_STEP autoreset are not counted);
* `tavc_env.adapters.batched.BatchedArenaEnv`, the batched multi-agent view: every arena in this
  process, and 1 and 2 worker processes with `arenas_per_worker` arenas each. A decision is a
  `must_decide` entry (a robot whose action the step read).

Random actions from a seeded generator; the timed part is the stepping loop alone (construction,
worker start-up and reset are not timed). Processes run side by side, so the figure is decisions
per wall second; CPU seconds of this process and of the workers (from /proc) are recorded too, with
the machine's load average. Ratios are to the 1-worker figure of the same round (async 1 for
make_vec, 1 worker for the batched view). Goal (issue 26): 2 workers >= 1.6 x 1, in both views.
The script is `benchmarks/vector_throughput.py`; outputs `vector_throughput.{md,csv,json}`.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing import shared_memory
from multiprocessing.connection import Connection
from typing import Any, ClassVar, NamedTuple

import gymnasium
import numpy as np

import tavc_agents.envs  # noqa: F401  (registers the Gymnasium ids)
from tavc_agents.analysis.reports import Report, markdown_table
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.study import Outcome, StudySettings
from tavc_agents.studies.common import at_least, positive
from tavc_env._validation import is_number, require
from tavc_env.adapters.batched import ArenaGroup, BatchedArenaEnv
from tavc_env.env import parallel_env

__all__ = ["Settings", "run"]

GYM_ID = "tavc/dahl2004-v0"
GOAL = 1.6  # 2 workers over 1 (issue 26), decisions per wall second, for both views
Row = dict[str, Any]


@dataclass(frozen=True)
class Case:
    """One configuration timed: a view, how it is vectorised and over how many processes."""

    name: str
    view: str  # "make_vec" or "batched"
    mode: str  # make_vec: "sync" / "async"; batched: "in-process" / "workers"
    envs: int  # sub-envs (make_vec) or arenas (batched)
    workers: int  # worker processes (0: none)
    baseline: str  # the case its ratio is taken to


class RunSize(NamedTuple):
    """What a run does: rounds, timed steps per case, the idle wait and the episode length."""

    rounds: int
    steps: int
    idle_wait_s: float
    episode_s: float


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The vector throughput benchmark's settings (its command line). The cases run one at a
    time in this process and its workers, so `workers` can only be 1 and `backend` local."""

    reference: ClassVar = "vector_throughput"
    quick_reference_apart: ClassVar = False

    repeats: int = 5
    """rounds (every case once per round)"""
    steps: int = 400
    """timed vector steps per case and round"""
    arenas_per_worker: int = 4
    """arenas of each batched worker (several spread the cost of the pipes)"""
    episode_s: float = 4 * 3600.0
    """simulated seconds of an episode (long: resets are rare)"""
    idle_wait_s: float = 60.0
    """before each case, wait up to this long for idle cores (0: no wait): another busy session
    takes a core from all of this run's processes"""
    quick: bool = False
    """smoke run: 2 rounds of 20 steps, 1-hour episodes, no waiting"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            ("repeats", at_least(self.repeats, 1), "an integer >= 1"),
            ("steps", at_least(self.steps, 1), "an integer >= 1"),
            ("arenas_per_worker", at_least(self.arenas_per_worker, 1), "an integer >= 1"),
            ("episode_s", positive(self.episode_s), "a duration > 0 s"),
            ("idle_wait_s", is_number(self.idle_wait_s) and self.idle_wait_s >= 0, "seconds >= 0"),
        ]
        for name, ok, allowed in checks:
            require(ok, name, getattr(self, name), allowed)
        require(
            self.workers in (None, 1) and self.backend == "local",
            "workers",
            self.workers,
            "1 (or unset) and backend local: the cases choose their own processes",
        )

    @property
    def size(self) -> RunSize:
        """What this run does: the settings, or the smoke run's sizes with `quick`."""
        if self.quick:
            return RunSize(rounds=2, steps=20, idle_wait_s=0.0, episode_s=3600.0)
        return RunSize(self.repeats, self.steps, self.idle_wait_s, self.episode_s)

    @property
    def cases(self) -> list[Case]:
        k = self.arenas_per_worker
        one_env, one_worker = "make_vec async, 1 env", f"batched 1 worker x {k} arenas"
        return [
            Case("make_vec sync, 1 env", "make_vec", "sync", 1, 0, one_env),
            Case(one_env, "make_vec", "async", 1, 1, one_env),
            Case("make_vec async, 2 envs", "make_vec", "async", 2, 2, one_env),
            Case(f"batched in-process, {k} arenas", "batched", "in-process", k, 0, one_worker),
            Case(one_worker, "batched", "workers", k, 1, one_worker),
            Case(f"batched 2 workers x {k} arenas", "batched", "workers", 2 * k, 2, one_worker),
        ]

    def recorded(self) -> dict[str, Any]:
        return {
            "repeats": self.size.rounds,
            "steps": self.size.steps,
            "arenas_per_worker": self.arenas_per_worker,
            "episode_s": self.size.episode_s,
            "idle_wait_s": self.size.idle_wait_s,
            "quick": self.quick,
        }


def process_cpu_s(pids: Sequence[int]) -> float:
    """CPU seconds (user + system) the processes `pids` have used so far, from /proc (Linux);
    NaN where /proc cannot tell."""
    ticks = os.sysconf("SC_CLK_TCK")
    total = 0.0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat", encoding="ascii") as fh:
                fields = fh.read().rpartition(")")[2].split()
        except OSError:
            return float("nan")
        total += (int(fields[11]) + int(fields[12])) / ticks  # utime, stime
    return total


def own_cpu_s() -> float:
    t = os.times()
    return t.user + t.system


def time_make_vec(case: Case, seed: int, steps: int, episode_s: float) -> Row:
    """`steps` vector steps of the single-robot view vectorised by `gymnasium.make_vec`."""
    envs = gymnasium.make_vec(GYM_ID, case.envs, vectorization_mode=case.mode, episode_s=episode_s)
    try:
        pids = [p.pid for p in getattr(envs, "processes", []) if p.pid is not None]
        rng = np.random.default_rng([seed, 1])
        envs.reset(seed=seed)
        resetting = np.zeros(case.envs, bool)  # NEXT_STEP: this step resets those sub-envs
        decisions = 0
        cpu, workers_cpu, started = own_cpu_s(), process_cpu_s(pids), time.perf_counter()
        for _ in range(steps):
            decisions += int((~resetting).sum())
            _, _, terminated, truncated, _ = envs.step(rng.integers(0, 2, case.envs))
            resetting = terminated | truncated
        wall = time.perf_counter() - started
        cpu, workers_cpu = own_cpu_s() - cpu, process_cpu_s(pids) - workers_cpu
    finally:
        envs.close()
    return {"decisions": decisions, "wall_s": wall, "cpu_s": cpu, "workers_cpu_s": workers_cpu}


def time_batched(case: Case, seed: int, steps: int, episode_s: float) -> Row:
    """`steps` steps of the batched multi-agent view."""
    env_kwargs = {"preset": "dahl2004", "max_sim_time_s": episode_s}
    with BatchedArenaEnv(case.envs, workers=case.workers, env_kwargs=env_kwargs) as batch:
        pids = batch.worker_pids
        rng = np.random.default_rng([seed, 2])
        _, infos = batch.reset(seed=seed)
        must_decide = infos["action_required"]
        shape = (batch.n_envs, batch.n_agents)
        decisions = 0
        cpu, workers_cpu, started = own_cpu_s(), process_cpu_s(pids), time.perf_counter()
        for _ in range(steps):
            decisions += int(must_decide.sum())
            must_decide = batch.step(rng.integers(0, batch.n_circuits, shape)).must_decide
        wall = time.perf_counter() - started
        cpu, workers_cpu = own_cpu_s() - cpu, process_cpu_s(pids) - workers_cpu
    return {"decisions": decisions, "wall_s": wall, "cpu_s": cpu, "workers_cpu_s": workers_cpu}


# -- the transport: pickled arrays through the pipe, or shared memory ------------------------------
def _echo_pickled(connection: Connection, payload: dict[str, np.ndarray]) -> None:
    """A worker that answers every message with `payload`, pickled (as `BatchedArenaEnv`'s)."""
    while connection.recv() is not None:
        connection.send(payload)


def _echo_shared(connection: Connection, payload: dict[str, np.ndarray], block: str) -> None:
    """A worker that writes `payload` into shared memory `block` and answers with one byte."""
    memory = shared_memory.SharedMemory(name=block)
    views = _views(memory, payload)
    while connection.recv() is not None:
        for key, value in payload.items():
            views[key][...] = value
        connection.send_bytes(b"1")
    del views
    memory.close()


def _views(memory: shared_memory.SharedMemory, like: dict[str, np.ndarray]) -> dict[str, Any]:
    views, offset = {}, 0
    for key, value in like.items():
        views[key] = np.ndarray(value.shape, value.dtype, buffer=memory.buf, offset=offset)
        offset += value.nbytes
    return views


def transport_us(payload: dict[str, np.ndarray], trips: int) -> dict[str, float]:
    """Median microseconds of one round trip (actions out, one step's arrays back, copied out in
    this process) with each transport, over `trips` trips in blocks of 50."""
    context: Any = multiprocessing.get_context("fork")
    actions = np.zeros(payload["rewards"].shape, np.int64)  # (arenas, robots)
    size = sum(v.nbytes for v in payload.values())
    memory = shared_memory.SharedMemory(create=True, size=size)
    found = {}
    try:
        for name, target, extra in (
            ("pickled_us", _echo_pickled, ()),
            ("shared_memory_us", _echo_shared, (memory.name,)),
        ):
            here, there = context.Pipe()
            worker = context.Process(target=target, args=(there, payload, *extra), daemon=True)
            worker.start()
            views = _views(memory, payload)
            blocks = []
            for _ in range(max(trips // 50, 1)):
                started = time.perf_counter()
                for _ in range(50):
                    here.send(actions)
                    if name == "pickled_us":
                        here.recv()
                    else:
                        here.recv_bytes()
                        {key: view.copy() for key, view in views.items()}
                blocks.append((time.perf_counter() - started) / 50 * 1e6)
            del views
            here.send(None)
            worker.join()
            found[name] = float(np.median(blocks))
    finally:
        memory.close()
        memory.unlink()
    found["payload_bytes"] = float(size)
    return found


def step_payload(arenas: int, episode_s: float) -> dict[str, np.ndarray]:
    """The arrays one worker of `arenas` arenas sends for one step (a step with no episode end)."""
    group = ArenaGroup(parallel_env, {"max_sim_time_s": episode_s}, arenas)
    group.reset([0] * arenas)
    return {k: v for k, v in group.step(np.zeros((arenas, 6), np.int64)).items() if k != "final"}


def idle_share(window_s: float = 0.5) -> float:
    """The share of all cores' time that was idle over the next `window_s` (Linux's /proc/stat);
    1.0 if it cannot tell."""

    def idle_and_total() -> tuple[int, int]:
        with open("/proc/stat", encoding="ascii") as fh:
            ticks = [int(x) for x in fh.readline().split()[1:]]
        return ticks[3] + ticks[4], sum(ticks)  # idle + iowait, all

    try:
        idle0, total0 = idle_and_total()
        time.sleep(window_s)
        idle1, total1 = idle_and_total()
    except (OSError, IndexError, ValueError):
        return 1.0
    return (idle1 - idle0) / max(total1 - total0, 1)


IDLE = 0.9  # the machine counts as idle when at least this share of its cores' time is


def wait_for_idle(limit_s: float) -> tuple[float, float]:
    """Wait up to `limit_s` until the machine has been idle (`IDLE`) for three half-second
    windows in a row; return the seconds waited and the idle share last seen."""
    started = time.perf_counter()
    quiet, share = 0, idle_share(0.1)
    while quiet < 3 and time.perf_counter() - started < limit_s:
        share = idle_share()
        quiet = quiet + 1 if share >= IDLE else 0
    return time.perf_counter() - started, share


def measure(s: Settings) -> list[Row]:
    """Every case once per round, in turn, after one untimed warm-up of each view."""
    time_make_vec(s.cases[0], 0, 5, s.size.episode_s)  # imports, compiled caches
    time_batched(s.cases[3], 0, 5, s.size.episode_s)
    rows: list[Row] = []
    started = time.perf_counter()
    for rep in range(s.size.rounds):
        for case in s.cases:
            timer = time_make_vec if case.view == "make_vec" else time_batched
            waited, idle = wait_for_idle(s.size.idle_wait_s)
            load = os.getloadavg()[0]
            found = timer(case, rep, s.size.steps, s.size.episode_s)
            found["decisions_per_s"] = found["decisions"] / found["wall_s"]
            rows.append(
                {
                    "case": case.name,
                    "view": case.view,
                    "mode": case.mode,
                    "envs": case.envs,
                    "workers": case.workers,
                    "repeat": rep,
                    "load_1min": load,
                    "idle_wait_s": waited,
                    "idle_share": idle,
                    **found,
                }
            )
        print(f"round {rep + 1} done ({time.perf_counter() - started:.0f} s)", flush=True)
    return rows


def ratios(rows: Sequence[Row], case: Case) -> list[float]:
    """The case's decisions per second over its baseline's, paired by round."""
    mine = {r["repeat"]: r["decisions_per_s"] for r in rows if r["case"] == case.name}
    theirs = {r["repeat"]: r["decisions_per_s"] for r in rows if r["case"] == case.baseline}
    return [mine[k] / theirs[k] for k in sorted(mine)]


def median_range(values: Sequence[float], digits: int) -> str:
    return f"{np.median(values):.{digits}f} [{min(values):.{digits}f}, {max(values):.{digits}f}]"


HEADER = [
    "case",
    "processes",
    "decisions / wall s",
    "ratio to 1 worker",
    "wall s",
    "CPU s (this process + workers)",
    "cores busy (CPU s / wall s)",
    "CPU ms / decision",
    "load (1 min)",
    "idle at start",
    "goal",
]


def sched_autogroup() -> bool | None:
    """Whether the kernel schedules each session's processes as one group (Linux's autogroup:
    then a benchmark's workers share one session's slice of a busy machine); None if unknown."""
    try:
        with open("/proc/sys/kernel/sched_autogroup_enabled", encoding="ascii") as fh:
            return fh.read().strip() == "1"
    except OSError:
        return None


def transport_paragraph(found: Row, s: Settings) -> str:
    return (
        f"Transport of the batched view: a round trip (actions out, one step's arrays of "
        f"{s.arenas_per_worker} arenas back, {found['payload_bytes']:.0f} bytes, copied out here) "
        f"took {found['pickled_us']:.0f} us pickled through the pipe and "
        f"{found['shared_memory_us']:.0f} us through shared memory with a one-byte answer "
        "(median of blocks of 50 trips, echo worker); `BatchedArenaEnv` uses shared memory."
    )


def build_report(rows: Sequence[Row], s: Settings, transport: Row | None = None) -> Report:
    table: list[list[str]] = []
    cases: dict[str, Any] = {}
    for case in s.cases:
        mine = [r for r in rows if r["case"] == case.name]
        speed = [r["decisions_per_s"] for r in mine]
        ratio = ratios(rows, case)
        verdict = "-"
        if case.workers == 2:  # the goal, for both views
            ok = float(np.median(ratio)) >= GOAL
            verdict = f"{'PASS' if ok else 'FAIL'} (>= {GOAL:g} x 1 worker)"
        cpu = [r["cpu_s"] + (r["workers_cpu_s"] if case.workers else 0.0) for r in mine]
        loads = [r["load_1min"] for r in mine]
        idle = sum(r.get("idle_share", 1.0) >= IDLE for r in mine)
        table.append(
            [
                case.name,
                f"1 + {case.workers}" if case.workers else "1",
                median_range(speed, 0),
                median_range(ratio, 2),
                median_range([r["wall_s"] for r in mine], 2),
                median_range(cpu, 2),
                median_range([c / r["wall_s"] for c, r in zip(cpu, mine)], 2),
                median_range([1e3 * c / r["decisions"] for c, r in zip(cpu, mine)], 3),
                f"{min(loads):.1f}-{max(loads):.1f}",
                f"{idle}/{len(mine)}",
                verdict,
            ]
        )
        cases[case.name] = {
            "decisions_per_s": float(np.median(speed)),
            "ratio_to_one_worker": float(np.median(ratio)),
            "ratio_range": [min(ratio), max(ratio)],
            "cores_busy": float(np.median([c / r["wall_s"] for c, r in zip(cpu, mine)])),
            "cpu_ms_per_decision": float(
                np.median([1e3 * c / r["decisions"] for c, r in zip(cpu, mine)])
            ),
            "load_1min": [min(loads), max(loads)],
            "idle_at_start": idle,
            "verdict": verdict,
        }
    body = "\n".join(
        [
            f"{s.size.rounds} rounds of {s.size.steps} vector steps per case, median [min, max] over "
            "rounds; the cases take turns within each round, from seed = round. Decisions per "
            "*wall* second of the stepping loop (processes run side by side): for `make_vec` one "
            f"decision is a step of one sub-env of `{GYM_ID}` (one of the learner's tasks, about "
            "six arena steps; NEXT_STEP reset steps not counted); for the batched view a robot "
            "whose action the step read (`must_decide`). The two views' figures are therefore not "
            "comparable with each other; the ratios are to the 1-worker case of the same view and "
            "round (async 1 env; 1 worker). CPU s: this process plus its workers (from /proc), "
            f"over the timed loop. Episodes of {s.size.episode_s:g} simulated s, `dahl2004`, "
            f"random actions. 'cores busy' is CPU s over wall s: with 2 workers it is 2 on an idle "
            "2-core machine; 'CPU ms / decision' staying put from 1 to 2 workers means the pipes "
            "cost nothing extra, so a ratio below 2 comes from cores the workers did not get. "
            f"'load' is the 1-minute load average before each case ({os.cpu_count()} cores): "
            "other work on the machine takes cores from the workers and shrinks the ratios, so "
            f"each case first waits up to {s.size.idle_wait_s:g} s for the cores to be idle (at least "
            f"{IDLE:.0%} of their time, three half-second windows in a row); 'idle at start' "
            "counts the rounds in which they were.",
            "",
            markdown_table(HEADER, table),
        ]
    )
    grouped = sched_autogroup()
    summary: dict[str, Any] = {"cases": cases, "sched_autogroup": grouped}
    if grouped:
        body += (
            "\n\nThis kernel groups each session's processes for scheduling (sched_autogroup): "
            "on a machine busy with other sessions the benchmark's processes share one session's "
            "slice however many workers it starts, so 'cores busy' stays flat and the ratios "
            "near 1; they measure the workers' overhead, not their speed-up, unless the machine "
            "is otherwise idle (load well under the core count)."
        )
    if transport is not None:
        summary["transport"] = transport
        body += "\n\n" + transport_paragraph(transport, s)
    return Report(
        "vector_throughput", "Vectorised views: decisions per second", body, list(rows), summary
    )


def run(settings: Settings) -> Outcome:
    """Measure every case, then write the report; the outcome names the goal if it was missed."""
    provenance = run_metadata(settings=settings.recorded())
    started = time.perf_counter()
    rows = measure(settings)
    payload = step_payload(settings.arenas_per_worker, settings.size.episode_s)
    transport = transport_us(payload, 200 if settings.quick else 2000)
    provenance["wall_time_s"] = time.perf_counter() - started
    report = build_report(rows, settings, transport)
    out = settings.out_dir()
    verdicts = {name: found["verdict"] for name, found in report.summary["cases"].items()}
    return Outcome(
        out,
        report.write(out, provenance),
        f"{report.body}\nwrote {out / 'vector_throughput.md'}",
        [f"{name}: {v}" for name, v in verdicts.items() if v.startswith("FAIL")],
    )
