"""Long-run health of the arena: many simulated hours of `dahl2004` with random circuit choices.

Drives the PettingZoo env (`tavc_env.parallel_env(preset="dahl2004")`, event-driven stepping) with
uniformly random circuit choices for every robot that must decide (seeded), and records every task
completion. Reports, per robot, the number of tasks and the longest gap between two completions
(also counting the start of the run to the first completion and the last completion to the end),
where and when it happened; the number of steps that hit the step cap (a step that returns with
nobody deciding); the minimum centre-to-centre distance between robots and the minimum robot-wall
clearance, sampled after every physics tick; and the wall time.

Exits with status 1 if any robot's longest gap exceeds `--max-gap-min` (default 30 simulated
minutes): a robot that stops completing tasks is a jam or a stuck robot.

Writes `long_run.{csv,md,json}` (per robot summary) and `long_run_tasks_seed<S>.csv` (every
completion, written as the run goes) into `--out`. Seeds run through the package's sweep runner
(`--workers`, `--backend local|ray`) and are kept in `--out`/cache/, so a rerun resumes.

    python benchmarks/long_run.py                 # 15 simulated hours, seeds 0-3 (~1-2 min wall)
    python benchmarks/long_run.py --quick         # smoke run
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from _common import (
    RESULTS_DIR,
    CsvAppender,
    add_sweep_options,
    fmt_ci,
    markdown_table,
    run_metadata,
    write_results,
)

import tavc_env
from agents.experiments.sweep import json_jobs, run_jobs
from tavc_env.engine.navigation import STUCK_PATIENCE_S
from tavc_env.engine.tasks import PHASE_NAMES, Mode, Phase

MODE_NAMES = {int(m): m.name.lower() for m in Mode}


class TickMonitor:
    """Wraps one World's `step` to sample robot spacing after every physics tick."""

    def __init__(self, sim: Any) -> None:
        self.sim = sim
        world = sim.world
        self.world = world
        self.radius = world.config.robot_radius
        self.width = world.config.width
        self.height = world.config.height
        self.bodies = world.bodies
        n = len(self.bodies)
        self.iu = np.triu_indices(n, 1)
        self.ticks = 0
        self.min_dist = math.inf
        self.min_dist_at: dict[str, Any] = {}
        self.min_wall = math.inf
        self.min_wall_at: dict[str, Any] = {}
        self.overlap_ticks = 0  # ticks with some pair deeper than 1 cm into each other
        self._orig_step = world.step
        world.step = self._step

    def _step(self, dt: float) -> None:
        self._orig_step(dt)
        self.ticks += 1
        present = self.world.in_space
        pos = np.array([tuple(b.position) for b in self.bodies])
        d = pos[:, None, :] - pos[None, :, :]
        dist = np.hypot(d[..., 0], d[..., 1])[self.iu]
        both = (present[:, None] & present[None, :])[self.iu]
        dist = np.where(both, dist, np.inf)
        k = int(np.argmin(dist))
        dmin = float(dist[k])
        if dmin < 2 * self.radius - 0.01:
            self.overlap_ticks += 1
        if dmin < self.min_dist:
            self.min_dist = dmin
            i, j = int(self.iu[0][k]), int(self.iu[1][k])
            self.min_dist_at = {
                "time_s": round(self.ticks * dt, 1),
                "pair": (i, j),
                "where": tuple(round(v, 2) for v in (pos[i] + pos[j]) / 2),
            }
        x, y = pos[present, 0], pos[present, 1]
        clear = np.minimum(np.minimum(x, self.width - x), np.minimum(y, self.height - y))
        c = float(clear.min()) - self.radius if clear.size else math.inf
        if c < self.min_wall:
            self.min_wall = c
            self.min_wall_at = {"time_s": round(self.ticks * dt, 1)}


@dataclass(frozen=True)
class LongRun:
    seed: int
    hours: float
    out_dir: str
    quiet: bool = True


def run_long(job: LongRun) -> dict[str, Any]:
    """One seed's run as JSON data (what the sweep runner saves)."""
    result: dict[str, Any] = json.loads(
        json.dumps(run_seed(job.seed, job.hours, job.out_dir, job.quiet), default=float)
    )
    return result


RUNS = json_jobs(run_long, lambda job: f"seed{job.seed}_{job.hours:g}h", unit="seed")


def run_seed(seed: int, hours: float, out_dir: str, quiet: bool) -> dict[str, Any]:
    env = tavc_env.parallel_env(preset="dahl2004", max_sim_time_s=hours * 3600.0, max_cycles=10**9)
    n = env.config.n_robots
    m = env.config.n_circuits
    classes = [r.speed_class for r in env.config.robots]
    rng = np.random.default_rng([seed, 1])  # action stream, separate from the env's seed
    _, infos = env.reset(seed=seed)
    monitor = TickMonitor(env.sim)
    tasks_log = CsvAppender(
        Path(out_dir) / f"long_run_tasks_seed{seed}.csv",
        ["seed", "robot", "speed_class", "circuit", "task_time_s", "time_s"],
    )
    completions: list[list[tuple[float, int, float]]] = [[] for _ in range(n)]
    # A light trace for "where was it": per step the time, positions, phase and mode of everyone.
    trace_t: list[float] = [0.0]
    trace_pos: list[np.ndarray] = [env.sim.positions()]
    trace_phase: list[np.ndarray] = [env.sim.tasks.phase.copy()]
    trace_mode: list[np.ndarray] = [env.sim.tasks.mode.copy()]
    steps = 0
    capped_steps: list[float] = []
    next_report = 3600.0
    wall0 = time.perf_counter()
    while env.agents:
        actions = {a: int(rng.integers(m)) for a in env.agents if infos[a]["action_required"]}
        _, _, _, truncs, infos = env.step(actions)
        steps += 1
        now = env.sim.time_s
        trace_t.append(now)
        trace_pos.append(env.sim.positions())
        trace_phase.append(env.sim.tasks.phase.copy())
        trace_mode.append(env.sim.tasks.mode.copy())
        truncated = any(truncs.values())
        deciding = False
        for a, info in infos.items():
            i = int(a.split("_")[1])
            if info["task_time_s"] is not None:
                completions[i].append((now, info["circuit"], info["task_time_s"]))
                tasks_log.write(
                    {
                        "seed": seed,
                        "robot": i,
                        "speed_class": classes[i],
                        "circuit": info["circuit"],
                        "task_time_s": round(info["task_time_s"], 3),
                        "time_s": round(now, 3),
                    }
                )
            deciding |= info["action_required"]
        if not deciding and not truncated:
            capped_steps.append(now)
        if not quiet and now >= next_report:
            done = sum(len(c) for c in completions)
            print(
                f"[seed {seed}] {now / 3600:.1f} h simulated, {done} tasks, "
                f"{time.perf_counter() - wall0:.0f} s wall",
                flush=True,
            )
            next_report += 3600.0
    wall = time.perf_counter() - wall0
    tasks_log.close()
    end = env.sim.time_s
    t_arr = np.array(trace_t)

    def where(i: int, t: float) -> dict[str, Any]:
        k = int(np.clip(np.searchsorted(t_arr, t), 0, len(t_arr) - 1))
        p = trace_pos[k][i]
        return {
            "x": round(float(p[0]), 2),
            "y": round(float(p[1]), 2),
            "phase": PHASE_NAMES[Phase(int(trace_phase[k][i]))],
            "mode": MODE_NAMES[int(trace_mode[k][i])],
        }

    robots = []
    for i in range(n):
        times = [0.0] + [c[0] for c in completions[i]] + [end]
        gaps = np.diff(times)
        k = int(np.argmax(gaps))
        t0, t1 = times[k], times[k + 1]
        kind = (
            "start->first"
            if k == 0
            else "last->end"
            if k == len(gaps) - 1
            else "between completions"
        )
        circuit = completions[i][k][1] if k < len(completions[i]) else None
        mid = where(i, (t0 + t1) / 2)
        tt = np.array([c[2] for c in completions[i]])
        circ = np.array([c[1] for c in completions[i]], dtype=int)
        robots.append(
            {
                "seed": seed,
                "robot": i,
                "speed_class": classes[i],
                "tasks": len(completions[i]),
                "tasks_c0": int((circ == 0).sum()),
                "tasks_c1": int((circ == 1).sum()),
                "mean_task_time_s": float(tt.mean()) if tt.size else math.nan,
                "max_task_time_s": float(tt.max()) if tt.size else math.nan,
                "longest_gap_s": float(gaps[k]),
                "gap_from_s": float(t0),
                "gap_to_s": float(t1),
                "gap_kind": kind,
                "gap_task_circuit": circuit,
                "gap_mid_x": mid["x"],
                "gap_mid_y": mid["y"],
                "gap_mid_phase": mid["phase"],
                "gap_mid_mode": mid["mode"],
            }
        )
    return {
        "seed": seed,
        "robots": robots,
        "sim_time_s": end,
        "steps": steps,
        "ticks": env.sim.ticks,
        "capped_steps": len(capped_steps),
        "escapes": env.sim.escapes,
        "capped_at_s": capped_steps[:20],
        "wall_s": wall,
        "min_dist_m": monitor.min_dist,
        "min_dist_at": monitor.min_dist_at,
        "overlap_ticks": monitor.overlap_ticks,
        "monitored_ticks": monitor.ticks,
        "min_wall_clearance_m": monitor.min_wall,
        "min_wall_at": monitor.min_wall_at,
        "diameter_m": 2 * env.config.robot_radius,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--seeds", type=int, default=4, help="number of seeds (seed0..); default 4")
    p.add_argument("--seed0", type=int, default=0, help="first seed (default 0)")
    p.add_argument("--hours", type=float, default=15.0, help="simulated hours per seed")
    add_sweep_options(p)
    p.add_argument("--max-gap-min", type=float, default=30.0, help="fail above this gap (min)")
    p.add_argument("--out", type=Path, default=RESULTS_DIR, help="output directory")
    p.add_argument("--quick", action="store_true", help="smoke run: 0.25 h, 1 seed")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    if args.quick:
        args.hours, args.seeds = 0.25, 1
    seeds = list(range(args.seed0, args.seed0 + args.seeds))
    max_gap_s = args.max_gap_min * 60.0
    args.out.mkdir(parents=True, exist_ok=True)

    wall0 = time.perf_counter()
    done = run_jobs(
        [LongRun(seed, args.hours, str(args.out), args.quiet) for seed in seeds],
        RUNS,
        args.out / "cache" / "long_run",
        workers=args.workers,
        progress_bar=not args.quiet,
        backend=args.backend,
    )
    results = [done[f"seed{seed}_{args.hours:g}h"] for seed in seeds]
    wall = time.perf_counter() - wall0

    rows = [r for res in results for r in res["robots"]]
    worst = max(rows, key=lambda r: r["longest_gap_s"])
    failed = [r for r in rows if r["longest_gap_s"] > max_gap_s]
    total_capped = sum(res["capped_steps"] for res in results)
    min_dist = min(res["min_dist_m"] for res in results)
    min_wall = min(res["min_wall_clearance_m"] for res in results)
    overlap_ticks = sum(res["overlap_ticks"] for res in results)
    diameter = results[0]["diameter_m"]

    body = [
        "## What was run",
        "",
        f"Preset `dahl2004` (robots 0-2 fast 0.30 m/s, 3-5 slow 0.20 m/s) through the PettingZoo "
        f"parallel env with event-driven stepping (step cap 600 s), {args.hours:g} simulated hours "
        f"per seed, seeds {seeds}. Every robot that must decide picks a circuit uniformly at random "
        "(numpy Generator seeded with [seed, 1]; the env is reset with `seed`). The robot spacing is "
        "sampled after every physics tick by wrapping the world's step function in this script.",
        "",
        "## Verdict",
        "",
        f"- **{'FAIL' if failed else 'PASS'}**: longest gap between completions of any robot "
        f"{worst['longest_gap_s']:.0f} s = {worst['longest_gap_s'] / 60:.1f} min "
        f"(robot {worst['robot']} ({worst['speed_class']}), seed {worst['seed']}, "
        f"{worst['gap_kind']}, from {worst['gap_from_s']:.0f} s to {worst['gap_to_s']:.0f} s, "
        f"at mid-gap near ({worst['gap_mid_x']}, {worst['gap_mid_y']}) {worst['gap_mid_phase']}/"
        f"{worst['gap_mid_mode']}); limit {args.max_gap_min:g} min.",
        f"- Steps that hit the step cap (returned with nobody deciding): {total_capped}.",
        "- Escape manoeuvres of stuck robots (no progress for "
        f"{STUCK_PATIENCE_S:g} s): {sum(res['escapes'] for res in results)}.",
        f"- Minimum centre-to-centre distance between robots over "
        f"{sum(res['monitored_ticks'] for res in results)} ticks: {min_dist:.4f} m "
        f"(robot diameter {diameter:.2f} m, i.e. deepest overlap {max(0.0, diameter - min_dist) * 100:.2f} cm); "
        f"ticks with an overlap deeper than 1 cm: {overlap_ticks}.",
        f"- Minimum robot-wall clearance (centre distance to the wall line minus radius): "
        f"{min_wall * 100:.2f} cm.",
        f"- Wall time: {wall:.0f} s in total ("
        + ", ".join(
            f"seed {res['seed']}: {res['wall_s']:.0f} s for {res['sim_time_s'] / 3600:.2f} h, "
            f"{res['steps']} steps, {res['ticks']} ticks"
            for res in results
        )
        + ").",
        "",
        "## Per robot",
        "",
        markdown_table(
            [
                "seed",
                "robot",
                "class",
                "tasks",
                "c0 / c1",
                "mean t (s)",
                "max t (s)",
                "longest gap (s)",
                "when (s)",
                "kind",
                "mid-gap place, phase/mode",
            ],
            [
                (
                    r["seed"],
                    r["robot"],
                    r["speed_class"],
                    r["tasks"],
                    f"{r['tasks_c0']} / {r['tasks_c1']}",
                    fmt_ci(r["mean_task_time_s"], math.nan, math.nan),
                    fmt_ci(r["max_task_time_s"], math.nan, math.nan),
                    f"{r['longest_gap_s']:.0f}",
                    f"{r['gap_from_s']:.0f}-{r['gap_to_s']:.0f}",
                    r["gap_kind"],
                    f"({r['gap_mid_x']}, {r['gap_mid_y']}) {r['gap_mid_phase']}/{r['gap_mid_mode']}",
                )
                for r in rows
            ],
        ),
        "",
        "Gaps count from the start of the run to the first completion and from the last "
        "completion to the end of the run as well, so a robot that stops for good is caught. "
        "The mid-gap place is the robot's position and phase at the env step nearest the middle "
        "of its longest gap. Every completion is in `long_run_tasks_seed<S>.csv`.",
    ]
    summary = {
        "passed": not failed,
        "max_gap_limit_s": max_gap_s,
        "longest_gap": worst,
        "capped_steps": total_capped,
        "min_center_distance_m": min_dist,
        "overlap_ticks_deeper_than_1cm": overlap_ticks,
        "min_wall_clearance_m": min_wall,
        "per_seed": [{k: v for k, v in res.items() if k != "robots"} for res in results],
    }
    meta = run_metadata(
        wall_time_s=wall,
        settings={"preset": "dahl2004", "hours": args.hours, "seeds": seeds},
    )
    paths = write_results(
        args.out, "long_run", rows, "\n".join(body), meta, "Long-run health (dahl2004)", summary
    )
    print("\n".join(body[6:12]))
    print(f"wrote {paths['md']}")
    if failed:
        for r in failed:
            print(
                f"FAIL: robot {r['robot']} (seed {r['seed']}) went {r['longest_gap_s'] / 60:.1f} "
                f"simulated minutes without completing a task ({r['gap_kind']}, "
                f"{r['gap_from_s']:.0f}-{r['gap_to_s']:.0f} s)",
                file=sys.stderr,
            )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
