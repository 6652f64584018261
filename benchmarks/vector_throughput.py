"""Decisions per second of the vectorised views with 1 and 2 worker processes, in wall time, in one
run: `gymnasium.make_vec("tavc/dahl2004-v0", ...)` (the single-robot view) sync 1, async 1 and
async 2, and the batched multi-agent view (`tavc_env.adapters.batched.BatchedArenaEnv`) in-process
and with 1 and 2 workers, for each of `--arenas-per-worker` (default 4 and 16 arenas per worker).
Every round also measures the machine's ceiling (two independent processes stepping the
single-robot view, over one) and reports each 2-worker ratio as a share of it, with the measured
parts that explain the gap (the workers' step cost and its spread, measured in-process; the
parent's CPU per vector step). Ratios are to the 1-worker figure of the same round; goal (issue 26):
2 workers >= 1.6 x 1 in both views (exit status 1 if missed). Writes `vector_throughput.{csv,md,json}`
into a new run folder under runs/ (git ignores it), `--out`, or with `--update-reference`
benchmarks/results/vector_throughput/.

    python benchmarks/vector_throughput.py               # a few minutes on 2 idle cores
    python benchmarks/vector_throughput.py --quick

Decisions per second of the vectorised views against their one-process figure, in wall time,
and against what the machine itself gives two processes.

Cases, all in one run, taking turns round after round (`repeats`), each from a fixed seed:

* the machine's **ceiling**: one and two independent processes, each stepping the single-robot view
  (`tavc_agents.envs.single_robot`, the same work as one sub-env of `make_vec`) on its own, with no
  pipes and no lock-step. Its 2-over-1 ratio is what two processes can get on this machine (shared
  caches, frequency, other load), so each 2-worker ratio is also reported as a share of it;
* `gymnasium.make_vec("tavc/dahl2004-v0", k, vectorization_mode=...)`: sync with 1 env, async with
  1 and with 2 (one worker process each). A decision is one step of one sub-env (one of the
  learner's tasks; the reset steps of NEXT_STEP autoreset are not counted);
* `tavc_env.adapters.batched.BatchedArenaEnv`, the batched multi-agent view, for each of
  `arenas_per_worker`: every arena in this process, and 1 and 2 worker processes with that many
  arenas each. A decision is a `must_decide` entry (a robot whose action the step read).

Random actions from a seeded generator; the timed part is the stepping loop alone (construction,
worker start-up and reset are not timed). Processes run side by side, so the figure is decisions
per wall second; CPU seconds of this process and of the workers are recorded too, with the
machine's load average. Ratios are to the 1-worker figure of the same round (1 process for the
ceiling, async 1 for make_vec, 1 worker for the batched view). Goal (issue 26): 2 workers >= 1.6 x 1,
in both views.

Where a 2-worker case falls short of the ceiling is explained from measured numbers
(`gap_model`): the CPU cost of one worker's step, measured in this process every round
(`step_costs`: its mean, its coefficient of variation, and how much longer the slower of two such
steps takes, which a lock-step vector step waits for), and the parent's CPU per vector step in the
timed cases. The script is `benchmarks/vector_throughput.py`; outputs `vector_throughput.{md,csv,json}`.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing import shared_memory
from multiprocessing.connection import Connection
from typing import Any, ClassVar, NamedTuple

import gymnasium
import numpy as np

import tavc_agents.envs  # noqa: F401  (registers the Gymnasium ids)
from tavc_agents.analysis.reports import Report, markdown_table
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_env.adapters.batched import ArenaGroup, BatchedArenaEnv
from tavc_env.env import parallel_env
from tavc_env.validation import is_number, require

__all__ = ["Settings", "run"]

GYM_ID = "tavc/dahl2004-v0"
CIRCUITS = 2  # dahl2004's circuits: the single-robot view's random actions are 0 or 1
GOAL = 1.6  # 2 workers over 1 (issue 26), decisions per wall second, for both views
Row = dict[str, Any]


@dataclass(frozen=True)
class Case:
    """One configuration timed: a view, how it is vectorised and over how many processes."""

    name: str
    view: str  # "ceiling", "make_vec" or "batched"
    mode: (
        str  # ceiling: "independent"; make_vec: "sync" / "async"; batched: "in-process" / "workers"
    )
    envs: int  # single-robot envs (ceiling, make_vec) or arenas (batched)
    workers: int  # worker processes (0: none)
    baseline: str  # the case its ratio is taken to

    @property
    def per_worker(self) -> int:
        """Envs or arenas each process steps: what one worker's step costs (`step_costs`)."""
        return self.envs // max(self.workers, 1)


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
    """timed vector steps per case and round (also the in-process steps of `step_costs`)"""
    arenas_per_worker: tuple[int, ...] = (4, 16)
    """arenas of each batched worker, one set of batched cases each (several spread the cost of
    the pipes and even out the workers' steps)"""
    episode_s: float = 4 * 3600.0
    """simulated seconds of an episode (long: resets are rare)"""
    idle_wait_s: float = 60.0
    """before each case, wait up to this long for idle cores (0: no wait): another busy session
    takes a core from all of this run's processes"""
    quick: bool = False
    """smoke run: 2 rounds of 20 steps, 1-hour episodes, no waiting"""

    def __post_init__(self) -> None:
        super().__post_init__()
        arenas = self.arenas_per_worker
        arenas_ok = (
            isinstance(arenas, tuple)
            and len(arenas) >= 1
            and all(at_least(k, 1) for k in arenas)
            and len(set(arenas)) == len(arenas)
        )
        checks = [
            ("repeats", at_least(self.repeats, 1), "an integer >= 1"),
            ("steps", at_least(self.steps, 2), "an integer >= 2 (the slower of two steps)"),
            ("arenas_per_worker", arenas_ok, "one or more distinct integers >= 1"),
            ("episode_s", positive(self.episode_s), "a duration > 0 s"),
            ("idle_wait_s", is_number(self.idle_wait_s) and self.idle_wait_s >= 0, "seconds >= 0"),
        ]
        refuse_invalid(self, checks)
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
        one_process, one_env = "ceiling: 1 process", "make_vec async, 1 env"
        cases = [
            Case(one_process, "ceiling", "independent", 1, 1, one_process),
            Case("ceiling: 2 processes", "ceiling", "independent", 2, 2, one_process),
            Case("make_vec sync, 1 env", "make_vec", "sync", 1, 0, one_env),
            Case(one_env, "make_vec", "async", 1, 1, one_env),
            Case("make_vec async, 2 envs", "make_vec", "async", 2, 2, one_env),
        ]
        for k in self.arenas_per_worker:
            one_worker = f"batched 1 worker x {k} arenas"
            cases += [
                Case(f"batched in-process, {k} arenas", "batched", "in-process", k, 0, one_worker),
                Case(one_worker, "batched", "workers", k, 1, one_worker),
                Case(f"batched 2 workers x {k} arenas", "batched", "workers", 2 * k, 2, one_worker),
            ]
        return cases

    def recorded(self) -> dict[str, Any]:
        return {
            "repeats": self.size.rounds,
            "steps": self.size.steps,
            "arenas_per_worker": list(self.arenas_per_worker),
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
    """CPU seconds of this process so far (nanosecond clock: the parent's share of a vector step
    is a fraction of a millisecond)."""
    return time.process_time()


def batched_kwargs(episode_s: float) -> dict[str, Any]:
    """The arguments of every arena of the batched cases."""
    return {"preset": "dahl2004", "max_sim_time_s": episode_s}


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
            _, _, terminated, truncated, _ = envs.step(rng.integers(0, CIRCUITS, case.envs))
            resetting = terminated | truncated
        wall = time.perf_counter() - started
        cpu, workers_cpu = own_cpu_s() - cpu, process_cpu_s(pids) - workers_cpu
    finally:
        envs.close()
    return {"decisions": decisions, "wall_s": wall, "cpu_s": cpu, "workers_cpu_s": workers_cpu}


def _step_alone(
    connection: Connection, seed: int, index: int, steps: int, episode_s: float
) -> None:
    """One process of the ceiling: the single-robot view as one sub-env of `make_vec` builds and
    steps it (same env, same NEXT_STEP resets), alone; its loop starts at the parent's word."""
    env = gymnasium.make(GYM_ID, episode_s=episode_s)
    rng = np.random.default_rng([seed, 3, index])
    env.reset(seed=seed + index)
    connection.send("ready")
    connection.recv()
    decisions, resetting = 0, False
    cpu, started = own_cpu_s(), time.perf_counter()
    for _ in range(steps):
        if resetting:
            env.reset()
            resetting = False
            continue
        _, _, terminated, truncated, _ = env.step(int(rng.integers(0, CIRCUITS)))
        decisions += 1
        resetting = terminated or truncated
    ended = time.perf_counter()
    found = {"decisions": decisions, "started": started, "ended": ended, "cpu_s": own_cpu_s() - cpu}
    connection.send(found)
    env.close()


def time_ceiling(case: Case, seed: int, steps: int, episode_s: float) -> Row:
    """`steps` steps of the single-robot view in each of `case.workers` independent processes,
    started together; the wall time is from the first start to the last end (perf_counter is one
    clock for every process on Linux)."""
    context: Any = multiprocessing.get_context("fork")
    pipes, processes = [], []
    try:
        for index in range(case.workers):
            here, there = context.Pipe()
            process = context.Process(
                target=_step_alone, args=(there, seed, index, steps, episode_s), daemon=True
            )
            process.start()
            there.close()  # so that a process that dies is an EOFError here, not a hang
            pipes.append(here)
            processes.append(process)
        for here in pipes:
            here.recv()
        cpu = own_cpu_s()
        for here in pipes:
            here.send("go")
        found = [here.recv() for here in pipes]
        cpu = own_cpu_s() - cpu
    finally:
        for process in processes:
            process.join(timeout=30)
            if process.is_alive():
                process.kill()
    return {
        "decisions": sum(f["decisions"] for f in found),
        "wall_s": max(f["ended"] for f in found) - min(f["started"] for f in found),
        "cpu_s": cpu,
        "workers_cpu_s": sum(f["cpu_s"] for f in found),
    }


def time_batched(case: Case, seed: int, steps: int, episode_s: float) -> Row:
    """`steps` steps of the batched multi-agent view."""
    env_kwargs = batched_kwargs(episode_s)
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


# -- what one worker's step costs, in this process --------------------------------------------------
def cpu_per_call(call: Callable[[], object], calls: int) -> np.ndarray:
    """This thread's CPU seconds of each of `calls` calls of `call`: CPU, not wall, so that the
    time a busy machine keeps this process waiting for a core does not count."""
    costs = np.empty(calls)
    for i in range(calls):
        started = time.thread_time()
        call()
        costs[i] = time.thread_time() - started
    return costs


def slower_of_two(costs: np.ndarray) -> float:
    """E[max(X, Y)] / E[X] for X, Y drawn independently from `costs` (over every pair of distinct
    samples): how much longer a lock-step vector step waits for the slower of two workers than
    one worker's mean step takes."""
    x = np.sort(np.asarray(costs, float))
    n = len(x)
    pairs = n * (n - 1) / 2
    return float(x @ np.arange(n) / pairs / x.mean())  # the i-th smallest is the larger of i pairs


def step_costs(view: str, per_worker: int, seed: int, steps: int, episode_s: float) -> Row:
    """One worker's step, `steps` times in this process, as the 2-worker case of `view` makes
    it: a step of one single-robot env (`make_vec`), or of a group of `per_worker` arenas
    (`batched`, the work a worker does between two messages). Its CPU ms per step (mean), their
    coefficient of variation and `slower_of_two`."""
    rng = np.random.default_rng([seed, 4])
    if view == "make_vec":
        env = gymnasium.make(GYM_ID, episode_s=episode_s)
        env.reset(seed=seed)

        def step() -> None:
            _, _, terminated, truncated, _ = env.step(int(rng.integers(0, CIRCUITS)))
            if terminated or truncated:
                env.reset()

        costs = cpu_per_call(step, steps)
        env.close()
    else:
        group = ArenaGroup(parallel_env, batched_kwargs(episode_s), per_worker)
        arenas = np.random.SeedSequence(seed).spawn(per_worker)
        group.reset([int(arena.generate_state(1)[0]) for arena in arenas])
        n_circuits = group.envs[0].config.n_circuits
        moves = iter(rng.integers(0, n_circuits, (steps, per_worker, len(group.agents))))
        costs = cpu_per_call(lambda: group.step(next(moves)), steps)
        group.close()
    return {
        "view": view,
        "per_worker": per_worker,
        "cpu_ms": 1e3 * float(costs.mean()),
        "cv": float(costs.std() / costs.mean()),
        "slower_of_two": slower_of_two(costs),
    }


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
    group = ArenaGroup(parallel_env, batched_kwargs(episode_s), arenas)
    group.reset([0] * arenas)
    actions = np.zeros((arenas, len(group.agents)), np.int64)
    return {k: v for k, v in group.step(actions).items() if k != "final"}


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


TIMERS: dict[str, Callable[[Case, int, int, float], Row]] = {
    "ceiling": time_ceiling,
    "make_vec": time_make_vec,
    "batched": time_batched,
}


def judged(s: Settings) -> list[Case]:
    """The 2-worker cases of the two views: the goal's cases, each explained by `gap_model`."""
    return [case for case in s.cases if case.workers == 2 and case.view != "ceiling"]


def measure(s: Settings) -> tuple[list[Row], list[Row]]:
    """Every case once per round, in turn, after one untimed warm-up of each view; then, in the
    same round, `step_costs` of each 2-worker case's worker step. Returns both lists of rows."""
    size = s.size
    for view, mode in (("make_vec", "sync"), ("batched", "in-process")):  # imports, caches
        case = next(c for c in s.cases if (c.view, c.mode) == (view, mode))
        TIMERS[view](case, 0, 5, size.episode_s)
    rows: list[Row] = []
    costs: list[Row] = []
    started = time.perf_counter()
    for rep in range(size.rounds):
        for case in s.cases:
            waited, idle = wait_for_idle(size.idle_wait_s)
            load = os.getloadavg()[0]
            found = TIMERS[case.view](case, rep, size.steps, size.episode_s)
            found["decisions_per_s"] = found["decisions"] / found["wall_s"]
            rows.append(
                {
                    "case": case.name,
                    "view": case.view,
                    "mode": case.mode,
                    "envs": case.envs,
                    "workers": case.workers,
                    "repeat": rep,
                    "steps": size.steps,
                    "load_1min": load,
                    "idle_wait_s": waited,
                    "idle_share": idle,
                    **found,
                }
            )
        for case in judged(s):
            found = step_costs(case.view, case.per_worker, rep, size.steps, size.episode_s)
            costs.append({"repeat": rep, **found})
        print(f"round {rep + 1} done ({time.perf_counter() - started:.0f} s)", flush=True)
    return rows, costs


def by_round(rows: Sequence[Row], name: str) -> dict[int, Row]:
    return {r["repeat"]: r for r in rows if r["case"] == name}


def ratios(rows: Sequence[Row], case: Case) -> list[float]:
    """The case's decisions per second over its baseline's, paired by round."""
    mine, theirs = by_round(rows, case.name), by_round(rows, case.baseline)
    return [mine[k]["decisions_per_s"] / theirs[k]["decisions_per_s"] for k in sorted(mine)]


def ceiling_case(s: Settings) -> Case:
    return next(case for case in s.cases if case.view == "ceiling" and case.workers == 2)


def gap_model(rows: Sequence[Row], costs: Sequence[Row], case: Case, ceiling: Case) -> list[Row]:
    """Per round, the 2-worker `case`'s vector step predicted from measured parts, against the
    measured one (all per vector step, ms). The 2-worker step takes the 1-worker step `t1`
    (measured) plus: the worker step (`cpu_ms`, in-process) slowed by two processes sharing the
    machine as the ceiling of the round shows (x 2 / ceiling), the wait for the slower of the two
    workers (x `slower_of_two`), and the parent's extra CPU for the second worker (its CPU per
    vector step, 2 workers minus 1). Lock-step vector steps put all of these on the critical
    path. The predicted ratio is the decisions of the two cases over that predicted time."""
    one, two = by_round(rows, case.baseline), by_round(rows, case.name)
    alone, shared = by_round(rows, ceiling.baseline), by_round(rows, ceiling.name)
    found = []
    for rep in sorted(two):
        cost = next(
            c
            for c in costs
            if c["repeat"] == rep and (c["view"], c["per_worker"]) == (case.view, case.per_worker)
        )
        ceiling_ratio = shared[rep]["decisions_per_s"] / alone[rep]["decisions_per_s"]
        t1, t2 = (1e3 * r[rep]["wall_s"] / r[rep]["steps"] for r in (one, two))
        parent_1, parent_2 = (1e3 * r[rep]["cpu_s"] / r[rep]["steps"] for r in (one, two))
        slowed = cost["cpu_ms"] * 2 / ceiling_ratio
        extra = {
            "sharing_ms": slowed - cost["cpu_ms"],
            "lockstep_ms": slowed * (cost["slower_of_two"] - 1),
            "parent_ms": parent_2 - parent_1,
        }
        decisions = two[rep]["decisions"] / one[rep]["decisions"]
        predicted = decisions * t1 / (t1 + sum(extra.values()))
        measured = decisions * t1 / t2
        found.append(
            {
                "repeat": rep,
                "ceiling": ceiling_ratio,
                "worker_step_cpu_ms": cost["cpu_ms"],
                "cv": cost["cv"],
                "slower_of_two": cost["slower_of_two"],
                "one_worker_ms": t1,
                "one_worker_parent_ms": parent_1,
                "two_workers_ms": t2,
                "two_workers_parent_ms": parent_2,
                **extra,
                "predicted_ratio": predicted,
                "measured_ratio": measured,
                "predicted_share": predicted / ceiling_ratio,
                "measured_share": measured / ceiling_ratio,
            }
        )
    return found


def median_range(values: Sequence[float], digits: int) -> str:
    return f"{np.median(values):.{digits}f} [{min(values):.{digits}f}, {max(values):.{digits}f}]"


def medians(found: Sequence[Row]) -> Row:
    """The median over rounds of every field but the round."""
    return {key: float(np.median([f[key] for f in found])) for key in found[0] if key != "repeat"}


HEADER = [
    "case",
    "processes",
    "decisions / wall s",
    "ratio to 1 worker (ceiling: to 1 process)",
    "share of the ceiling",
    "wall s",
    "CPU s (this process + workers)",
    "cores busy (CPU s / wall s)",
    "CPU ms / decision",
    "load (1 min)",
    "idle at start",
    "goal",
]

GAP_HEADER = [
    "2-worker case",
    "worker step: CPU ms (CV), in-process",
    "slower of two / mean",
    "1 worker: wall ms / step (parent CPU ms)",
    "2 workers: wall ms / step (parent CPU ms)",
    "extra ms / step: sharing + lock-step + parent",
    "ratio: predicted, measured",
    "share of the ceiling: predicted, measured",
]


def gap_table(rows: Sequence[Row], costs: Sequence[Row], s: Settings) -> tuple[str, Row]:
    """The gap model's table (medians over rounds) and its figures by case, for the summary."""
    table, found = [], {}
    for case in judged(s):
        m = medians(gap_model(rows, costs, case, ceiling_case(s)))
        found[case.name] = m
        table.append(
            [
                case.name,
                f"{m['worker_step_cpu_ms']:.2f} ({m['cv']:.2f})",
                f"{m['slower_of_two']:.2f}",
                f"{m['one_worker_ms']:.2f} ({m['one_worker_parent_ms']:.2f})",
                f"{m['two_workers_ms']:.2f} ({m['two_workers_parent_ms']:.2f})",
                f"{m['sharing_ms']:.2f} + {m['lockstep_ms']:.2f} + {m['parent_ms']:.2f}",
                f"{m['predicted_ratio']:.2f}, {m['measured_ratio']:.2f}",
                f"{m['predicted_share']:.2f}, {m['measured_share']:.2f}",
            ]
        )
    return markdown_table(GAP_HEADER, table), found


def sched_autogroup() -> bool | None:
    """Whether the kernel schedules each session's processes as one group (Linux's autogroup:
    then a benchmark's workers share one session's slice of a busy machine); None if unknown."""
    try:
        with open("/proc/sys/kernel/sched_autogroup_enabled", encoding="ascii") as fh:
            return fh.read().strip() == "1"
    except OSError:
        return None


def transport_paragraph(found: Sequence[Row]) -> str:
    trips = "; ".join(
        f"{f['arenas']} arenas ({f['payload_bytes']:.0f} bytes): {f['pickled_us']:.0f} us pickled "
        f"through the pipe, {f['shared_memory_us']:.0f} us through shared memory with a one-byte "
        "answer"
        for f in found
    )
    return (
        "Transport of the batched view, a round trip (actions out, one step's arrays of one "
        f"worker's arenas back, copied out here): {trips} (median of blocks of 50 trips, echo "
        "worker); `BatchedArenaEnv` uses shared memory."
    )


GAP_TEXT = (
    "Where the gap to the ceiling comes from (medians over rounds, every figure measured in this "
    "run): a 2-worker vector step takes the 1-worker step plus three extras, each on the critical "
    "path because a vector step is lock-step. *Sharing*: one worker's step (its CPU ms measured "
    "in this process every round, for `make_vec` a step of one single-robot env, for the batched "
    "view a step of one worker's arenas) slowed by two processes sharing the machine as much as "
    "the ceiling of that round shows (x 2 / ceiling). *Lock-step*: the vector step waits for the "
    "slower of the two workers; 'slower of two / mean' is the expected larger of two independent "
    "step costs over their mean (from the in-process samples, whose coefficient of variation is "
    "the CV), so a noisy step costs more. *Parent*: this process's CPU per vector step with 2 "
    "workers minus with 1 (Gymnasium's async vector env unpickles every sub-env's result and "
    "merges its infos key by key; the batched view copies its shared block out). The predicted "
    "ratio is the 1-worker step over the predicted 2-worker step (times the two cases' decisions "
    "per step); a predicted ratio close to the measured one means these extras account for the "
    "gap, and the largest is what to shrink. With more arenas per worker the parent's and the "
    "pipes' cost is spread over more decisions, and a worker's step, a sum of more arena steps, "
    "varies less (compare the CVs); `make_vec` runs one sub-env per process and can do neither."
)


def build_report(
    rows: Sequence[Row],
    s: Settings,
    transport: Sequence[Row] | None = None,
    costs: Sequence[Row] | None = None,
) -> Report:
    table: list[list[str]] = []
    cases: dict[str, Any] = {}
    goal_cases = judged(s)
    ceiling = ratios(rows, ceiling_case(s))
    for case in s.cases:
        mine = [r for r in rows if r["case"] == case.name]
        speed = [r["decisions_per_s"] for r in mine]
        ratio = ratios(rows, case)
        verdict, share = "-", "-"
        found: dict[str, Any] = {}
        if case in goal_cases:  # the goal, for both views
            ok = float(np.median(ratio)) >= GOAL
            verdict = f"{'PASS' if ok else 'FAIL'} (>= {GOAL:g} x 1 worker)"
            shares = [r / c for r, c in zip(ratio, ceiling)]
            share = median_range(shares, 2)
            found = {"share_of_ceiling": float(np.median(shares)), "share_range": shares}
        cpu = [r["cpu_s"] + (r["workers_cpu_s"] if case.workers else 0.0) for r in mine]
        loads = [r["load_1min"] for r in mine]
        idle = sum(r.get("idle_share", 1.0) >= IDLE for r in mine)
        table.append(
            [
                case.name,
                f"1 + {case.workers}" if case.workers else "1",
                median_range(speed, 0),
                median_range(ratio, 2),
                share,
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
            **found,
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
            "*wall* second of the stepping loop (processes run side by side): for the ceiling and "
            f"`make_vec` one decision is a step of one single-robot env of `{GYM_ID}` (one of the "
            "learner's tasks, about six arena steps; NEXT_STEP reset steps not counted); for the "
            "batched view a robot whose action the step read (`must_decide`). The two views' "
            "figures are therefore not comparable with each other; the ratios are to the "
            "1-worker case of the same view and round (async 1 env; 1 worker). The *ceiling* is "
            "what this machine gives two processes: two independent processes, each stepping the "
            "single-robot view alone (the work of one `make_vec` sub-env, no pipes, no "
            "lock-step), over one such process; 'share of the ceiling' is a 2-worker ratio over "
            "the ceiling of the same round, the part of what the machine can give that the "
            "vectorisation gets. CPU s: this process plus its workers, over the timed loop. "
            f"Episodes of {s.size.episode_s:g} simulated s, `dahl2004`, random actions. 'cores "
            "busy' is CPU s over wall s: with 2 workers it is 2 on an idle 2-core machine. "
            f"'load' is the 1-minute load average before each case ({os.cpu_count()} cores): "
            "other work on the machine takes cores from the workers and shrinks the ratios, so "
            f"each case first waits up to {s.size.idle_wait_s:g} s for the cores to be idle (at "
            f"least {IDLE:.0%} of their time, three half-second windows in a row); 'idle at "
            "start' counts the rounds in which they were.",
            "",
            markdown_table(HEADER, table),
        ]
    )
    grouped = sched_autogroup()
    ceiling_found = {"ratio": float(np.median(ceiling)), "range": [min(ceiling), max(ceiling)]}
    summary: dict[str, Any] = {"cases": cases, "ceiling": ceiling_found, "sched_autogroup": grouped}
    if costs is not None:
        gaps, summary["gaps"] = gap_table(rows, costs, s)
        summary["step_costs"] = list(costs)  # every round's, for the medians above
        body += f"\n\n{GAP_TEXT}\n\n{gaps}"
    if grouped:
        body += (
            "\n\nThis kernel groups each session's processes for scheduling (sched_autogroup): "
            "on a machine busy with other sessions the benchmark's processes share one session's "
            "slice however many workers it starts, so 'cores busy' stays flat and the ratios "
            "near 1; they measure the workers' overhead, not their speed-up, unless the machine "
            "is otherwise idle (load well under the core count)."
        )
    if transport is not None:
        summary["transport"] = list(transport)
        body += "\n\n" + transport_paragraph(transport)
    return Report(
        "vector_throughput", "Vectorised views: decisions per second", body, list(rows), summary
    )


def run(settings: Settings) -> Outcome:
    """Measure every case, then write the report; the outcome names the goal if it was missed."""
    provenance = run_metadata(settings=settings.recorded())
    started = time.perf_counter()
    rows, costs = measure(settings)
    trips = 200 if settings.quick else 2000
    transport = [
        {"arenas": k, **transport_us(step_payload(k, settings.size.episode_s), trips)}
        for k in settings.arenas_per_worker
    ]
    provenance["wall_time_s"] = time.perf_counter() - started
    report = build_report(rows, settings, transport, costs)
    out = settings.out_dir()
    verdicts = {name: found["verdict"] for name, found in report.summary["cases"].items()}
    return Outcome(
        out,
        report.write(out, provenance),
        f"{report.body}\nwrote {out / 'vector_throughput.md'}",
        [f"{name}: {v}" for name, v in verdicts.items() if v.startswith("FAIL")],
    )


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
