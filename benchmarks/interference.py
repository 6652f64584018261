"""Interference in the arena: task time against crowding, the cost of a circuit switch, and the
cross-interference between fast and slow robots.

Every measurement drives the bare engine (`tavc_env.engine.simulation.Simulation`) with fixed allocations:
each robot serves the circuit it is given, task after task (a designated "switcher" alternates).

1. **t(n)** (preset `dahl2004_homogeneous`, six robots at 0.25 m/s): allocation k on circuit 0 and
   6 - k on circuit 1 for k = 0..6; one run gives t_0(k) and t_1(6 - k), so seven allocations give
   t(n) for n = 1..6 on both circuits. Also t(n+1)/t(n) with a 95% interval.
2. **Switch cost** (homogeneous): one robot alternates circuits every `--switch-every` tasks while
   the five others stay (three on one circuit, two on the other, both ways round, so every switch
   into a circuit is measured with 3 robots there, i.e. in the 3 + 3 state, and with 4); and a lone
   robot alone in the arena, alternating. A *switch task* starts at the other circuit's sink; its
   time is compared with the same robot's *own-circuit* tasks on the same circuit in the same run
   (same crowding).
3. **Cross-interference** (preset `dahl2004`: robots 0-2 fast 0.30 m/s, 3-5 slow 0.20 m/s): f fast
   and s slow robots on circuit 0 (f, s = 0..3), the rest on circuit 1; the mean task time of a fast
   and of a slow robot on circuit 0 (and, from the same runs, on circuit 1 with 3-f fast, 3-s slow).

Warm-up: in every run a task counts only if it was *decided* at or after `--warmup-min` (default
10 simulated minutes) and it is not among the robot's first `--skip-first` (default 2) tasks (the
first task can start at the other circuit's sink, since reset spreads robots 3 + 3 in random
order). Tasks decided up to the end of the run (`--hours`) count, and the run goes on until they
are all complete, so long tasks are not censored at the end.

Statistics: each run (seed) gives one number per quantity: the mean over its counted tasks
(task-weighted over the robots of that group). Reported: mean over seeds with a Student-t 95%
interval (scipy.stats.t, n_seeds - 1 df). Ratios t(n+1)/t(n) are ratios of the seed means of two
separate sets of runs; the 95% interval is a delta-method interval on the log scale with
Welch-Satterthwaite degrees of freedom (see `_common.ratio_ci`); a percentile bootstrap over seeds
is given as a cross-check (too narrow with few seeds). The switch cost is paired within a run:
per seed, mean(switch tasks into c) - mean(own tasks on c), absolute and relative to the own-task
mean; mean over seeds with a Student-t interval.

Writes `interference.{csv,md,json}`, `interference_runs.csv` (one row per run and group, written
as runs finish) and `interference.png` (if matplotlib is installed) into `--out`. Runs go through
the package's sweep runner (`--workers`, `--backend local|ray`) and are kept in `--out`/cache/ as
they finish, so an interrupted benchmark resumes.

    python benchmarks/interference.py             # 130 runs: 5 seeds x 3 simulated h, ~3-5 min
    python benchmarks/interference.py --quick
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
from collections import defaultdict
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from _common import (
    RESULTS_DIR,
    CsvAppender,
    add_override_option,
    add_sweep_options,
    bootstrap_ratio_ci,
    fmt_ci,
    have_matplotlib,
    markdown_table,
    mean_ci,
    parsed_overrides,
    ratio_ci,
    run_metadata,
    write_results,
)

import tavc_env
from agents.experiments.sweep import json_jobs, run_jobs
from tavc_env.engine.simulation import Simulation
from tavc_env.engine.tasks import Mode

HOMOG = "dahl2004_homogeneous"
HETERO = "dahl2004"
RATIO_REQUIREMENT = 1.15  # t(4)/t(3) on the high-value circuit
SWITCH_REQUIREMENT = 0.20  # extra time of a switch task relative to an own-circuit task


@dataclass(frozen=True)
class Job:
    experiment: str  # t_n | switch | switch_lone | cross
    preset: str
    circuit_of: tuple[int, ...]  # each robot's circuit (the switcher's first circuit)
    seed: int
    hours: float
    warmup_s: float
    skip_first: int
    switcher: int = -1
    switch_every: int = 3
    speeds: tuple[float, ...] | None = None
    label: str = ""
    arena: tuple[tuple[str, Any], ...] = ()  # ArenaConfig overrides (--set)


def run_job(job: Job) -> dict[str, Any]:
    """One run; returns every counted task (robot, class, circuit, time, kind)."""
    overrides: dict[str, Any] = dict(job.arena)
    if job.speeds is not None:
        overrides["speeds"] = list(job.speeds)
    cfg = tavc_env.make_config(job.preset, **overrides)
    n = cfg.n_robots
    assert len(job.circuit_of) == n, (job, n)
    classes = [r.speed_class for r in cfg.robots]
    sim = Simulation(cfg)
    sim.reset(np.random.default_rng(job.seed))
    end_s = job.hours * 3600.0
    current = list(job.circuit_of)
    block = [0] * n  # tasks chosen in the switcher's current block
    ordinal = [0] * n  # tasks chosen so far per robot
    # per robot: the task in progress (decided_at, kind, ordinal) or None once past the window
    pending: list[tuple[float, str, int] | None] = [None] * n

    def decide(i: int) -> None:
        if i == job.switcher:
            if block[i] == job.switch_every:
                current[i] = 1 - current[i]
                block[i] = 0
            block[i] += 1
        c = current[i]
        kind = "switch" if c != int(sim.tasks.circuit[i]) else "own"
        now = sim.time_s
        pending[i] = (now, kind, ordinal[i]) if now <= end_s + 1e-9 else None
        ordinal[i] += 1
        sim.choose(i, c)

    # Where the time goes: ticks spent in each mode (travel, queued, docking, service) per robot
    # during the measured window, counted by wrapping the world's step function.
    mode_ticks = np.zeros((n, len(Mode)))
    rows_idx = np.arange(n)
    world_step = sim.world.step

    def counting_step(dt: float) -> None:
        world_step(dt)
        if job.warmup_s <= sim.time_s < end_s:
            mode_ticks[rows_idx, sim.tasks.mode] += 1

    sim.world.step = counting_step  # type: ignore[method-assign]

    wall0 = time.perf_counter()
    for i in range(n):
        decide(i)
    tasks: list[tuple[int, str, int, float, float, str]] = []
    while sim.time_s < end_s or any(p is not None for p in pending):
        out = sim.advance(600.0)
        for comp in out.completions:
            i = comp.robot
            p = pending[i]
            if p is not None and p[0] >= job.warmup_s - 1e-9 and p[2] >= job.skip_first:
                tasks.append((i, classes[i], comp.circuit, comp.task_time_s, p[0], p[1]))
            pending[i] = None
            decide(i)
        if sim.time_s > end_s + 3600.0:
            raise RuntimeError(f"{job}: tasks still pending an hour after the end of the run")
    return {
        "job": job,
        "tasks": tasks,
        "wall_s": time.perf_counter() - wall0,
        "n_robots": n,
        "classes": classes,
        "mode_ticks": mode_ticks,
    }


def run_job_rows(job: Job) -> dict[str, Any]:
    """One run reduced to its per-group rows (JSON data, what the sweep runner saves)."""
    return {"rows": run_rows(run_job(job))}


def job_key(job: Job) -> str:
    label = re.sub(r"[^A-Za-z0-9_.=-]+", "-", job.label).strip("-")
    return f"{job.experiment}_{label}_s{job.seed}"


RUNS = json_jobs(run_job_rows, job_key, unit="run")


# -- job lists ---------------------------------------------------------------------------------
def make_jobs(
    seeds: list[int],
    hours: float,
    warmup_s: float,
    skip: int,
    k: int,
    arena: tuple[tuple[str, Any], ...] = (),
) -> list[Job]:
    jobs: list[Job] = []
    common: dict[str, Any] = {
        "hours": hours,
        "warmup_s": warmup_s,
        "skip_first": skip,
        "arena": arena,
    }
    for s in seeds:
        for n0 in range(7):  # n0 robots on circuit 0, 6 - n0 on circuit 1
            alloc = tuple([0] * n0 + [1] * (6 - n0))
            jobs.append(Job("t_n", HOMOG, alloc, s, label=f"{n0}+{6 - n0}", **common))
        for others0 in (3, 2):  # the five others: `others0` on circuit 0, the rest on circuit 1
            alloc = tuple([0] * others0 + [1] * (5 - others0) + [1])  # switcher (5) starts on 1
            jobs.append(
                Job(
                    "switch",
                    HOMOG,
                    alloc,
                    s,
                    switcher=5,
                    switch_every=k,
                    label=f"others {others0}+{5 - others0}",
                    **common,
                )
            )
        jobs.append(
            Job(
                "switch_lone",
                HOMOG,
                (0,),
                s,
                switcher=0,
                switch_every=k,
                speeds=(0.25,),
                label="lone",
                **common,
            )
        )
        for f in range(4):
            for sl in range(4):
                alloc = tuple([0] * f + [1] * (3 - f) + [0] * sl + [1] * (3 - sl))
                jobs.append(Job("cross", HETERO, alloc, s, label=f"{f}:{sl}", **common))
    return jobs


# -- aggregation -------------------------------------------------------------------------------
def run_rows(res: dict[str, Any]) -> list[dict[str, Any]]:
    """Per-run rows: one per (circuit, class, kind) group with its task count and mean time."""
    job: Job = res["job"]
    groups: dict[tuple[int, str, str], list[float]] = defaultdict(list)
    for robot, cls, c, t, _, kind in res["tasks"]:
        if robot == job.switcher:
            groups[(c, "switcher", kind)].append(t)
        else:
            groups[(c, cls, kind)].append(t)
            groups[(c, "all", kind)].append(t)
    rows = []
    alloc = job.circuit_of
    for (c, cls, kind), times in sorted(groups.items()):
        on_c = [i for i, ci in enumerate(alloc) if ci == c and i != job.switcher]
        row = {
            "experiment": job.experiment,
            "preset": job.preset,
            "label": job.label,
            "seed": job.seed,
            "circuit": c,
            "robot_class": cls,
            "task_kind": kind,
            "n_on_circuit": len(on_c) + (1 if job.switcher >= 0 else 0),
            "n_fast_on_circuit": sum(1 for i in on_c if job.preset == HETERO and i < 3),
            "n_slow_on_circuit": sum(1 for i in on_c if job.preset == HETERO and i >= 3),
            "n_tasks": len(times),
            "mean_task_time_s": float(np.mean(times)),
            "sd_task_time_s": float(np.std(times, ddof=1)) if len(times) > 1 else math.nan,
            "run_wall_s": round(res["wall_s"], 2),
        }
        if job.switcher < 0 and kind == "own":
            members = [i for i in on_c if cls == "all" or res["classes"][i] == cls]
            ticks = res["mode_ticks"][members].sum(axis=0)
            if ticks.sum() > 0:
                frac = ticks / ticks.sum()
                row["queued_s_per_task"] = float(frac[Mode.QUEUED] * row["mean_task_time_s"])
                row["travel_s_per_task"] = float(frac[Mode.TRAVEL] * row["mean_task_time_s"])
        rows.append(row)
    return rows


RUN_FIELDS = [
    "experiment",
    "preset",
    "label",
    "seed",
    "circuit",
    "robot_class",
    "task_kind",
    "n_on_circuit",
    "n_fast_on_circuit",
    "n_slow_on_circuit",
    "n_tasks",
    "mean_task_time_s",
    "sd_task_time_s",
    "queued_s_per_task",
    "travel_s_per_task",
    "run_wall_s",
]


def per_seed(rows: list[dict[str, Any]], **match: Any) -> dict[int, dict[str, Any]]:
    out = {}
    for r in rows:
        if all(r[k] == v for k, v in match.items()):
            assert r["seed"] not in out, (match, r)
            out[r["seed"]] = r
    return out


def analyse(rows: list[dict[str, Any]], seeds: list[int], boot_rng: np.random.Generator):
    summary_rows: list[dict[str, Any]] = []
    results: dict[str, Any] = {}

    def add(section: str, quantity: str, stats: tuple[float, float, float, int], **kw: Any):
        m, lo, hi, n = stats
        row = {"section": section, "quantity": quantity, **kw}
        row.update({"mean": m, "ci95_low": lo, "ci95_high": hi, "n_seeds": n})
        summary_rows.append(row)
        return row

    # 1. t(n) per circuit
    tn: dict[int, dict[int, list[float]]] = {0: {}, 1: {}}
    for c in (0, 1):
        for n in range(1, 7):
            sel = per_seed(
                rows,
                experiment="t_n",
                circuit=c,
                n_on_circuit=n,
                robot_class="all",
                task_kind="own",
            )
            vals = [sel[s]["mean_task_time_s"] for s in seeds if s in sel]
            tn[c][n] = vals
            st = mean_ci(vals)
            add(
                "t_n",
                "mean task time (s)",
                st,
                preset=HOMOG,
                circuit=c,
                n_on_circuit=n,
                robot_class="medium",
                n_tasks=sum(sel[s]["n_tasks"] for s in sel),
            )
            add(
                "t_n",
                "time queued per task (s)",
                mean_ci([sel[s].get("queued_s_per_task", math.nan) for s in seeds if s in sel]),
                preset=HOMOG,
                circuit=c,
                n_on_circuit=n,
                robot_class="medium",
            )
            # circuit throughput c(n) = n / t(n) (tasks per hour), the TAVC model's c_{i,J}
            add(
                "t_n",
                "circuit throughput n/t(n) (tasks/h)",
                mean_ci([3600.0 * n / v for v in vals]),
                preset=HOMOG,
                circuit=c,
                n_on_circuit=n,
                robot_class="medium",
            )
        for n in range(1, 6):
            r, lo, hi = ratio_ci(tn[c][n + 1], tn[c][n])
            blo, bhi = bootstrap_ratio_ci(tn[c][n + 1], tn[c][n], boot_rng)
            add(
                "t_ratio",
                f"t({n + 1})/t({n})",
                (r, lo, hi, min(len(tn[c][n + 1]), len(tn[c][n]))),
                preset=HOMOG,
                circuit=c,
                n_on_circuit=n + 1,
                robot_class="medium",
                bootstrap_low=blo,
                bootstrap_high=bhi,
            )
    results["t_n"] = tn

    # 2. switch cost, paired within each run
    switch: dict[str, dict[str, Any]] = {}
    for exp, label, c in (
        ("switch", "others 2+3", 0),  # switch into c0 -> 3 on c0 (3 + 3 state)
        ("switch", "others 3+2", 1),  # switch into c1 -> 3 on c1 (3 + 3 state)
        ("switch", "others 3+2", 0),  # switch into c0 -> 4 on c0 (4 + 2)
        ("switch", "others 2+3", 1),  # switch into c1 -> 4 on c1 (2 + 4)
        ("switch_lone", "lone", 0),
        ("switch_lone", "lone", 1),
    ):
        match = {"experiment": exp, "label": label, "circuit": c, "robot_class": "switcher"}
        sw = per_seed(rows, task_kind="switch", **match)
        own = per_seed(rows, task_kind="own", **match)
        both = [s for s in seeds if s in sw and s in own]
        t_sw = [sw[s]["mean_task_time_s"] for s in both]
        t_own = [own[s]["mean_task_time_s"] for s in both]
        extra = [a - b for a, b in zip(t_sw, t_own)]
        rel = [(a - b) / b for a, b in zip(t_sw, t_own)]
        if exp == "switch_lone":
            n_on = 1
        else:
            others0 = int(label.split()[1].split("+")[0])
            n_on = (others0 if c == 0 else 5 - others0) + 1
        key = f"{label} into c{c}"
        kw = {"preset": HOMOG, "circuit": c, "n_on_circuit": n_on, "robot_class": "switcher"}
        info = {
            "label": label,
            "circuit": c,
            "n_on_circuit": n_on,
            "own": add("switch", f"{key}: own-circuit task time (s)", mean_ci(t_own), **kw),
            "switch": add("switch", f"{key}: switch task time (s)", mean_ci(t_sw), **kw),
            "extra": add("switch", f"{key}: extra time (s)", mean_ci(extra), **kw),
            "relative": add("switch", f"{key}: relative extra", mean_ci(rel), **kw),
            "rel_values": rel,
            "n_switch_tasks": sum(sw[s]["n_tasks"] for s in both),
            "n_own_tasks": sum(own[s]["n_tasks"] for s in both),
        }
        switch[key] = info
    # headline: the two 3 + 3 cases pooled (one value per run)
    pooled = switch["others 2+3 into c0"]["rel_values"] + switch["others 3+2 into c1"]["rel_values"]
    results["switch_pooled"] = add(
        "switch",
        "3+3 pooled over both circuits: relative extra",
        mean_ci(pooled),
        preset=HOMOG,
        n_on_circuit=3,
        robot_class="switcher",
    )
    results["switch"] = switch

    # 3. cross-interference matrices: circuit 0 from (f, s) on it; circuit 1 from (3-f, 3-s)
    cross: dict[tuple[int, str], dict[tuple[int, int], tuple[float, float, float, int]]] = {}
    queued: dict[tuple[int, str], dict[tuple[int, int], tuple[float, float, float, int]]] = {}
    for c in (0, 1):
        for cls in ("fast", "slow", "all"):
            mat = {}
            qmat = {}
            for f in range(4):
                for sl in range(4):
                    nf, ns = (f, sl) if c == 0 else (3 - f, 3 - sl)
                    sel = per_seed(
                        rows,
                        experiment="cross",
                        label=f"{f}:{sl}",
                        circuit=c,
                        robot_class=cls,
                        task_kind="own",
                    )
                    vals = [sel[s]["mean_task_time_s"] for s in seeds if s in sel]
                    st = mean_ci(vals)
                    mat[(nf, ns)] = st
                    qst = mean_ci(
                        [sel[s].get("queued_s_per_task", math.nan) for s in seeds if s in sel]
                    )
                    qmat[(nf, ns)] = qst
                    if vals:
                        add(
                            "cross",
                            "time queued per task (s)",
                            qst,
                            preset=HETERO,
                            circuit=c,
                            n_on_circuit=nf + ns,
                            n_fast_on_circuit=nf,
                            n_slow_on_circuit=ns,
                            robot_class=cls,
                        )
                        add(
                            "cross",
                            "mean task time (s)",
                            st,
                            preset=HETERO,
                            circuit=c,
                            n_on_circuit=nf + ns,
                            n_fast_on_circuit=nf,
                            n_slow_on_circuit=ns,
                            robot_class=cls,
                            n_tasks=sum(sel[s]["n_tasks"] for s in sel),
                        )
            cross[(c, cls)] = mat
            queued[(c, cls)] = qmat
    results["cross"] = cross
    results["cross_queued"] = queued
    return summary_rows, results


# -- report ------------------------------------------------------------------------------------
def report(results: dict[str, Any], summary_rows: list[dict[str, Any]], args: Any) -> str:
    tn = results["t_n"]
    ratio_rows = {
        (r["circuit"], r["quantity"]): r for r in summary_rows if r["section"] == "t_ratio"
    }
    r43 = ratio_rows[(0, "t(4)/t(3)")]
    r43_1 = ratio_rows[(1, "t(4)/t(3)")]
    pooled = results["switch_pooled"]
    sw = results["switch"]
    ok_ratio = r43["mean"] >= RATIO_REQUIREMENT
    ok_switch = pooled["mean"] >= SWITCH_REQUIREMENT

    def verdict(ok: bool, low: float, req: float) -> str:
        if not ok and not math.isfinite(low):
            return "NOT MEASURED (too few tasks or seeds for an estimate)"
        word = "PASS" if ok else "FAIL"
        if ok and math.isfinite(low):
            word += (
                " (the whole 95% interval is above the requirement)"
                if low >= req
                else " (but the 95% interval reaches below the requirement)"
            )
        return word

    lines = [
        "## Verdict",
        "",
        f"- **t(4)/t(3) on the high-value circuit (circuit 0) = "
        f"{fmt_ci(r43['mean'], r43['ci95_low'], r43['ci95_high'], 3)}**; requirement >= "
        f"{RATIO_REQUIREMENT}: **{verdict(ok_ratio, r43['ci95_low'], RATIO_REQUIREMENT)}**. "
        f"(Circuit 1: {fmt_ci(r43_1['mean'], r43_1['ci95_low'], r43_1['ci95_high'], 3)}.)",
        f"- **Switch cost relative to an own-circuit task, 3 + 3 state, pooled over both circuits "
        f"= {fmt_ci(100 * pooled['mean'], 100 * pooled['ci95_low'], 100 * pooled['ci95_high'])} "
        f"%**; requirement >= {100 * SWITCH_REQUIREMENT:.0f} %: "
        f"**{verdict(ok_switch, pooled['ci95_low'], SWITCH_REQUIREMENT)}**. Into circuit 0: "
        f"{fmt_ci(*(100 * v for v in _ci(sw['others 2+3 into c0']['relative'])))} %, into "
        f"circuit 1: {fmt_ci(*(100 * v for v in _ci(sw['others 3+2 into c1']['relative'])))} %; "
        f"lone robot: {fmt_ci(*(100 * v for v in _ci(sw['lone into c0']['relative'])))} % / "
        f"{fmt_ci(*(100 * v for v in _ci(sw['lone into c1']['relative'])))} %.",
    ]
    # TAVC equilibrium check in reward terms: 4th on c0 vs 3rd on c1
    w0, w1 = (c.value for c in tavc_env.make_config(HOMOG).circuits)
    t0_4, t1_3 = np.mean(tn[0][4]), np.mean(tn[1][3])
    lines.append(
        f"- TAVC equilibrium (DESIGN.md section 3): the 4th robot on circuit 0 earns w0/t0(4) = "
        f"{w0 / t0_4:.2f}/s, the 3rd on circuit 1 w1/t1(3) = {w1 / t1_3:.2f}/s, so 3 + 3 is "
        f"{'an' if w1 / t1_3 > w0 / t0_4 else 'NOT an'} equilibrium of the homogeneous arena "
        f"(needs t0(4)/t1(3) > w0/w1 = {w0 / w1:.2f}; measured {t0_4 / t1_3:.3f})."
    )
    lines += [
        "",
        "## Method",
        "",
        f"Simulated {args.hours:g} h per run, seeds {args.seed_list}; a task counts if decided at "
        f"or after {args.warmup_min:g} simulated minutes and not among the robot's first "
        f"{args.skip_first} tasks; tasks decided before the end are run to completion. Each run "
        "gives one mean per group (task-weighted over the group's robots); tables show the mean "
        "over seeds and a Student-t 95% interval [low, high]. Ratios: ratio of seed means with a "
        "log-scale delta-method interval (Welch-Satterthwaite df); the bootstrap column resamples "
        "seeds (10,000 reps) and is too narrow with few seeds. Switch cost: per run, mean switch "
        "task time minus mean own-circuit task time of the same robot on the same circuit "
        f"(switching every {args.switch_every} tasks: one switch task and "
        f"{args.switch_every - 1} own tasks per block); relative = that / own-task mean; mean "
        "over runs with a Student-t interval. Stations serve one robot at a time "
        "(source loading 20 s, sink unloading 4 s); robots are discs of radius 0.22 m.",
        "",
        "## 1. Task time t(n) with n robots on a circuit (dahl2004_homogeneous, 0.25 m/s)",
        "",
    ]
    get = {
        (r["section"], r["quantity"], r.get("circuit"), r.get("n_on_circuit")): r
        for r in summary_rows
    }
    trows = []
    for n in range(1, 7):
        cells = [str(n)]
        for c in (0, 1):
            r = get[("t_n", "mean task time (s)", c, n)]
            cells.append(fmt_ci(r["mean"], r["ci95_low"], r["ci95_high"]))
            q = get[("t_n", "time queued per task (s)", c, n)]
            cells.append(fmt_ci(q["mean"], q["ci95_low"], q["ci95_high"]))
            thr = get[("t_n", "circuit throughput n/t(n) (tasks/h)", c, n)]
            cells.append(fmt_ci(thr["mean"], thr["ci95_low"], thr["ci95_high"]))
            if n >= 2:
                q = ratio_rows[(c, f"t({n})/t({n - 1})")]
                cells.append(
                    f"{fmt_ci(q['mean'], q['ci95_low'], q['ci95_high'], 3)} "
                    f"(boot [{q['bootstrap_low']:.3f}, {q['bootstrap_high']:.3f}])"
                )
            else:
                cells.append("")
        trows.append(cells)
    lines.append(
        markdown_table(
            [
                "n",
                "c0 t(n) s",
                "c0 queued s/task",
                "c0 tasks/h n/t",
                "c0 t(n)/t(n-1)",
                "c1 t(n) s",
                "c1 queued s/task",
                "c1 tasks/h n/t",
                "c1 t(n)/t(n-1)",
            ],
            trows,
        )
    )
    lines += [
        "",
        "t(n) on circuit 0 and t(6-n) on circuit 1 come from the same runs (allocation n + 6-n). "
        "'queued s/task': time a robot spends waiting in a station's line per task (its share "
        "of ticks in the queued mode times its mean task time). 'tasks/h': the circuit's "
        "delivery rate n / t(n) (the TAVC model's c); it saturates where the source station "
        "(20 s loading plus the changeover between robots) is busy all the time.",
        "",
        "## 2. Extra time of a circuit switch (dahl2004_homogeneous)",
        "",
    ]
    srows = []
    for key, info in sw.items():
        srows.append(
            (
                key,
                info["n_on_circuit"],
                fmt_ci(*_ci(info["own"])),
                fmt_ci(*_ci(info["switch"])),
                fmt_ci(*_ci(info["extra"])),
                fmt_ci(*(100 * v for v in _ci(info["relative"]))),
                f"{info['n_switch_tasks']} / {info['n_own_tasks']}",
            )
        )
    lines.append(
        markdown_table(
            [
                "case (switcher into circuit)",
                "robots on that circuit",
                "own task (s)",
                "switch task (s)",
                "extra (s)",
                "extra (%)",
                "tasks switch / own",
            ],
            srows,
        )
    )
    lines += [
        "",
        "'others a+b': the five non-switching robots, a on circuit 0 and b on circuit 1; the "
        "switcher (robot 5) alternates. 'robots on that circuit' counts the switcher.",
        "",
        "## 3. Cross-interference (dahl2004: fast 0.30 m/s, slow 0.20 m/s)",
        "",
        "Mean task time (s) of a fast and of a slow robot on the high-value circuit 0, with f fast "
        "(rows) and s slow (columns) robots on circuit 0 (the robot itself included) and the rest "
        "on circuit 1.",
        "",
    ]
    cross = results["cross"]
    for c in (0, 1):
        for cls in ("fast", "slow"):
            mat = cross[(c, cls)]
            lines.append(f"**{cls.capitalize()} robot on circuit {c}** (rows f, columns s):")
            lines.append("")
            mrows = []
            for f in range(4):
                mrows.append([f"f={f}"] + [fmt_ci(*_ci4(mat.get((f, s)))) for s in range(4)])
            lines.append(markdown_table(["", "s=0", "s=1", "s=2", "s=3"], mrows))
            lines.append("")
        if c == 0:
            qm = results["cross_queued"]
            for cls in ("fast", "slow"):
                lines.append(
                    f"**{cls.capitalize()} robot on circuit 0: seconds per task spent waiting in "
                    "a station's line** (rows f, columns s):"
                )
                lines.append("")
                mrows = [
                    [f"f={f}"] + [fmt_ci(*_ci4(qm[(0, cls)].get((f, s)))) for s in range(4)]
                    for f in range(4)
                ]
                lines.append(markdown_table(["", "s=0", "s=1", "s=2", "s=3"], mrows))
                lines.append("")
            lines += [
                "Circuit 1 from the same runs (f fast and s slow robots on circuit 1):",
                "",
            ]
    lines += _cross_notes(cross, results["cross_queued"])
    return "\n".join(lines)


def _ci(row: dict[str, Any]) -> tuple[float, float, float]:
    return (row["mean"], row["ci95_low"], row["ci95_high"])


def _ci4(st: tuple[float, float, float, int] | None) -> tuple[float, float, float]:
    if st is None:
        return (math.nan, math.nan, math.nan)
    return st[:3]


def _cross_notes(cross: dict[Any, Any], queued: dict[Any, Any]) -> list[str]:
    """Plain-language reading of the circuit-0 matrices: who slows whom."""
    out = ["### Reading the matrices", ""]

    def t(cls: str, f: int, s: int) -> float:
        st = cross[(0, cls)].get((f, s))
        return st[0] if st is not None and math.isfinite(st[0]) else math.nan

    def q(cls: str, f: int, s: int) -> float:
        st = queued[(0, cls)].get((f, s))
        return st[0] if st is not None and math.isfinite(st[0]) else math.nan

    out.append(
        f"- Alone on circuit 0: fast {t('fast', 1, 0):.1f} s, slow {t('slow', 0, 1):.1f} s "
        f"(slow/fast = {t('slow', 0, 1) / t('fast', 1, 0):.3f}; travel alone would give 1.5)."
    )
    out.append(
        f"- First companion: a fast robot with one more fast robot {t('fast', 1, 0):.1f} -> "
        f"{t('fast', 2, 0):.1f} s ({t('fast', 2, 0) - t('fast', 1, 0):+.1f} s), with one slow "
        f"robot -> {t('fast', 1, 1):.1f} s ({t('fast', 1, 1) - t('fast', 1, 0):+.1f} s; queued "
        f"{q('fast', 1, 1):.1f} s per task against {q('fast', 2, 0):.1f} s with a fast "
        f"companion). A slow robot with one more slow robot {t('slow', 0, 1):.1f} -> "
        f"{t('slow', 0, 2):.1f} s ({t('slow', 0, 2) - t('slow', 0, 1):+.1f} s), with one fast "
        f"robot -> {t('slow', 1, 1):.1f} s ({t('slow', 1, 1) - t('slow', 0, 1):+.1f} s)."
    )
    same = [
        abs(t("fast", f, s) - t("slow", f, s))
        for f in range(1, 4)
        for s in range(1, 4)
        if math.isfinite(t("fast", f, s)) and math.isfinite(t("slow", f, s))
    ]
    if same:
        out.append(
            f"- Wherever fast and slow robots share circuit 0 (f, s >= 1), their task times "
            f"differ by at most {max(same):.1f} s: a fast robot that shares a station with a slow "
            "one ends up at the slow one's pace (it catches up during the 20 s loading and then "
            "waits behind it in the line, lap after lap), so speed pays only among robots of the "
            "same class."
        )
    out.append(
        f"- Three of a kind on circuit 0: 3 fast {t('fast', 3, 0):.1f} s per fast task, 3 slow "
        f"{t('slow', 0, 3):.1f} s per slow task."
    )
    return out


def plot(results: dict[str, Any], summary_rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 9.5))
    ax = axes[0, 0]
    for c, color in ((0, "tab:red"), (1, "tab:blue")):
        ns, ms, lo, hi = [], [], [], []
        for r in summary_rows:
            if (
                r["section"] == "t_n"
                and r["quantity"] == "mean task time (s)"
                and r["circuit"] == c
            ):
                ns.append(r["n_on_circuit"] + (c - 0.5) * 0.08)
                ms.append(r["mean"])
                lo.append(r["mean"] - r["ci95_low"] if math.isfinite(r["ci95_low"]) else 0)
                hi.append(r["ci95_high"] - r["mean"] if math.isfinite(r["ci95_high"]) else 0)
        ax.errorbar(ns, ms, yerr=[lo, hi], marker="o", capsize=4, color=color, label=f"circuit {c}")
    ax.set_xlabel("robots on the circuit, n")
    ax.set_ylabel("mean task time t(n) (s)")
    ax.set_title("Interference curve (dahl2004_homogeneous), 95% CI over seeds")
    ax.grid(alpha=0.3)
    ax.legend()

    ax = axes[0, 1]
    for c, color in ((0, "tab:red"), (1, "tab:blue")):
        xs, ms, lo, hi = [], [], [], []
        for r in summary_rows:
            if r["section"] == "t_ratio" and r["circuit"] == c:
                xs.append(r["n_on_circuit"] + (c - 0.5) * 0.08)
                ms.append(r["mean"])
                lo.append(r["mean"] - r["ci95_low"] if math.isfinite(r["ci95_low"]) else 0)
                hi.append(r["ci95_high"] - r["mean"] if math.isfinite(r["ci95_high"]) else 0)
        ax.errorbar(xs, ms, yerr=[lo, hi], marker="s", capsize=4, color=color, label=f"circuit {c}")
    ax.axhline(
        RATIO_REQUIREMENT, color="k", ls="--", lw=1, label=f"{RATIO_REQUIREMENT} (t(4)/t(3) req.)"
    )
    ax.axhline(1.0, color="gray", lw=0.8)
    ax.set_xlabel("n")
    ax.set_ylabel("t(n) / t(n-1)")
    ax.set_title("Marginal slow-down, 95% CI (log delta method)")
    ax.grid(alpha=0.3)
    ax.legend()

    cross = results["cross"]
    grids = {}
    for cls in ("fast", "slow"):
        grids[cls] = np.full((4, 4), np.nan)
        for (f, s), st in cross[(0, cls)].items():
            grids[cls][f, s] = st[0]
    vmin = np.nanmin([np.nanmin(g) for g in grids.values()])
    vmax = np.nanmax([np.nanmax(g) for g in grids.values()])
    for ax, cls in ((axes[1, 0], "fast"), (axes[1, 1], "slow")):
        mat = cross[(0, cls)]
        grid = grids[cls]
        im = ax.imshow(grid, origin="lower", cmap="viridis", vmin=vmin, vmax=vmax)
        for f in range(4):
            for s in range(4):
                st = mat.get((f, s))
                if st and math.isfinite(st[0]):
                    half = (st[2] - st[0]) if math.isfinite(st[2]) else math.nan
                    txt = f"{st[0]:.1f}" + (f"\n±{half:.1f}" if math.isfinite(half) else "")
                    ax.text(s, f, txt, ha="center", va="center", color="w", fontsize=9)
        ax.set_xticks(range(4))
        ax.set_yticks(range(4))
        ax.set_xlabel("slow robots on circuit 0, s")
        ax.set_ylabel("fast robots on circuit 0, f")
        ax.set_title(f"{cls.capitalize()} robot's task time on circuit 0 (s), dahl2004")
        fig.colorbar(im, ax=ax, shrink=0.8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--seeds", type=int, default=5, help="seeds per configuration (default 5)")
    p.add_argument("--hours", type=float, default=3.0, help="simulated hours per run (default 3)")
    add_sweep_options(p)
    p.add_argument("--warmup-min", type=float, default=10.0, help="warm-up, simulated minutes")
    p.add_argument("--skip-first", type=int, default=2, help="tasks discarded per robot")
    p.add_argument("--switch-every", type=int, default=3, help="switcher's block length (tasks)")
    p.add_argument("--out", type=Path, default=RESULTS_DIR, help="output directory")
    p.add_argument("--quick", action="store_true", help="smoke run: 2 seeds x 0.12 h")
    add_override_option(p)
    args = p.parse_args(argv)
    args.arena = tuple(sorted(parsed_overrides(p, args).items()))
    if args.quick:
        args.seeds, args.hours, args.warmup_min, args.skip_first = 2, 0.12, 0.5, 1
    args.seed_list = list(range(args.seeds))
    if args.switch_every < 2:
        p.error("--switch-every must be >= 2 (a block needs own-circuit tasks to compare with)")
    args.out.mkdir(parents=True, exist_ok=True)

    jobs = make_jobs(
        args.seed_list,
        args.hours,
        args.warmup_min * 60.0,
        args.skip_first,
        args.switch_every,
        args.arena,
    )
    # longest first, so the pool does not end on a lone straggler
    jobs.sort(key=lambda j: (j.experiment == "switch_lone", j.seed))
    runs_csv = CsvAppender(args.out / "interference_runs.csv", RUN_FIELDS)
    rows: list[dict[str, Any]] = []
    wall0 = time.perf_counter()

    def collect(job: Job, result: dict[str, Any], resumed: bool) -> None:
        for r in result["rows"]:
            runs_csv.write(r)
        rows.extend(result["rows"])

    run_jobs(
        jobs,
        RUNS,
        args.out / "cache" / "interference",
        workers=args.workers,
        on_done=collect,
        progress_bar=True,
        backend=args.backend,
    )
    runs_csv.close()
    wall = time.perf_counter() - wall0

    summary_rows, results = analyse(rows, args.seed_list, np.random.default_rng(12345))
    body = report(results, summary_rows, args)
    png = args.out / "interference.png"
    if have_matplotlib():
        plot(results, summary_rows, png)
        body += f"\n\n![interference]({png.name})\n"
    r43 = next(
        r
        for r in summary_rows
        if r["section"] == "t_ratio" and r["circuit"] == 0 and r["quantity"] == "t(4)/t(3)"
    )
    pooled = results["switch_pooled"]
    summary = {
        "t4_over_t3_circuit0": {k: r43[k] for k in ("mean", "ci95_low", "ci95_high")},
        "t4_over_t3_requirement": RATIO_REQUIREMENT,
        "t4_over_t3_pass": r43["mean"] >= RATIO_REQUIREMENT,
        "switch_relative_3p3_pooled": {k: pooled[k] for k in ("mean", "ci95_low", "ci95_high")},
        "switch_requirement": SWITCH_REQUIREMENT,
        "switch_pass": pooled["mean"] >= SWITCH_REQUIREMENT,
        "runs": len(jobs),
        "runs_per_experiment": {
            e: sum(1 for j in jobs if j.experiment == e)
            for e in ("t_n", "switch", "switch_lone", "cross")
        },
        "example_run": asdict(jobs[0]),
    }
    meta = run_metadata(
        wall_time_s=wall,
        settings={
            "seeds": args.seed_list,
            "hours": args.hours,
            "warmup_min": args.warmup_min,
            "skip_first": args.skip_first,
            "switch_every": args.switch_every,
            "workers": args.workers,
            "arena_overrides": dict(args.arena),
        },
    )
    fields = [
        "section",
        "quantity",
        "preset",
        "circuit",
        "n_on_circuit",
        "n_fast_on_circuit",
        "n_slow_on_circuit",
        "robot_class",
        "mean",
        "ci95_low",
        "ci95_high",
        "n_seeds",
        "n_tasks",
        "bootstrap_low",
        "bootstrap_high",
    ]
    paths = write_results(
        args.out,
        "interference",
        summary_rows,
        body,
        meta,
        "Interference benchmark",
        summary,
        fields,
    )
    print(body.split("## Method")[0])
    print(f"wrote {paths['md']} ({wall:.0f} s wall)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
