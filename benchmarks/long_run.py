"""Long-run health of the arena: many simulated hours of `dahl2004` with random circuit choices.

Drives the PettingZoo env (`tavc_env.parallel_env(preset="dahl2004")`, event-driven stepping) with
uniformly random circuit choices for every robot that must decide (seeded), and records every task
completion. Reports, per robot, the number of tasks and the longest gap between two completions
(also counting the start of the run to the first completion and the last completion to the end),
where and when it happened; the number of steps that hit the step cap (a step that returns with
nobody deciding); the minimum centre-to-centre distance between robots and the minimum robot-wall
clearance, sampled after every physics tick by an observer of the engine; and the wall time.

Exits with status 1 if any robot's longest gap exceeds `--max-gap-min` (default 30 simulated
minutes): a robot that stops completing tasks is a jam or a stuck robot.

Writes `long_run.{csv,md,json}` (per robot summary) and `long_run_tasks_seed<S>.csv` (every
completion, written as the run goes) into a new run folder under runs/ (git ignores it), `--out`,
or with `--update-reference` benchmarks/results/. Seeds run through the package's sweep runner
(`--workers`, `--backend local|ray`) and are kept in the output folder's cache/long_run/, so
`--resume RUN_DIR` continues an interrupted run.

    python benchmarks/long_run.py                 # 15 simulated hours, seeds 0-3 (~1-2 min wall)
    python benchmarks/long_run.py --quick         # smoke run

Long-run health of an arena: many simulated hours of a preset (`dahl2004` by default) through
the PettingZoo env with random circuit choices; per robot the longest time without a completion, the steps that hit the
step cap, escapes, and the closest approach of robots to each other and to the walls (sampled
after every physics tick by `tavc_env.measurement.SpacingMonitor`). The script is
`benchmarks/long_run.py`.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

import tavc_env
from tavc_agents.analysis.reports import CsvAppender, Report, fmt_ci, markdown_table
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import json_jobs
from tavc_env.env import completed_task_s
from tavc_env.measurement import PHASE_NAMES, STUCK_PATIENCE_S, Mode, Phase, SpacingMonitor

PRESET = "dahl2004"
MODE_NAMES = {int(m): m.name.lower() for m in Mode}
TASK_FIELDS = ["seed", "robot", "speed_class", "circuit", "task_time_s", "time_s"]
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The long-run check's settings (its command line)."""

    quick_sizes: ClassVar = {"hours": 0.25, "seeds": 1}
    recorded_fields: ClassVar = "preset hours seeds=seed_list"

    preset: str = PRESET
    """the arena (any preset)"""
    seeds: int = 4
    """number of seeds (seed0, seed0 + 1, ...)"""
    seed0: int = 0
    """first seed"""
    hours: float = 15.0
    """simulated hours per seed"""
    max_gap_min: float = 30.0
    """fail if a robot goes longer than this without completing a task (simulated minutes)"""
    quick: bool = False
    """smoke run: 0.25 h, 1 seed"""
    quiet: bool = False
    """no progress output"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            ("seeds", at_least(self.seeds, 1), "an integer >= 1"),
            ("seed0", at_least(self.seed0, 0), "an integer >= 0"),
            ("hours", positive(self.hours), "> 0"),
            ("max_gap_min", positive(self.max_gap_min), "> 0"),
            ("preset", self.preset in tavc_env.PRESETS, f"one of {sorted(tavc_env.PRESETS)}"),
        ]
        refuse_invalid(self, checks)

    @property
    def seed_list(self) -> list[int]:
        return list(range(self.seed0, self.seed0 + self.seeds))


# -- one seed -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class LongRun:
    """One seed's run; its completions are written to `out_dir`/long_run_tasks_seed<S>.csv."""

    seed: int
    hours: float
    out_dir: str
    quiet: bool = True
    preset: str = PRESET


@dataclass
class Trace:
    """What a run recorded step by step: every completion per robot (time, circuit, task time),
    and after every env step the time and everyone's position, phase and mode."""

    completions: list[list[tuple[float, int, float]]]
    times: list[float] = field(default_factory=list)
    positions: list[np.ndarray] = field(default_factory=list)
    phases: list[np.ndarray] = field(default_factory=list)
    modes: list[np.ndarray] = field(default_factory=list)
    steps: int = 0
    capped_at_s: list[float] = field(default_factory=list)

    def sample(self, env: Any) -> None:
        self.times.append(env.sim_time_s)
        self.positions.append(env.sim.positions())
        self.phases.append(env.sim.phases.copy())
        self.modes.append(env.sim.modes.copy())

    def where(self, i: int, t: float) -> dict[str, Any]:
        """Robot i's place, phase and mode at the step nearest after time `t`."""
        t_arr = np.array(self.times)
        k = int(np.clip(np.searchsorted(t_arr, t), 0, len(t_arr) - 1))
        p = self.positions[k][i]
        return {
            "x": round(float(p[0]), 2),
            "y": round(float(p[1]), 2),
            "phase": PHASE_NAMES[Phase(int(self.phases[k][i]))],
            "mode": MODE_NAMES[int(self.modes[k][i])],
        }


def _drive(env: Any, infos: dict[str, Any], seed: int, log: CsvAppender, quiet: bool) -> Trace:
    """Step `env` (just reset, with `infos`) to its end with uniformly random choices (numpy
    Generator seeded [seed, 1]), logging every completion."""
    m = env.config.n_circuits
    classes = [r.speed_class for r in env.config.robots]
    rng = np.random.default_rng([seed, 1])  # action stream, separate from the env's seed
    trace = Trace([[] for _ in range(env.config.n_robots)])
    trace.sample(env)
    next_report, wall0 = 3600.0, time.perf_counter()
    while env.agents:
        actions = {a: int(rng.integers(m)) for a in env.agents if infos[a]["action_required"]}
        _, _, _, truncs, infos = env.step(actions)
        trace.steps += 1
        now = env.sim_time_s
        trace.sample(env)
        deciding = False
        for a, info in infos.items():
            i = int(a.split("_")[1])
            t = completed_task_s(info)
            if t is not None:
                trace.completions[i].append((now, info["circuit"], t))
                log.write(
                    {
                        "seed": seed,
                        "robot": i,
                        "speed_class": classes[i],
                        "circuit": info["circuit"],
                        "task_time_s": round(t, 3),
                        "time_s": round(now, 3),
                    }
                )
            deciding |= info["action_required"]
        if not deciding and not any(truncs.values()):
            trace.capped_at_s.append(now)
        if not quiet and now >= next_report:
            done = sum(len(c) for c in trace.completions)
            wall = time.perf_counter() - wall0
            print(
                f"[seed {seed}] {now / 3600:.1f} h simulated, {done} tasks, {wall:.0f} s wall",
                flush=True,
            )
            next_report += 3600.0
    return trace


def robot_row(seed: int, i: int, speed_class: str, trace: Trace, end: float) -> Row:
    """Robot i's tasks and its longest gap between completions (the start of the run to the first
    and the last to the end count too), where it was in the middle of that gap."""
    done = trace.completions[i]
    times = [0.0] + [c[0] for c in done] + [end]
    gaps = np.diff(times)
    k = int(np.argmax(gaps))
    t0, t1 = times[k], times[k + 1]
    kind = (
        "start->first" if k == 0 else "last->end" if k == len(gaps) - 1 else "between completions"
    )
    mid = trace.where(i, (t0 + t1) / 2)
    tt = np.array([c[2] for c in done])
    circ = np.array([c[1] for c in done], dtype=int)
    return {
        "seed": seed,
        "robot": i,
        "speed_class": speed_class,
        "tasks": len(done),
        "tasks_c0": int((circ == 0).sum()),
        "tasks_c1": int((circ == 1).sum()),
        "mean_task_time_s": float(tt.mean()) if tt.size else math.nan,
        "max_task_time_s": float(tt.max()) if tt.size else math.nan,
        "longest_gap_s": float(gaps[k]),
        "gap_from_s": float(t0),
        "gap_to_s": float(t1),
        "gap_kind": kind,
        "gap_task_circuit": done[k][1] if k < len(done) else None,
        "gap_mid_x": mid["x"],
        "gap_mid_y": mid["y"],
        "gap_mid_phase": mid["phase"],
        "gap_mid_mode": mid["mode"],
    }


def run_seed(
    seed: int, hours: float, out_dir: str, quiet: bool, preset: str = PRESET
) -> dict[str, Any]:
    """One seed's run: per robot rows and the run's health figures."""
    env = tavc_env.parallel_env(preset=preset, max_sim_time_s=hours * 3600.0, max_cycles=10**9)
    monitor = SpacingMonitor(env.config)
    log = CsvAppender(Path(out_dir) / f"long_run_tasks_seed{seed}.csv", TASK_FIELDS)
    _, infos = env.reset(seed=seed)
    env.sim.add_observer(monitor)
    wall0 = time.perf_counter()
    trace = _drive(env, infos, seed, log, quiet)
    wall = time.perf_counter() - wall0
    log.close()
    end = env.sim_time_s
    classes = [r.speed_class for r in env.config.robots]
    return {
        "seed": seed,
        "robots": [robot_row(seed, i, c, trace, end) for i, c in enumerate(classes)],
        "sim_time_s": end,
        "steps": trace.steps,
        "ticks": env.sim.ticks,
        "capped_steps": len(trace.capped_at_s),
        "escapes": env.escapes,
        "jams": env.jams,
        "jammed_s": env.time_jammed_s,
        "capped_at_s": trace.capped_at_s[:20],
        "wall_s": wall,
        "min_dist_m": monitor.min_dist,
        "min_dist_at": monitor.min_dist_at,
        "overlap_ticks": monitor.overlap_ticks,
        "monitored_ticks": monitor.ticks,
        "min_wall_clearance_m": monitor.min_wall,
        "min_wall_at": monitor.min_wall_at,
        "diameter_m": 2 * env.config.robot_radius,
    }


def run_long(job: LongRun) -> dict[str, Any]:
    """One seed's run as JSON data (what the sweep saves)."""
    result = run_seed(job.seed, job.hours, job.out_dir, job.quiet, job.preset)
    data: dict[str, Any] = json.loads(json.dumps(result, default=float))
    return data


RUNS = json_jobs(run_long, lambda job: f"seed{job.seed}_{job.hours:g}h", unit="seed")


# -- report -------------------------------------------------------------------------------------
def verdict_lines(
    results: Sequence[dict[str, Any]], worst: Row, failed: bool, s: Settings, wall_s: float
) -> list[str]:
    """The verdict (longest gap against the limit) and the run's health figures."""
    min_dist = min(res["min_dist_m"] for res in results)
    diameter = results[0]["diameter_m"]
    gap = worst["longest_gap_s"]
    walls = ", ".join(
        f"seed {res['seed']}: {res['wall_s']:.0f} s for {res['sim_time_s'] / 3600:.2f} h, "
        f"{res['steps']} steps, {res['ticks']} ticks"
        for res in results
    )
    return [
        f"- **{'FAIL' if failed else 'PASS'}**: longest gap between completions of any robot "
        f"{gap:.0f} s = {gap / 60:.1f} min "
        f"(robot {worst['robot']} ({worst['speed_class']}), seed {worst['seed']}, "
        f"{worst['gap_kind']}, from {worst['gap_from_s']:.0f} s to {worst['gap_to_s']:.0f} s, "
        f"at mid-gap near ({worst['gap_mid_x']}, {worst['gap_mid_y']}) {worst['gap_mid_phase']}/"
        f"{worst['gap_mid_mode']}); limit {s.max_gap_min:g} min.",
        "- Steps that hit the step cap (returned with nobody deciding): "
        f"{sum(res['capped_steps'] for res in results)}.",
        f"- Jams found by the engine's detector: {sum(res['jams'] for res in results)} "
        f"({sum(res['jammed_s'] for res in results):.0f} s jammed in all).",
        "- Escape manoeuvres of stuck robots (no progress for "
        f"{STUCK_PATIENCE_S:g} s): {sum(res['escapes'] for res in results)}.",
        f"- Minimum centre-to-centre distance between robots over "
        f"{sum(res['monitored_ticks'] for res in results)} ticks: {min_dist:.4f} m "
        f"(robot diameter {diameter:.2f} m, i.e. deepest overlap "
        f"{max(0.0, diameter - min_dist) * 100:.2f} cm); ticks with an overlap deeper than 1 cm: "
        f"{sum(res['overlap_ticks'] for res in results)}.",
        f"- Minimum robot-wall clearance (centre distance to the wall line minus radius): "
        f"{min(res['min_wall_clearance_m'] for res in results) * 100:.2f} cm.",
        f"- Wall time: {wall_s:.0f} s in total ({walls}).",
    ]


def robot_table(rows: Sequence[Row]) -> str:
    header = [
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
    ]
    cells = [
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
    ]
    return markdown_table(header, cells)


def team_text(preset: str) -> str:
    """The preset's robots by index, class and top speed, e.g. '0-2 fast 0.3 m/s, 3-5 slow 0.2 m/s'."""
    robots = tavc_env.preset(preset).robots
    runs: list[list[int]] = []
    for i, robot in enumerate(robots):
        if runs and robots[runs[-1][0]] == robot:
            runs[-1].append(i)
        else:
            runs.append([i])

    def span(r: list[int]) -> str:
        return f"{r[0]}-{r[-1]}" if len(r) > 1 else str(r[0])

    return ", ".join(
        f"{span(r)} {robots[r[0]].speed_class} {robots[r[0]].speed:g} m/s" for r in runs
    )


def report_body(
    results: Sequence[dict[str, Any]], worst: Row, failed: bool, s: Settings, wall_s: float
) -> list[str]:
    return [
        "## What was run",
        "",
        f"Preset `{s.preset}` (robots {team_text(s.preset)}) through the PettingZoo "
        f"parallel env with event-driven stepping (step cap 600 s), {s.hours:g} simulated hours "
        f"per seed, seeds {s.seed_list}. Every robot that must decide picks a circuit uniformly at "
        "random (numpy Generator seeded with [seed, 1]; the env is reset with `seed`). The robot "
        "spacing is sampled after every physics tick by an observer of the engine "
        "(`tavc_env.measurement.SpacingMonitor`).",
        "",
        "## Verdict",
        "",
        *verdict_lines(results, worst, failed, s, wall_s),
        "",
        "## Per robot",
        "",
        robot_table([r for res in results for r in res["robots"]]),
        "",
        "Gaps count from the start of the run to the first completion and from the last "
        "completion to the end of the run as well, so a robot that stops for good is caught. "
        "The mid-gap place is the robot's position and phase at the env step nearest the middle "
        "of its longest gap. Every completion is in `long_run_tasks_seed<S>.csv`.",
    ]


def summary(results: Sequence[dict[str, Any]], worst: Row, failed: bool, s: Settings) -> Row:
    return {
        "passed": not failed,
        "max_gap_limit_s": s.max_gap_min * 60.0,
        "longest_gap": worst,
        "capped_steps": sum(res["capped_steps"] for res in results),
        "min_center_distance_m": min(res["min_dist_m"] for res in results),
        "overlap_ticks_deeper_than_1cm": sum(res["overlap_ticks"] for res in results),
        "min_wall_clearance_m": min(res["min_wall_clearance_m"] for res in results),
        "per_seed": [{k: v for k, v in res.items() if k != "robots"} for res in results],
    }


def run(settings: Settings) -> Outcome:
    """Run (or resume) every seed, then write the per-robot report; the outcome lists the robots
    whose longest gap exceeded `max_gap_min`."""
    out = settings.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    s = settings.sized()
    jobs = [LongRun(seed, s.hours, str(out), s.quiet, s.preset) for seed in s.seed_list]
    jobs_dir = Path("cache", "long_run")  # its provenance with it (`out` may be shared)
    done, provenance = settings.run_jobs(
        jobs,
        RUNS,
        jobs_dir,
        provenance_in=jobs_dir,
        wall_of=lambda result: float(result["wall_s"]),
        progress_bar=not s.quiet,
    )
    results = [done[RUNS.key(job)] for job in jobs]
    rows = [r for res in results for r in res["robots"]]
    worst = max(rows, key=lambda r: r["longest_gap_s"])
    failed = [r for r in rows if r["longest_gap_s"] > s.max_gap_min * 60.0]
    body = report_body(results, worst, bool(failed), s, provenance["wall_time_s"])
    report = Report(
        "long_run",
        f"Long-run health ({s.preset})",
        "\n".join(body),
        rows,
        summary(results, worst, bool(failed), s),
    )
    written = report.write(out, provenance)
    text = "\n".join([*body[6:12], f"wrote {out / 'long_run.md'}"])
    return Outcome(out, written, text, failure_lines(failed))


def failure_lines(failed: Sequence[Row]) -> list[str]:
    """One line per robot that went longer than the limit without completing a task."""
    return [
        f"FAIL: robot {r['robot']} (seed {r['seed']}) went {r['longest_gap_s'] / 60:.1f} "
        f"simulated minutes without completing a task ({r['gap_kind']}, "
        f"{r['gap_from_s']:.0f}-{r['gap_to_s']:.0f} s)"
        for r in failed
    ]


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
