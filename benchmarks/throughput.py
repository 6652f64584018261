"""Throughput of the arena at 6, 24, 96 and 384 robots, next to the bare-physics floor.

For each team size (`dahl2004` for 6 robots; `tavc_env.scaled_config(n_circuits, 3)` for 24, 96
and 384: 8, 32 and 128 lanes of three robots), in a fresh process of its own (so its peak memory
is its own), one core, every robot that must decide picking a circuit uniformly at random (seeded):

* `env`: the PettingZoo parallel env, event-driven stepping: simulated seconds, physics ticks and
  decisions per wall second;
* `floor`: the bare-physics floor in the same process: the package's `World` (same space, walls,
  bodies, solver settings) placed as at reset, each robot's velocity set once to its top speed in
  a random direction, then `space.step(dt)` in a loop, as many ticks as the env run made;
* `floor_each_tick`: the same with every velocity set again every tick (the least an engine with a
  controller must do).

The measurements of one size alternate (env, floors, env, floors, ...) `--repeats` times so load
hits them alike; reported are the means, the best repeat, the ratio env / floor (ticks per second,
paired by repeat), and the peak resident memory of the size's process. Goals (issue 5): 6 robots
at least 15 000x real time and 30 % of the floor; 96 robots at least 1 500x.

    python benchmarks/throughput.py                # ~2 min
    python benchmarks/throughput.py --dt 0.2 --out benchmarks/results/throughput_dt0.2
    python benchmarks/throughput.py --quick
"""

from __future__ import annotations

import argparse
import math
import resource
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from _common import RESULTS_DIR, fmt_ci, markdown_table, mean_ci, run_metadata, write_results

import tavc_env
from tavc_env.engine.simulation import Simulation

SIZES = {6: None, 24: 8, 96: 32, 384: 128}  # robots -> lanes of scaled_config (None: dahl2004)
SIM_HOURS = {6: 5.0, 24: 1.0, 96: 0.25, 384: 0.05}  # per repeat, about a second of wall each
GOALS = {6: 15_000.0, 96: 1_500.0}
FLOOR_GOAL = 0.30


def config_for(robots: int, dt: float | None = None) -> Any:
    lanes = SIZES[robots]
    config = tavc_env.make_config("dahl2004") if lanes is None else tavc_env.scaled_config(lanes, 3)
    return config if dt is None else config.replace(dt=dt)


def measure_env(config: Any, seed: int, sim_s: float) -> dict[str, float]:
    env = tavc_env.parallel_env(config=config, max_sim_time_s=sim_s, max_cycles=10**9)
    m = config.n_circuits
    rng = np.random.default_rng([seed, 1])
    _, infos = env.reset(seed=seed)
    decisions = 0
    t0 = time.perf_counter()
    while env.agents:
        actions = {a: int(rng.integers(m)) for a in env.agents if infos[a]["action_required"]}
        decisions += len(actions)
        _, _, _, _, infos = env.step(actions)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "sim_s": env.sim.time_s, "ticks": env.sim.ticks, "decisions": decisions}


def measure_floor(config: Any, seed: int, ticks: int, each_tick: bool) -> dict[str, float]:
    sim = Simulation(config)
    sim.reset(np.random.default_rng(seed))  # robots at the sinks, as at the start of a trial
    world = sim.world
    rng = np.random.default_rng([seed, 2])
    angle = rng.uniform(-math.pi, math.pi, config.n_robots)
    speed = np.array([r.speed for r in config.robots])
    velocity = np.stack([speed * np.cos(angle), speed * np.sin(angle)], axis=1)
    world.set_velocities(velocity)
    space, dt = world.space, config.dt
    t0 = time.perf_counter()
    if each_tick:
        for _ in range(ticks):
            world.set_velocities(velocity)
            space.step(dt)
    else:
        for _ in range(ticks):
            space.step(dt)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "sim_s": ticks * dt, "ticks": ticks, "decisions": 0}


def run_size(
    robots: int, repeats: int, hours_scale: float, dt: float | None = None
) -> dict[str, Any]:
    """Everything for one team size (run in its own process)."""
    config = config_for(robots, dt)
    sim_s = SIM_HOURS[robots] * 3600.0 * hours_scale
    measure_env(config, 10**6, min(sim_s, 600.0))  # untimed: imports, numba, caches
    rows = []
    for rep in range(repeats):
        env = measure_env(config, rep, sim_s)
        rows.append({"robots": robots, "repeat": rep, "mode": "env", **env})
        for mode, each in (("floor", False), ("floor_each_tick", True)):
            floor = measure_floor(config, rep, int(env["ticks"]), each)
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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=list(SIZES), choices=list(SIZES))
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--dt", type=float, default=None, help="physics step (default: the package's)")
    p.add_argument("--out", type=Path, default=RESULTS_DIR, help="output directory")
    p.add_argument("--quick", action="store_true", help="smoke run: 2 repeats, short runs")
    args = p.parse_args(argv)
    if args.quick:
        args.repeats = 2
    if args.repeats < 2:
        p.error(f"--repeats = {args.repeats}; allowed: >= 2 (for confidence intervals)")
    scale = 0.05 if args.quick else 1.0

    meta = run_metadata(
        settings={"sizes": args.sizes, "repeats": args.repeats, "quick": args.quick}
    )
    wall0 = time.perf_counter()
    sizes: list[dict[str, Any]] = []
    for robots in args.sizes:
        # one fresh process per size, one at a time: figures are per core, memory per size
        with ProcessPoolExecutor(max_workers=1) as pool:
            sizes.append(pool.submit(run_size, robots, args.repeats, scale, args.dt).result())
        print(f"{robots} robots done ({time.perf_counter() - wall0:.0f} s)", flush=True)
    meta["wall_time_s"] = time.perf_counter() - wall0

    rows = [r for s in sizes for r in s["rows"]]
    table_rows = []
    summary: dict[str, Any] = {}
    for s in sizes:
        n = s["robots"]
        mine = [r for r in s["rows"]]
        env = [r for r in mine if r["mode"] == "env"]
        floor = [r for r in mine if r["mode"] == "floor"]
        each = [r for r in mine if r["mode"] == "floor_each_tick"]
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
        table_rows.append(
            [
                n,
                f"{s['arena_m'][0]:g} x {s['arena_m'][1]:g} m, {s['circuits']} circuits",
                fmt_ci(*speed[:3], 0),
                f"{max(r['sim_s_per_wall_s'] for r in env):,.0f}",
                fmt_ci(*mean_ci([r["us_per_tick"] for r in env])[:3], 1),
                fmt_ci(*mean_ci([r["decisions_per_s"] for r in env])[:3], 0),
                fmt_ci(*mean_ci([r["us_per_tick"] for r in floor])[:3], 1),
                fmt_ci(*ratio[:3], 3),
                fmt_ci(*ratio_each[:3], 3),
                f"{s['peak_rss_mib']:.0f}",
                verdict,
            ]
        )
        summary[str(n)] = {
            "sim_s_per_wall_s": speed[0],
            "best_sim_s_per_wall_s": max(r["sim_s_per_wall_s"] for r in env),
            "ratio_to_floor": ratio[0],
            "ratio_to_floor_each_tick": ratio_each[0],
            "peak_rss_mib": s["peak_rss_mib"],
            "dt": s["dt"],
            "goal": goal,
            "verdict": verdict,
        }
    table = markdown_table(
        [
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
        ],
        table_rows,
    )
    body = "\n".join(
        [
            f"Physics step dt = {sizes[0]['dt']:g} s; {args.repeats} repeats per size, mean "
            "[95 % CI] over repeats; one core, one size at a time, each in its own process. "
            "'env / floor' is the env's physics ticks per second over the bare pymunk loop's "
            "(same bodies, same run, paired by repeat): the share of the physics floor reached. "
            "Peak MiB is the size's process's maximum resident memory (Python, numpy, numba, "
            "pymunk included: about 150 MiB of it is the interpreter and libraries).",
            "",
            table,
        ]
    )
    paths = write_results(
        args.out, "throughput", rows, body, meta, "Throughput by team size", summary
    )
    print(body)
    print(f"wrote {paths['md']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
