"""Throughput of the arena at 6, 24 and 96 robots (and 384), in CPU time, against three yardsticks
of the same physics.

Each case (`dahl2004` for 6 robots; `tavc_env.scaled_config(n_circuits, 3)` for 24, 96 and 384:
8, 32 and 128 lanes of three robots; event-driven stepping, and for `--fixed-sizes` one env step
every `--interval-s` simulated seconds) runs in a process of its own, every robot that must decide
picking a circuit uniformly at random (seeded):

* `env`: the PettingZoo parallel env: simulated seconds, ticks and decisions per CPU second;
* `compiled floor`: the env's own velocity commands of the same run, recorded, then replayed in a
  compiled loop through the very Chipmunk calls the env's compiled tick makes (batch velocity
  write, `cpSpaceStep`, batch position read), no Python per tick (it must end exactly where the
  env ended): what the physics alone costs, the floor the env can approach;
* `replay`: the env's own velocity commands of the same run, recorded, then set tick after tick
  on a bare pymunk world of the same bodies (it must end exactly where the env ended);
* `bare loop`: the same bodies (same radius, mass, dt, solver iterations, walls) placed as at
  reset, each velocity set once, then `space.step(dt)` as many ticks as the env ran.

Times are CPU seconds of the measuring process (`time.process_time`), so other processes on a
shared machine do not count; the cases take turns round after round (`--repeats`), and the
machine's load average is recorded with every row. By default (`--no-batched`: not), each round
also times `BatchedArenaEnv` with K = 16 `dahl2004` arenas in one process (robot decisions per
CPU second, beside the plain env's in the same round and process and the compiled tick loop's own
ceiling: decisions per CPU second spent inside `run_ticks`), and the same batch in 1 and 2 worker
processes (decisions per wall-clock second). Reported: speeds, env / replay and env / bare
loop and env / compiled floor (ticks per CPU second, paired by round), peak memory. Goal (issue
24): at 6 robots at least 0.95 of the bare loop and 0.5 of the replay; the exit status is 1 if it
is missed. Goals of issue 38 against the compiled floor (reported, not yet enforced): 6 robots
>= 0.45, 96 robots >= 0.5, 6 robots every 1 s >= 0.25; batched K = 16 >= 10,000 decisions per
CPU second, 2 workers >= 1.8x 1. Writes
`throughput.{csv,md,json}` into a new run folder under runs/ (git ignores it), `--out`, or with
`--update-reference` benchmarks/results/throughput/.

    python benchmarks/throughput.py                # ~3 min
    python benchmarks/throughput.py --dt 0.2 --sizes 6 96 --out benchmarks/results/throughput_dt0.2
    python benchmarks/throughput.py --quick

Throughput of the arena by team size against three yardsticks of the same physics, in CPU time.

For each case (a team size, event-driven or fixed-interval stepping) the PettingZoo env runs with
random choices (`arena_runs.random_choice_run`), and beside it, in the
same process and round:

* `compiled floor`: the env's own velocity commands of that run replayed in a compiled loop
  through the Chipmunk calls of the env's compiled tick (`compiled_floor`); exact like the replay;
* `floor`: a bare pymunk loop of the same bodies (the engine's `World`: same radius, mass, dt,
  solver iterations and walls), velocities set once (`physics_floor`);
* `replay`: the env's own velocity commands of that run, recorded and set tick after tick on a
  bare `World` (`physics_replay`); it must end exactly where the env ended.

Every figure is CPU seconds of the measuring process (`time.process_time`); each case runs in a
process of its own, and the cases take turns round after round, so load hits them alike; the
machine's load average is recorded with every row. The run to profile is `benchmarks/profile_env.py`'s.
"""

from __future__ import annotations

import os
import resource
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

import tavc_env
from arena_runs import TEAM_SIZES as SIZES
from arena_runs import random_choice_run
from arena_runs import team_config as config_for
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.study import Outcome, StudySettings, run_study
from tavc_env.adapters.batched import BatchedArenaEnv
from tavc_env.config import ArenaConfig
from tavc_env.measurement import (
    compiled_floor,
    compiled_loop_timer,
    physics_floor,
    physics_replay,
)

SIM_HOURS = {6: 5.0, 24: 1.0, 96: 0.25, 384: 0.05}  # per repeat, about a CPU second or less each
# Goals (issue 24): at 6 robots the public parallel API reaches 95 % of the bare loop's speed
# and half of its own replayed physics, in CPU time.
FLOOR_GOAL = 0.95
REPLAY_GOAL = 0.5
# Goals (issue 38) against the compiled physics floor, by case: reported, not yet enforced
COMPILED_GOALS = {"6": 0.45, "96": 0.5, "6 every 1 s": 0.25}
# Goals (issue 38) of the batched view: K = 16 arenas in one process, and 2 worker processes
BATCH_ARENAS = 16
BATCH_GOAL = 10_000  # robot decisions per CPU second in one process
WORKERS_GOAL = 1.8  # 2 worker processes over 1, wall-clock decisions per second
BATCH_STEPS = 400  # batched steps per round (about 6,400 decisions at K = 16)
BATCH_EPISODE_S = 3600.0  # each arena's episode (then same-step autoreset)
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The throughput benchmark's settings (its command line). Each case runs in a process of
    its own on one core, one at a time, so `workers` can only be 1 and `backend` only local."""

    reference: ClassVar = "throughput"
    quick_reference_apart: ClassVar = False
    recorded_fields: ClassVar = "sizes fixed_sizes interval_s repeats=repeat_count quick"

    sizes: tuple[int, ...] = (6, 24, 96)
    """team sizes (robots) with event-driven stepping, among 6, 24, 96, 384"""
    fixed_sizes: tuple[int, ...] = (6,)
    """team sizes also run with fixed-interval stepping (none: ())"""
    interval_s: float = 1.0
    """the fixed interval's simulated seconds per env step"""
    repeats: int = 5
    """rounds (>= 2, for intervals); each case runs once per round"""
    dt: float | None = None
    """physics step (default: the package's)"""
    quick: bool = False
    """smoke run: 2 rounds, short runs"""
    batched: bool = True
    """also time K = 16 batched arenas in one process and 1 vs 2 worker processes"""

    def __post_init__(self) -> None:
        super().__post_init__()
        bad = [n for n in (*self.sizes, *self.fixed_sizes) if n not in SIZES]
        if bad or not self.sizes:
            raise ValueError(
                f"sizes = {list(self.sizes)!r}, fixed_sizes = {list(self.fixed_sizes)!r} is "
                f"invalid; allowed: one or more sizes (and any fixed sizes) among {list(SIZES)}"
            )
        if not self.quick and (not isinstance(self.repeats, int) or self.repeats < 2):
            raise ValueError(
                f"repeats = {self.repeats!r} is invalid; allowed: >= 2 (for confidence intervals)"
            )
        if not (isinstance(self.interval_s, (int, float)) and self.interval_s > 0):
            raise ValueError(f"interval_s = {self.interval_s!r} is invalid; allowed: > 0 s")
        if self.dt is not None:
            tavc_env.make_config("dahl2004", dt=self.dt)  # names a bad step
        if self.workers not in (None, 1) or self.backend != "local":
            raise ValueError(
                f"workers = {self.workers!r}, backend = {self.backend!r} is invalid; allowed: "
                "workers 1 and backend local (one case at a time, one core each)"
            )

    @property
    def repeat_count(self) -> int:
        return 2 if self.quick else self.repeats

    @property
    def hours_scale(self) -> float:
        return 0.05 if self.quick else 1.0

    @property
    def cases(self) -> list[tuple[int, float | None]]:
        """(robots, fixed interval or None for event-driven stepping), in the order they run."""
        return [(n, None) for n in self.sizes] + [(n, self.interval_s) for n in self.fixed_sizes]


def case_name(robots: int, interval_s: float | None) -> str:
    return f"{robots}" if interval_s is None else f"{robots} every {interval_s:g} s"


def run_case(
    robots: int, interval_s: float | None, rep: int, hours_scale: float, dt: float | None
) -> list[Row]:
    """One round of one case (in the case's own process): the env (seed `rep`), its replay and
    the bare loop with as many ticks, each timed in this process's CPU seconds."""
    config = config_for(robots, dt)
    sim_s = SIM_HOURS[robots] * 3600.0 * hours_scale
    if rep == 0:  # untimed: imports, numba, caches
        random_choice_run(config, 10**6, min(sim_s, 600.0), interval_s)
    common = {"case": case_name(robots, interval_s), "robots": robots, "repeat": rep}
    rows: list[Row] = []
    # the recording run is untimed (an observer reads every tick); the timed run is the same run
    recorded = random_choice_run(config, rep, sim_s, interval_s, record=True)
    measures: list[tuple[str, Any]] = [
        ("env", lambda: random_choice_run(config, rep, sim_s, interval_s)),
        ("replay", lambda: physics_replay(config, recorded)),
        ("compiled", lambda: compiled_floor(config, recorded)),
        ("floor", lambda: physics_floor(config, rep, int(recorded["ticks"]), each_tick=False)),
    ]
    for mode, measure in measures:
        load = os.getloadavg()[0]
        found = measure()
        row = {**common, "mode": mode, "load_1min": load}
        row.update({k: v for k, v in found.items() if k not in ("start", "commands", "end")})
        rows.append(row)
    env = rows[0]
    # the compiled tick loop's own share of the same run: what the env would cost per tick if
    # nothing but the loop (physics, controller, task rules) cost anything
    with compiled_loop_timer() as spent:
        random_choice_run(config, rep, sim_s, interval_s)
    env["loop_cpu_s"] = spent[0]
    if (env["ticks"], env["decisions"]) != (recorded["ticks"], recorded["decisions"]):
        raise RuntimeError(f"{common['case']}: the timed run differs from the recorded one")
    env["loop_us_per_tick"] = 1e6 * env["loop_cpu_s"] / env["ticks"]
    for r in rows:
        r["sim_s_per_cpu_s"] = r["sim_s"] / r["cpu_s"]
        r["us_per_tick"] = 1e6 * r["cpu_s"] / r["ticks"]
        r["decisions_per_cpu_s"] = r.get("decisions", 0) / r["cpu_s"]
        r["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return rows


def batched_run(
    config: ArenaConfig, arenas: int, steps: int, seed: int, workers: int = 0
) -> dict[str, Any]:
    """`steps` steps of `BatchedArenaEnv` over `arenas` arenas of `config` (episodes of
    `BATCH_EPISODE_S`, same-step autoreset), every robot that must decide picking a circuit
    uniformly at random (seeded [seed, 2]): CPU seconds of this process, wall seconds, robot
    decisions. The CPU time of worker processes (`workers` > 0) is not this process's: compare
    those runs by wall time."""
    kwargs = {"config": config, "max_sim_time_s": BATCH_EPISODE_S, "max_cycles": 10**9}
    with BatchedArenaEnv(arenas, workers=workers, env_kwargs=kwargs) as batch:
        rng = np.random.default_rng([seed, 2])
        moves = rng.integers(0, config.n_circuits, (steps, arenas, config.n_robots))
        _, infos = batch.reset(seed=seed)
        deciding = infos["action_required"]
        decisions = 0
        cpu0, wall0 = time.process_time(), time.perf_counter()
        for actions in moves:
            decisions += int(deciding.sum())
            deciding = batch.step(actions).must_decide
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    return {"cpu_s": cpu, "wall_s": wall, "decisions": decisions}


def compiled_loop_cpu(config: ArenaConfig, arenas: int, steps: int, seed: int) -> float:
    """CPU seconds spent inside the compiled tick loop (`run_ticks`) in `batched_run`'s run of
    the same arguments: the loop's own cost, whatever the adapter around it costs (each call
    timed; the run is the same trajectory, so the decisions are the same)."""
    with compiled_loop_timer() as spent:
        batched_run(config, arenas, steps, seed)
    return spent[0]


def run_batched_case(rep: int, scale: float, dt: float | None) -> list[Row]:
    """One round of the batched case (in its own process): K = `BATCH_ARENAS` arenas of
    `dahl2004` in this process (seed `rep`), the plain env in the same round, and the compiled
    loop's own CPU time in the batch's run (its ceiling: decisions per CPU second if nothing but
    the loop cost anything)."""
    config = config_for(6, dt)
    steps = max(20, round(BATCH_STEPS * scale))
    if rep == 0:  # untimed: imports, numba, caches
        batched_run(config, BATCH_ARENAS, 20, 10**6)
    common = {"case": f"batched K={BATCH_ARENAS}", "robots": 6, "repeat": rep}
    load = os.getloadavg()[0]
    batch = batched_run(config, BATCH_ARENAS, steps, rep)
    loop_cpu_s = compiled_loop_cpu(config, BATCH_ARENAS, steps, rep)
    plain = random_choice_run(config, rep, SIM_HOURS[6] * 3600.0 * scale * 0.2)
    return [
        {**common, "mode": "batched", "load_1min": load, **batch, "loop_cpu_s": loop_cpu_s},
        {**common, "mode": "env", "load_1min": load, **{k: plain[k] for k in batch}},
    ]


def run_workers_round(rep: int, scale: float, dt: float | None) -> list[Row]:
    """One round of K = `BATCH_ARENAS` arenas in 1 and then 2 worker processes (wall time: the
    work is in the workers), with the machine's load before each."""
    config = config_for(6, dt)
    steps = max(20, round(BATCH_STEPS * scale))
    rows = []
    for workers in (1, 2):
        load = os.getloadavg()[0]
        found = batched_run(config, BATCH_ARENAS, steps, rep, workers=workers)
        rows.append(
            {"case": "workers", "mode": f"{workers} workers", "repeat": rep, "load_1min": load}
            | found
        )
    return rows


def measure_cases(s: Settings) -> list[Row]:
    """Every case in a process of its own, kept for all rounds; the cases take turns, one at a
    time, round after round."""
    rows: list[Row] = []
    started = time.perf_counter()
    with ExitStack() as stack:
        pools = [stack.enter_context(ProcessPoolExecutor(max_workers=1)) for _ in s.cases]
        batched = stack.enter_context(ProcessPoolExecutor(max_workers=1))
        for rep in range(s.repeat_count):
            for (robots, interval_s), pool in zip(s.cases, pools):
                job = pool.submit(run_case, robots, interval_s, rep, s.hours_scale, s.dt)
                rows.extend(job.result())
            if s.batched:
                rows.extend(batched.submit(run_batched_case, rep, s.hours_scale, s.dt).result())
                rows.extend(run_workers_round(rep, s.hours_scale, s.dt))
            print(f"round {rep + 1} done ({time.perf_counter() - started:.0f} s)", flush=True)
    return rows


def case_findings(rows: Sequence[Row], config: ArenaConfig) -> tuple[list[Any], Row]:
    """One case's table row and JSON summary: speeds and the env's share of both yardsticks
    (ticks per CPU second, paired by round)."""
    modes = ("env", "replay", "floor", "compiled")
    by_mode = {m: [r for r in rows if r["mode"] == m] for m in modes}
    env, replay, floor = by_mode["env"], by_mode["replay"], by_mode["floor"]
    cfloor = by_mode["compiled"]
    speed = mean_ci([r["sim_s_per_cpu_s"] for r in env])
    to_floor = mean_ci([f["us_per_tick"] / e["us_per_tick"] for e, f in zip(env, floor)])
    to_replay = mean_ci([p["us_per_tick"] / e["us_per_tick"] for e, p in zip(env, replay)])
    to_compiled = mean_ci([c["us_per_tick"] / e["us_per_tick"] for e, c in zip(env, cfloor)])
    loop = mean_ci([e["loop_us_per_tick"] for e in env])
    loop_ceiling = mean_ci([c["us_per_tick"] / e["loop_us_per_tick"] for e, c in zip(env, cfloor)])
    exact = all(r["exact"] for r in replay + cfloor)
    name = env[0]["case"]
    verdict = "-"
    if name == "6":
        ok = to_floor[0] >= FLOOR_GOAL and to_replay[0] >= REPLAY_GOAL and exact
        verdict = (
            f"{'PASS' if ok else 'FAIL'} (>= {FLOOR_GOAL:g} of the bare loop, "
            f">= {REPLAY_GOAL:g} of the replay)"
        )
    goal38 = COMPILED_GOALS.get(name)
    verdict38 = "-"
    if goal38 is not None:
        verdict38 = f"{'met' if to_compiled[0] >= goal38 else 'not yet'} (>= {goal38:g})"
    loads = [r["load_1min"] for r in rows]
    cells = [
        name,
        f"{config.width:g} x {config.height:g} m, {config.n_circuits} circuits",
        fmt_ci(*speed[:3], 0),
        fmt_ci(*mean_ci([r["us_per_tick"] for r in env])[:3], 1),
        fmt_ci(*mean_ci([r["decisions_per_cpu_s"] for r in env])[:3], 0),
        fmt_ci(*mean_ci([r["us_per_tick"] for r in replay])[:3], 1),
        fmt_ci(*mean_ci([r["us_per_tick"] for r in floor])[:3], 1),
        fmt_ci(*mean_ci([r["us_per_tick"] for r in cfloor])[:3], 2),
        fmt_ci(*to_compiled[:3], 3),
        verdict38,
        fmt_ci(*loop[:3], 2),
        fmt_ci(*loop_ceiling[:3], 3),
        fmt_ci(*to_replay[:3], 3),
        fmt_ci(*to_floor[:3], 3),
        "yes" if exact else "NO",
        f"{min(loads):.1f}-{max(loads):.1f}",
        f"{max(r['peak_rss_mib'] for r in rows):.0f}",
        verdict,
    ]
    summary = {
        "sim_s_per_cpu_s": speed[0],
        "us_per_tick": mean_ci([r["us_per_tick"] for r in env])[0],
        "ratio_to_replay": to_replay[0],
        "ratio_to_floor": to_floor[0],
        "ratio_to_compiled_floor": to_compiled[0],
        "ratio_to_compiled_floor_ci": [to_compiled[1], to_compiled[2]],
        "compiled_floor_us_per_tick": mean_ci([r["us_per_tick"] for r in cfloor])[0],
        "compiled_goal": verdict38,
        "loop_us_per_tick": loop[0],
        "loop_ceiling_to_compiled_floor": loop_ceiling[0],
        "loop_ceiling_to_compiled_floor_ci": [loop_ceiling[1], loop_ceiling[2]],
        "replay_exact": exact,
        "load_1min": [min(loads), max(loads)],
        "arena_m": [config.width, config.height],
        "dt": config.dt,
        "verdict": verdict,
    }
    return cells, summary


HEADER = [
    "case (robots)",
    "arena",
    "sim s / CPU s",
    "us / tick",
    "decisions / CPU s",
    "replay us / tick",
    "bare loop us / tick",
    "compiled floor us / tick",
    "env / compiled floor",
    "compiled-floor goal (issue 38)",
    "compiled loop us / tick",
    "ceiling: compiled floor / loop",
    "env / replay",
    "env / bare loop",
    "replays exact",
    "load (1 min)",
    "peak MiB",
    "goal",
]


def batched_findings(rows: Sequence[Row]) -> tuple[str, Row]:
    """The batched case's paragraph and tables, and its JSON summary: robot decisions per CPU
    second of K arenas in one process, of the plain env in the same rounds and of the compiled
    loop alone (the ceiling), paired by round; 1 vs 2 worker processes by wall time."""
    case = f"batched K={BATCH_ARENAS}"
    batch = [r for r in rows if r["case"] == case and r["mode"] == "batched"]
    env = [r for r in rows if r["case"] == case and r["mode"] == "env"]
    speed = mean_ci([r["decisions"] / r["cpu_s"] for r in batch])
    plain = mean_ci([r["decisions"] / r["cpu_s"] for r in env])
    ceiling = mean_ci([r["decisions"] / r["loop_cpu_s"] for r in batch])
    to_plain = mean_ci(
        [b["decisions"] / b["cpu_s"] / (e["decisions"] / e["cpu_s"]) for b, e in zip(batch, env)]
    )
    to_ceiling = mean_ci([r["loop_cpu_s"] / r["cpu_s"] for r in batch])
    one = [r for r in rows if r["case"] == "workers" and r["mode"] == "1 workers"]
    two = [r for r in rows if r["case"] == "workers" and r["mode"] == "2 workers"]
    wall_one = mean_ci([r["decisions"] / r["wall_s"] for r in one])
    wall_two = mean_ci([r["decisions"] / r["wall_s"] for r in two])
    scaling = mean_ci([a["wall_s"] / b["wall_s"] for a, b in zip(one, two)])
    loads = [r["load_1min"] for r in batch]
    worker_loads = [r["load_1min"] for r in one + two]
    goal = f"{'met' if speed[0] >= BATCH_GOAL else 'not met'} (>= {BATCH_GOAL:,})"
    workers_goal = f"{'met' if scaling[0] >= WORKERS_GOAL else 'not met'} (>= {WORKERS_GOAL:g})"
    text = "\n".join(
        [
            f"**Batched arenas** (`BatchedArenaEnv`, K = {BATCH_ARENAS} `dahl2004` arenas, "
            f"episodes of {BATCH_EPISODE_S:g} s with same-step autoreset, random choices): robot "
            "decisions per CPU second of the batch in one process (`workers=0`), of the plain "
            "env in the same rounds and process, and of the compiled tick loop alone (`run_ticks`, "
            "each call timed in a second run of the same trajectory: the ceiling the batch can "
            "approach while each decision needs that many ticks). Then the same batch in 1 and in 2 "
            "worker processes, decisions per wall-clock second (the work is in the workers; on 2 "
            "cores shared with other jobs, the load says how idle they were).",
            "",
            markdown_table(
                [
                    "case",
                    "decisions / CPU s",
                    "plain env decisions / CPU s",
                    "batch / plain env",
                    "compiled loop ceiling, decisions / CPU s",
                    "batch / ceiling",
                    "goal (issue 38)",
                    "load (1 min)",
                ],
                [
                    [
                        case,
                        fmt_ci(*speed[:3], 0),
                        fmt_ci(*plain[:3], 0),
                        fmt_ci(*to_plain[:3], 2),
                        fmt_ci(*ceiling[:3], 0),
                        fmt_ci(*to_ceiling[:3], 2),
                        goal,
                        f"{min(loads):.1f}-{max(loads):.1f}",
                    ]
                ],
            ),
            "",
            markdown_table(
                [
                    "case",
                    "1 worker, decisions / wall s",
                    "2 workers, decisions / wall s",
                    "2 over 1",
                    "goal (issue 38)",
                    "load (1 min)",
                ],
                [
                    [
                        f"K={BATCH_ARENAS} in workers",
                        fmt_ci(*wall_one[:3], 0),
                        fmt_ci(*wall_two[:3], 0),
                        fmt_ci(*scaling[:3], 2),
                        workers_goal,
                        f"{min(worker_loads):.1f}-{max(worker_loads):.1f}",
                    ]
                ],
            ),
        ]
    )
    summary = {
        "arenas": BATCH_ARENAS,
        "decisions_per_cpu_s": speed[0],
        "decisions_per_cpu_s_ci": [speed[1], speed[2]],
        "plain_env_decisions_per_cpu_s": plain[0],
        "ratio_to_plain_env": to_plain[0],
        "ceiling_decisions_per_cpu_s": ceiling[0],
        "ratio_to_ceiling": to_ceiling[0],
        "ratio_to_ceiling_ci": [to_ceiling[1], to_ceiling[2]],
        "goal": goal,
        "workers_2_over_1": scaling[0],
        "workers_2_over_1_ci": [scaling[1], scaling[2]],
        "workers_goal": workers_goal,
        "load_1min": [min(loads + worker_loads), max(loads + worker_loads)],
    }
    return text, summary


def build_report(rows: Sequence[Row], s: Settings) -> Report:
    names = [case_name(n, i) for n, i in s.cases]
    found = {
        name: case_findings([r for r in rows if r["case"] == name], config_for(n, s.dt))
        for name, (n, _) in zip(names, s.cases)
    }
    dt = config_for(6, s.dt).dt
    body = "\n".join(
        [
            f"Physics step dt = {dt:g} s; {s.repeat_count} rounds, mean [95 % CI] over rounds. "
            "All times are CPU seconds of the measuring process; each case runs in a process of "
            "its own and the cases take turns, round after round; 'load' is the machine's 1-minute "
            "load average at the measurements (2 cores). 'env' is the public PettingZoo parallel "
            "API, every deciding robot choosing at random (event-driven stepping, or one step "
            f"every {s.interval_s:g} simulated s for 'every'). 'replay': the env's own velocity "
            "commands of the same run set tick after tick on a bare pymunk world of the same "
            "bodies (it must end exactly where the env ended: 'replays exact'). 'compiled floor': "
            "the same commands replayed in a compiled loop through the Chipmunk calls the env's "
            "compiled tick makes (batch velocity write, cpSpaceStep, batch position read), no "
            "Python per tick: the physics alone, the floor the env can approach (exact too). "
            "'bare loop': the "
            "same bodies with velocities set once, pymunk stepping alone (its discs keep hitting "
            "walls, which costs more than the env's free driving). 'env / replay' and "
            "'env / bare loop' and 'env / compiled floor' are ticks per CPU second, env over "
            "yardstick, paired by round. 'compiled loop': the CPU time spent inside the compiled "
            "tick loop (`run_ticks`: physics, controller, task rules) in a second run of the same "
            "trajectory, per tick; 'ceiling' is the compiled floor over it, what 'env / compiled "
            "floor' would be if the Python around the loop (the PettingZoo API, decisions, "
            "rewards, observations, infos) cost nothing. "
            "Peak MiB is the case's process's maximum resident memory.",
            "",
            markdown_table(HEADER, [cells for cells, _ in found.values()]),
        ]
    )
    summary = {name: summary for name, (_, summary) in found.items()}
    if s.batched:
        batched, summary["batched"] = batched_findings(rows)
        body += "\n\n" + batched
    return Report("throughput", "Throughput against its own physics", body, list(rows), summary)


def run(settings: Settings) -> Outcome:
    """Measure every case, then write the report."""
    out = settings.out_dir()
    provenance = run_metadata(settings=settings.recorded())
    started = time.perf_counter()
    rows = measure_cases(settings)
    provenance["wall_time_s"] = time.perf_counter() - started
    report = build_report(rows, settings)
    written = report.write(out, provenance)
    failed = [
        f"FAIL: {name} robots: {found['verdict']}"
        for name, found in report.summary.items()
        if name != "batched" and (found["verdict"].startswith("FAIL") or not found["replay_exact"])
    ]
    return Outcome(out, written, f"{report.body}\nwrote {out / 'throughput.md'}", failed)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
