"""Throughput of the arena: simulated seconds, physics ticks and decisions per wall-clock second.

Preset `dahl2004`, every robot that must decide picks a circuit uniformly at random (seeded). Four
measurements per seed, interleaved so that background load hits them alike:

* `env`: the PettingZoo parallel env (`tavc_env.parallel_env(preset="dahl2004")`, event-driven
  stepping), actions for the robots whose info says `action_required`;
* `simulation`: the bare engine (`tavc_env.simulation.Simulation`: `choose` / `advance`);
* `pymunk_floor_once`: the physics floor: the same pymunk space (the package's `World`: four wall
  segments, six discs of the same radius and mass, same solver settings) with each disc's velocity
  set once to a constant (random direction, the robot's top speed) and `space.step(dt)` in a loop;
* `pymunk_floor_each_tick`: the same, but the six velocities are set again every tick (what the
  engine must do at least: the controller sets velocities each tick).

Also the cost of one call of the vectorised controller (`Navigator.command`) on arena states,
to show where a tick's time goes. Ratios are engine ticks/s divided by floor ticks/s.

    python benchmarks/throughput.py               # 3 seeds x 10 simulated h per mode, ~1 min
    python benchmarks/throughput.py --quick
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from _common import RESULTS_DIR, fmt_ci, markdown_table, mean_ci, run_metadata, write_results

import tavc_env
from tavc_env.navigation import COMPILED
from tavc_env.simulation import Simulation
from tavc_env.world import World

PRESET = "dahl2004"


def measure_env(seed: int, sim_s: float) -> dict[str, Any]:
    env = tavc_env.parallel_env(preset=PRESET, max_sim_time_s=sim_s, max_cycles=10**9)
    m = env.config.n_circuits
    rng = np.random.default_rng([seed, 1])
    _, infos = env.reset(seed=seed)
    steps = decisions = 0
    t0, c0 = time.perf_counter(), time.process_time()
    while env.agents:
        actions = {a: int(rng.integers(m)) for a in env.agents if infos[a]["action_required"]}
        decisions += len(actions)
        _, _, _, _, infos = env.step(actions)
        steps += 1
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "sim_s": env.sim.time_s,
        "ticks": env.sim.ticks,
        "decisions": decisions,
        "steps": steps,
    }


def measure_sim(seed: int, sim_s: float) -> dict[str, Any]:
    cfg = tavc_env.make_config(PRESET)
    sim = Simulation(cfg)
    sim.reset(np.random.default_rng(seed))
    rng = np.random.default_rng([seed, 1])
    m = cfg.n_circuits
    t0, c0 = time.perf_counter(), time.process_time()
    for i in range(cfg.n_robots):
        sim.choose(i, int(rng.integers(m)))
    decisions = cfg.n_robots
    steps = 0
    while sim.time_s < sim_s - 1e-9:
        out = sim.advance(min(600.0, sim_s - sim.time_s))
        steps += 1
        for c in out.completions:
            sim.choose(c.robot, int(rng.integers(m)))
            decisions += 1
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "sim_s": sim.time_s,
        "ticks": sim.ticks,
        "decisions": decisions,
        "steps": steps,
    }


def _floor_world(seed: int) -> tuple[World, np.ndarray, float]:
    cfg = tavc_env.make_config(PRESET)
    sim = Simulation(cfg)
    sim.reset(np.random.default_rng(seed))  # robots at the sinks, as at the start of a trial
    world = sim.world
    rng = np.random.default_rng([seed, 2])
    angle = rng.uniform(-math.pi, math.pi, cfg.n_robots)
    speed = np.array([r.speed for r in cfg.robots])
    vel = np.stack([speed * np.cos(angle), speed * np.sin(angle)], axis=1)
    return world, vel, cfg.dt


def measure_floor(seed: int, ticks: int, each_tick: bool) -> dict[str, Any]:
    world, vel, dt = _floor_world(seed)
    space = world.space
    world.set_velocities(vel)
    t0, c0 = time.perf_counter(), time.process_time()
    if each_tick:
        for _ in range(ticks):
            world.set_velocities(vel)
            space.step(dt)
    else:
        for _ in range(ticks):
            space.step(dt)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "sim_s": ticks * dt,
        "ticks": ticks,
        "decisions": 0,
        "steps": 0,
    }


def measure_navigator(seed: int, calls: int) -> dict[str, Any]:
    """Cost of the controller alone on states sampled from a short random run."""
    cfg = tavc_env.make_config(PRESET)
    sim = Simulation(cfg)
    sim.reset(np.random.default_rng(seed))
    rng = np.random.default_rng([seed, 3])
    for i in range(cfg.n_robots):
        sim.choose(i, int(rng.integers(cfg.n_circuits)))
    states = []
    for _ in range(20):
        out = sim.advance(30.0, stop_on_decision=False)
        for c in out.completions:
            sim.choose(c.robot, int(rng.integers(cfg.n_circuits)))
        t = sim.tasks
        states.append(
            (
                sim.positions(),
                sim.heading.copy(),
                t.target.copy(),
                t.moving.copy(),
                sim.speeds * sim.speed_factor,
                sim.world.in_space.copy(),
            )
        )
    nav = sim.nav
    t0, c0 = time.perf_counter(), time.process_time()
    for k in range(calls):
        nav.command(*states[k % len(states)])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "calls": calls}


def warm_up() -> None:
    """Run the engine briefly, untimed, so one-off costs (imports, loading or compiling the
    controller's numba code) stay out of the measurements."""
    measure_sim(10**6, 120.0)
    measure_env(10**6, 120.0)


def run_seed(seed: int, sim_s: float) -> list[dict[str, Any]]:
    warm_up()
    rows = []
    for mode, fn in (("env", measure_env), ("simulation", measure_sim)):
        r = fn(seed, sim_s)
        rows.append({"seed": seed, "mode": mode, **r})
    ticks = rows[-1]["ticks"]
    for mode, each in (("pymunk_floor_once", False), ("pymunk_floor_each_tick", True)):
        rows.append({"seed": seed, "mode": mode, **measure_floor(seed, ticks, each)})
    nav = measure_navigator(seed, max(2000, ticks // 4))
    rows.append(
        {
            "seed": seed,
            "mode": "navigator_command",
            "wall_s": nav["wall_s"],
            "cpu_s": nav["cpu_s"],
            "ticks": nav["calls"],
            "sim_s": nav["calls"] * 0.1,
            "decisions": 0,
            "steps": 0,
        }
    )
    for r in rows:
        w = r["wall_s"]
        r["sim_s_per_wall_s"] = r["sim_s"] / w
        r["ticks_per_s"] = r["ticks"] / w
        r["us_per_tick"] = 1e6 * w / r["ticks"]
        r["decisions_per_s"] = r["decisions"] / w
        r["ticks_per_cpu_s"] = r["ticks"] / r["cpu_s"]
        r["us_per_tick_cpu"] = 1e6 * r["cpu_s"] / r["ticks"]
        r["cpu_share"] = r["cpu_s"] / w  # < 1: the process waited for a core (machine load)
        r["steps_per_s"] = r["steps"] / w
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--seeds", type=int, default=3, help="repetitions (seeds 0..N-1); default 3")
    p.add_argument("--hours", type=float, default=10.0, help="simulated hours per engine run")
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        help="processes (default 1: figures are per core; 2 runs seeds concurrently)",
    )
    p.add_argument("--out", type=Path, default=RESULTS_DIR, help="output directory")
    p.add_argument("--quick", action="store_true", help="smoke run: 1 seed, 0.05 simulated h")
    args = p.parse_args(argv)
    if args.quick:
        args.seeds, args.hours = 1, 0.05
    args.workers = max(1, min(args.workers, 2, args.seeds))
    seeds = list(range(args.seeds))
    sim_s = args.hours * 3600.0

    wall0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    if args.workers == 1:
        for s in seeds:
            rows += run_seed(s, sim_s)
            print(f"seed {s} done ({time.perf_counter() - wall0:.0f} s)", flush=True)
    else:
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            for res in pool.map(run_seed, seeds, [sim_s] * len(seeds)):
                rows += res
    wall = time.perf_counter() - wall0

    modes = [
        "env",
        "simulation",
        "pymunk_floor_once",
        "pymunk_floor_each_tick",
        "navigator_command",
    ]
    keys = (
        "sim_s_per_wall_s",
        "ticks_per_s",
        "us_per_tick",
        "ticks_per_cpu_s",
        "us_per_tick_cpu",
        "decisions_per_s",
        "steps_per_s",
        "cpu_share",
    )
    stats: dict[str, dict[str, tuple[float, float, float, int]]] = {}
    best: dict[str, float] = {}
    for mode in modes:
        sel = [r for r in rows if r["mode"] == mode]
        stats[mode] = {k: mean_ci([r[k] for r in sel]) for k in keys}
        best[mode] = min(r["us_per_tick_cpu"] for r in sel)

    by = {(r["seed"], r["mode"]): r for r in rows}

    def per_seed_ratio(a: str, b: str, key: str) -> tuple[float, float, float, int]:
        # engine ticks per second over floor ticks per second, paired by seed (back to back)
        return mean_ci([by[(s, a)][key] / by[(s, b)][key] for s in seeds])

    pairs = [
        (a, b)
        for a in ("env", "simulation")
        for b in ("pymunk_floor_once", "pymunk_floor_each_tick")
    ] + [("env", "simulation")]
    ratios = {f"{a}/{b}": per_seed_ratio(a, b, "ticks_per_cpu_s") for a, b in pairs}
    ratios_wall = {f"{a}/{b}": per_seed_ratio(a, b, "ticks_per_s") for a, b in pairs}
    for r in rows:
        r["wall_s"] = round(r["wall_s"], 4)
        r["cpu_s"] = round(r["cpu_s"], 4)

    def cell(mode: str, key: str, digits: int = 0) -> str:
        m, lo, hi, _ = stats[mode][key]
        return fmt_ci(m, lo, hi, digits)

    engine = ("env", "simulation")
    table = markdown_table(
        [
            "mode",
            "sim s / wall s",
            "ticks / wall s",
            "us / tick (wall)",
            "us / tick (CPU)",
            "best us / tick (CPU)",
            "decisions / wall s",
            "env steps / wall s",
            "CPU share",
        ],
        [
            (
                f"`{mode}`",
                cell(mode, "sim_s_per_wall_s") if mode != "navigator_command" else "-",
                cell(mode, "ticks_per_s"),
                cell(mode, "us_per_tick", 1),
                cell(mode, "us_per_tick_cpu", 1),
                f"{best[mode]:.1f}",
                cell(mode, "decisions_per_s", 1) if mode in engine else "-",
                cell(mode, "steps_per_s", 1) if mode in engine else "-",
                cell(mode, "cpu_share", 2),
            )
            for mode in modes
        ],
    )
    ratio_table = markdown_table(
        ["ratio of ticks/s", "CPU time: mean [95% CI]", "wall time: mean [95% CI]"],
        [
            (k, fmt_ci(*ratios[k][:3], digits=3), fmt_ci(*ratios_wall[k][:3], digits=3))
            for k in ratios
        ],
    )
    env_sim = stats["env"]["sim_s_per_wall_s"][0]
    env_cpu = 3600 / (stats["env"]["ticks_per_cpu_s"][0] * 0.1)
    load = os.getloadavg() if hasattr(os, "getloadavg") else (math.nan,) * 3
    body = "\n".join(
        [
            "## What was measured",
            "",
            f"Preset `{PRESET}` (6 robots, dt = 0.1 s), uniformly random circuit choices, "
            f"{args.hours:g} simulated hours per engine run, seeds {seeds}, "
            f"{args.workers} process(es). The floors run as many ticks as the engine run of the "
            "same seed, on the package's own `World` (same space, walls, bodies, solver "
            "settings), placed as at reset, with random constant velocities at the robots' top "
            "speeds (the discs soon rest against walls, so wall contacts are included). "
            "`navigator_command` is one call of the controller alone, on 20 states sampled from "
            "a random run (its 'ticks' are calls). Mean over seeds with a Student-t 95% "
            "interval. Wall-clock figures depend on machine load (other processes shared this "
            "2-core machine); CPU-time figures (`time.process_time`) much less so, and 'CPU "
            "share' (CPU time / wall time, 1.0 = had a core to itself) shows how much the load "
            "hit each measurement. 'best' is the fastest seed. Ratios use CPU time (wall time "
            "beside them).",
            "",
            "## Results",
            "",
            table,
            "",
            ratio_table,
            "",
            f"One simulated hour takes about {3600 / env_sim:.1f} s of wall time through the env "
            f"in this run ({env_cpu:.1f} s of CPU time); a 15-hour trial about "
            f"{15 * 3600 / env_sim:.0f} s. Load average at the end of the run: "
            f"{load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 min) on "
            f"{os.cpu_count()} cores.",
            "",
            "Ratios of engine ticks/s to the floor are paired by seed (the floor runs right after "
            "the engine runs of the same seed). The gap between `pymunk_floor_each_tick` and "
            "`simulation` is the controller (`navigator_command`), reading positions back from "
            "pymunk, and the task bookkeeping; the gap between `simulation` and `env` is the "
            "PettingZoo adapter (observations, infos, rewards per step).",
        ]
    )
    summary = {
        "stats": {
            mode: {k: dict(zip(("mean", "low", "high", "n"), v)) for k, v in s.items()}
            for mode, s in stats.items()
        },
        "ratios_cpu_time": {
            k: dict(zip(("mean", "low", "high", "n"), v)) for k, v in ratios.items()
        },
        "ratios_wall_time": {
            k: dict(zip(("mean", "low", "high", "n"), v)) for k, v in ratios_wall.items()
        },
        "best_us_per_tick_cpu": best,
        "load_average_end": load,
    }
    meta = run_metadata(
        wall_time_s=wall,
        settings={
            "preset": PRESET,
            "hours": args.hours,
            "seeds": seeds,
            "workers": args.workers,
            "controller_compiled_with_numba": COMPILED,
        },
    )
    paths = write_results(
        args.out, "throughput", rows, body, meta, f"Throughput ({PRESET})", summary
    )
    print(table)
    print(ratio_table)
    print(f"wrote {paths['md']} ({wall:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
