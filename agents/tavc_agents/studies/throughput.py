"""Throughput of the arena by team size, next to the bare-physics floor: simulated seconds, ticks
and decisions per wall second of the PettingZoo env, and the share of the bare pymunk loop's speed
it reaches (`tavc_agents.experiments.measurement.random_choice_run`, `physics_floor`). Also the run
to profile (`ProfileSettings`, `profile_run`). The scripts are `benchmarks/throughput.py` and
`benchmarks/profile_env.py`.
"""

from __future__ import annotations

import math
import resource
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import tavc_env
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.measurement import physics_floor, random_choice_run
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.studies.common import RESULTS_DIR, Outcome, SweepOptions
from tavc_env.config import ArenaConfig

SIZES = {6: None, 24: 8, 96: 32, 384: 128}  # robots -> lanes of scaled_config (None: dahl2004)
SIM_HOURS = {6: 5.0, 24: 1.0, 96: 0.25, 384: 0.05}  # per repeat, about a second of wall each
GOALS = {6: 15_000.0, 96: 1_500.0}
FLOOR_GOAL = 0.30
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(SweepOptions):
    """The throughput benchmark's settings (its command line). Sizes run one at a time, each in a
    process of its own on one core, so `workers` can only be 1 and `backend` only local."""

    sizes: tuple[int, ...] = tuple(SIZES)
    """team sizes (robots), among 6, 24, 96, 384"""
    repeats: int = 5
    """repeats per size (>= 2, for intervals)"""
    dt: float | None = None
    """physics step (default: the package's)"""
    quick: bool = False
    """smoke run: 2 repeats, short runs"""

    def __post_init__(self) -> None:
        super().__post_init__()
        bad = [n for n in self.sizes if n not in SIZES]
        if bad or not self.sizes:
            raise ValueError(
                f"sizes = {list(self.sizes)!r} is invalid; allowed: one or more of {list(SIZES)}"
            )
        if not self.quick and (not isinstance(self.repeats, int) or self.repeats < 2):
            raise ValueError(
                f"repeats = {self.repeats!r} is invalid; allowed: >= 2 (for confidence intervals)"
            )
        if self.dt is not None:
            tavc_env.make_config("dahl2004", dt=self.dt)  # names a bad step
        if self.workers not in (None, 1) or self.backend != "local":
            raise ValueError(
                f"workers = {self.workers!r}, backend = {self.backend!r} is invalid; allowed: "
                "workers 1 and backend local (one size at a time, one core each)"
            )

    @property
    def repeat_count(self) -> int:
        return 2 if self.quick else self.repeats

    @property
    def hours_scale(self) -> float:
        return 0.05 if self.quick else 1.0

    def reference_dir(self) -> Path:
        return RESULTS_DIR

    def recorded(self) -> dict[str, Any]:
        return {"sizes": list(self.sizes), "repeats": self.repeat_count, "quick": self.quick}


def config_for(robots: int, dt: float | None = None) -> ArenaConfig:
    """`dahl2004` for 6 robots, `scaled_config(lanes, 3)` for more; with step `dt` if given."""
    lanes = SIZES[robots]
    config = tavc_env.make_config("dahl2004") if lanes is None else tavc_env.scaled_config(lanes, 3)
    return config if dt is None else config.replace(dt=dt)


def run_size(robots: int, repeats: int, hours_scale: float, dt: float | None = None) -> Row:
    """Everything for one team size (run in a process of its own): per repeat the env, then the
    two floors with as many ticks, and the process's peak memory."""
    config = config_for(robots, dt)
    sim_s = SIM_HOURS[robots] * 3600.0 * hours_scale
    random_choice_run(config, 10**6, min(sim_s, 600.0))  # untimed: imports, numba, caches
    rows: list[Row] = []
    for rep in range(repeats):
        env = random_choice_run(config, rep, sim_s)
        rows.append({"robots": robots, "repeat": rep, "mode": "env", **env})
        for mode, each in (("floor", False), ("floor_each_tick", True)):
            floor = physics_floor(config, rep, int(env["ticks"]), each)
            rows.append({"robots": robots, "repeat": rep, "mode": mode, **floor})
    for r in rows:
        r["sim_s_per_wall_s"] = r["sim_s"] / r["wall_s"]
        r["ticks_per_s"] = r["ticks"] / r["wall_s"]
        r["us_per_tick"] = 1e6 * r["wall_s"] / r["ticks"]
        r["decisions_per_s"] = r["decisions"] / r["wall_s"]
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    return {
        "robots": robots,
        "dt": config.dt,
        "arena_m": (config.width, config.height),
        "circuits": config.n_circuits,
        "rows": rows,
        "peak_rss_mib": peak_kib / 1024.0,
    }


def measure_sizes(s: Settings) -> list[Row]:
    """Each size in a fresh process of its own, one at a time: figures are per core, memory per
    size."""
    sizes: list[Row] = []
    started = time.perf_counter()
    for robots in s.sizes:
        with ProcessPoolExecutor(max_workers=1) as pool:
            job = pool.submit(run_size, robots, s.repeat_count, s.hours_scale, s.dt)
            sizes.append(job.result())
        print(f"{robots} robots done ({time.perf_counter() - started:.0f} s)", flush=True)
    return sizes


def size_findings(size: Row) -> tuple[list[Any], Row]:
    """One size's table row and JSON summary: speed, env / floor ratios, memory, goal."""
    n, rows = size["robots"], size["rows"]
    env = [r for r in rows if r["mode"] == "env"]
    floor = [r for r in rows if r["mode"] == "floor"]
    each = [r for r in rows if r["mode"] == "floor_each_tick"]
    speed = mean_ci([r["sim_s_per_wall_s"] for r in env])
    ratio = mean_ci([e["ticks_per_s"] / f["ticks_per_s"] for e, f in zip(env, floor)])
    ratio_each = mean_ci([e["ticks_per_s"] / f["ticks_per_s"] for e, f in zip(env, each)])
    goal = GOALS.get(n)
    verdict = "-"
    if goal is not None:
        ok = speed[0] >= goal and (n != 6 or ratio[0] >= FLOOR_GOAL)
        verdict = f"{'PASS' if ok else 'FAIL'} (>= {goal:,.0f}x" + (
            f", >= {FLOOR_GOAL:.0%} of floor)" if n == 6 else ")"
        )
    best = max(r["sim_s_per_wall_s"] for r in env)
    cells = [
        n,
        f"{size['arena_m'][0]:g} x {size['arena_m'][1]:g} m, {size['circuits']} circuits",
        fmt_ci(*speed[:3], 0),
        f"{best:,.0f}",
        fmt_ci(*mean_ci([r["us_per_tick"] for r in env])[:3], 1),
        fmt_ci(*mean_ci([r["decisions_per_s"] for r in env])[:3], 0),
        fmt_ci(*mean_ci([r["us_per_tick"] for r in floor])[:3], 1),
        fmt_ci(*ratio[:3], 3),
        fmt_ci(*ratio_each[:3], 3),
        f"{size['peak_rss_mib']:.0f}",
        verdict,
    ]
    summary = {
        "sim_s_per_wall_s": speed[0],
        "best_sim_s_per_wall_s": best,
        "ratio_to_floor": ratio[0],
        "ratio_to_floor_each_tick": ratio_each[0],
        "peak_rss_mib": size["peak_rss_mib"],
        "dt": size["dt"],
        "goal": goal,
        "verdict": verdict,
    }
    return cells, summary


HEADER = [
    "robots",
    "arena",
    "sim s / wall s",
    "best",
    "us / tick",
    "decisions / s",
    "floor us / tick",
    "env / floor",
    "env / floor (velocities each tick)",
    "peak MiB",
    "goal",
]


def build_report(sizes: Sequence[Row], s: Settings) -> Report:
    findings = [size_findings(size) for size in sizes]
    body = "\n".join(
        [
            f"Physics step dt = {sizes[0]['dt']:g} s; {s.repeat_count} repeats per size, mean "
            "[95 % CI] over repeats; one core, one size at a time, each in its own process. "
            "'env / floor' is the env's physics ticks per second over the bare pymunk loop's "
            "(same bodies, same run, paired by repeat): the share of the physics floor reached. "
            "Peak MiB is the size's process's maximum resident memory (Python, numpy, numba, "
            "pymunk included: about 150 MiB of it is the interpreter and libraries).",
            "",
            markdown_table(HEADER, [cells for cells, _ in findings]),
        ]
    )
    summary = {str(size["robots"]): found for size, (_, found) in zip(sizes, findings)}
    rows = [r for size in sizes for r in size["rows"]]
    return Report("throughput", "Throughput by team size", body, rows, summary)


def run(settings: Settings) -> Outcome:
    """Measure every size, then write the report."""
    out = settings.out_dir()
    provenance = run_metadata(settings=settings.recorded())
    started = time.perf_counter()
    sizes = measure_sizes(settings)
    provenance["wall_time_s"] = time.perf_counter() - started
    report = build_report(sizes, settings)
    written = report.write(out, provenance)
    return Outcome(out, written, f"{report.body}\nwrote {out / 'throughput.md'}")


# -- profiling ----------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class ProfileSettings:
    """The run to profile (its command line)."""

    hours: float = 2.0
    """simulated hours"""
    robots: int = 6
    """team size, among 6, 24, 96, 384"""
    seed: int = 0
    """env seed (the choices come from a Generator seeded [seed, 1])"""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.hours) and self.hours > 0):
            raise ValueError(f"hours = {self.hours!r} is invalid; allowed: > 0")
        if self.robots not in SIZES:
            raise ValueError(f"robots = {self.robots!r} is invalid; allowed: one of {list(SIZES)}")


def profile_run(settings: ProfileSettings) -> str:
    """One random-choice run of the env, as `run_size` times it; returns what it did."""
    found = random_choice_run(config_for(settings.robots), settings.seed, settings.hours * 3600.0)
    return (
        f"{found['sim_s'] / 3600:g} simulated h, {found['ticks']:.0f} ticks, "
        f"{found['decisions']:.0f} decisions in {found['wall_s']:.1f} s wall "
        f"({found['sim_s'] / found['wall_s']:,.0f}x real time)"
    )
