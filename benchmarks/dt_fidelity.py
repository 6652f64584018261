"""Does the physics time step change the results? Task times and the interference curve at several dt.

For each physics step `dt` (default 0.05, 0.1, 0.2 and 0.25 s) and each seed:

1. the interference curve t(n), n = 1..6, of the homogeneous arena (`dahl2004_homogeneous`, fixed
   allocations, exactly the runs of `interference.py`'s first experiment);
2. the mean task time of fast and of slow robots in `dahl2004` under random allocation.

Each quantity at each dt is compared with the finest step (a ratio of seed means with a 95 %
interval, `tavc_agents.analysis.stats.ratio_ci`); a step passes when every quantity is within
`--tolerance` (3 %) of the finest. The package's default step is the largest that passes. Outputs
in `benchmarks/results/dt_fidelity/` (the committed reference; a run writes into a new `runs/` folder unless `--update-reference` or `--out`): `dt_fidelity.{md,csv,json}`; runs are kept in
`cache/` as they finish, so `--resume RUN_DIR` continues an interrupted run.

    python benchmarks/dt_fidelity.py            # 160 runs of 3 simulated h, ~4 min on 2 cores
    python benchmarks/dt_fidelity.py --quick

Does the physics time step change the results? The interference curve t(n) of the homogeneous
arena (fixed allocations, the runs of the interference study's first experiment) and the task
times of fast and slow robots under random allocation, at several steps `dt`, each compared with
the finest step. The script is `benchmarks/dt_fidelity.py`.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from arena_analysis import group_rows
from arena_runs import measured_rate
from tavc_agents.allocators.baselines import RandomAllocator
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci, ratio_ci
from tavc_agents.experiments.runner import run_trial
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import json_jobs
from tavc_env import make_config
from tavc_env.measurement import FixedAllocation, run_fixed, two_circuit_allocation

HOMOG = "dahl2004_homogeneous"
QUANTITIES = [f"t({n})" for n in range(1, 7)] + ["t fast (random)", "t slow (random)"]
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The time-step study's settings (its command line)."""

    reference: ClassVar = "dt_fidelity"
    quick_reference_apart: ClassVar = False
    quick_sizes: ClassVar = {"seeds": 2, "hours": 0.3}
    recorded_as_text: ClassVar = True
    recorded_fields: ClassVar = "dts seeds hours tolerance out=out_text quick backend"

    dts: tuple[float, ...] = (0.05, 0.1, 0.2, 0.25)
    """physics steps to compare (s); the finest is the reference"""
    seeds: int = 5
    """seeds per step and configuration"""
    hours: float = 3.0
    """simulated hours per run"""
    tolerance: float = 0.03
    """largest relative difference from the finest step that passes"""
    quick: bool = False
    """2 seeds x 0.3 h (smoke run)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            ("seeds", at_least(self.seeds, 2), ">= 2 (for intervals)"),
            ("hours", positive(self.hours), "> 0"),
            ("tolerance", positive(self.tolerance), "> 0"),
            ("dts", len(self.dts) >= 1, "one or more steps"),
        ]
        refuse_invalid(self, checks)
        for dt in self.dts:
            try:
                make_config("dahl2004", dt=dt)
            except ValueError as error:
                raise ValueError(f"dts = {list(self.dts)!r} is invalid: {error}") from None


@dataclass(frozen=True)
class Run:
    """One run: "t_n" (a fixed allocation of the homogeneous arena, `n_on_0` robots on circuit 0)
    or "random" (random allocation in `dahl2004`)."""

    kind: str
    dt: float
    seed: int
    hours: float
    n_on_0: int = 0


def _t_n_run(job: Run) -> dict[str, Any]:
    alloc = FixedAllocation(
        preset=HOMOG,
        circuit_of=two_circuit_allocation(job.n_on_0),
        seed=job.seed,
        hours=job.hours,
        warmup_s=600.0,
        skip_first=2,
        arena=(("dt", job.dt),),
    )
    rows = group_rows(run_fixed(alloc), "t_n", "")
    return {
        "t_n": [
            [r["n_on_circuit"], r["n_tasks"], r["mean_task_time_s"]]
            for r in rows
            if r["robot_class"] == "all" and r["task_kind"] == "own"
        ]
    }


def _random_run(job: Run) -> dict[str, Any]:
    result = run_trial(
        lambda agent: RandomAllocator(),
        seed=job.seed,
        convergence_s=600.0,
        measured_s=job.hours * 3600.0,
        arena={"preset": "dahl2004", "dt": job.dt},
    )
    t0, t1 = result.measured_window
    classes = np.array(result.speed_classes)[result.delivery_robot]
    times = np.asarray(result.delivery_task_time_s)
    when = np.asarray(result.delivery_time_s)
    inside = (when >= t0) & (when < t1)
    return {
        "fast": float(times[inside & (classes == "fast")].mean()),
        "slow": float(times[inside & (classes == "slow")].mean()),
        "tasks_per_h": 3600.0 * measured_rate(result),
    }


def run_one(job: Run) -> dict[str, Any]:
    """One run's task times: per circuit group (t_n) or per speed class (random)."""
    return _t_n_run(job) if job.kind == "t_n" else _random_run(job)


def run_key(job: Run) -> str:
    return f"{job.kind}_dt{job.dt:g}_n{job.n_on_0}_s{job.seed}_{job.hours:g}h"


RUNS = json_jobs(run_one, run_key, unit="run")


def make_jobs(s: Settings) -> list[Run]:
    """Seven allocations and one random run per step and seed, the finest steps (the slowest)
    first so the pool does not end on them."""
    dts, seeds = sorted(s.dts), range(s.seeds)
    jobs = [Run("t_n", dt, seed, s.hours, k) for dt in dts for seed in seeds for k in range(7)]
    jobs += [Run("random", dt, seed, s.hours) for dt in dts for seed in seeds]
    jobs.sort(key=lambda j: j.dt)
    return jobs


def per_seed_values(
    results: Mapping[str, dict[str, Any]], jobs: Sequence[Run], dt: float, seeds: Sequence[int]
) -> dict[str, list[float]]:
    """Quantity -> one value per seed at step `dt` (t(n): task-weighted over the runs with n
    robots on a circuit)."""
    values: dict[str, list[float]] = {q: [] for q in QUANTITIES}
    for seed in seeds:
        pooled: dict[int, list[tuple[int, float]]] = {}
        for j in jobs:
            if j.dt != dt or j.seed != seed:
                continue
            r = results[run_key(j)]
            if j.kind == "t_n":
                for n, count, mean in r["t_n"]:
                    pooled.setdefault(int(n), []).append((count, mean))
            else:
                values["t fast (random)"].append(r["fast"])
                values["t slow (random)"].append(r["slow"])
        for n in range(1, 7):
            groups = pooled.get(n, [])
            total = sum(c for c, _ in groups)
            values[f"t({n})"].append(sum(c * m for c, m in groups) / total if total else math.nan)
    return values


def compare(
    values: Mapping[float, dict[str, list[float]]], tolerance: float
) -> tuple[list[Row], dict[float, bool]]:
    """Rows of every quantity at every step with its ratio to the finest step, and whether each
    step is within `tolerance` at every quantity."""
    dts = sorted(values)
    reference = dts[0]
    rows: list[Row] = []
    passes: dict[float, bool] = {}
    for dt in dts:
        ok = True
        for q in QUANTITIES:
            m, lo, hi, _ = mean_ci(values[dt][q])
            ratio = ratio_ci(values[dt][q], values[reference][q]) if dt != reference else (1.0,) * 3
            within = abs(ratio[0] - 1.0) <= tolerance
            ok &= within
            rows.append(
                {
                    "dt": dt,
                    "quantity": q,
                    "mean_s": m,
                    "low_s": lo,
                    "high_s": hi,
                    "ratio_to_finest": ratio[0],
                    "ratio_low": ratio[1],
                    "ratio_high": ratio[2],
                    "within_tolerance": within,
                }
            )
        passes[dt] = ok
    return rows, passes


def largest_passing(passes: Mapping[float, bool]) -> float:
    """The largest step within tolerance (the finest always is: it is the reference)."""
    return max(dt for dt, ok in passes.items() if ok)


def report_body(rows: Sequence[Row], passes: Mapping[float, bool], s: Settings) -> str:
    dts = sorted(passes)
    reference = dts[0]
    chosen = largest_passing(passes)
    table = []
    for q in QUANTITIES:
        cells = [q]
        for dt in dts:
            r = next(x for x in rows if x["dt"] == dt and x["quantity"] == q)
            cell = fmt_ci(r["mean_s"], r["low_s"], r["high_s"], 1)
            if dt != reference:
                cell += f" ({100 * (r['ratio_to_finest'] - 1):+.1f} %)"
            cells.append(cell)
        table.append(cells)
    return "\n".join(
        [
            f"{s.seeds} seeds x {s.hours:g} simulated h per run; task times in seconds, mean "
            f"[95 % CI] over seeds; in brackets the difference from the finest step "
            f"({reference:g} s). Tolerance {100 * s.tolerance:g} %.",
            "",
            markdown_table(["quantity", *(f"dt = {dt:g} s" for dt in dts)], table),
            "",
            "Within tolerance at every quantity: "
            + ", ".join(f"dt = {dt:g} s: {'yes' if ok else 'no'}" for dt, ok in passes.items())
            + f". Largest passing step: **{chosen:g} s**.",
        ]
    )


def run(settings: Settings) -> Outcome:
    """Run (or resume) every run, compare each step with the finest, write the report."""
    out = settings.out_dir()
    s = settings.sized()
    jobs = make_jobs(s)
    # the provenance of the runs stays with them
    results, provenance = settings.run_jobs(jobs, RUNS, "cache", provenance_in="cache")
    seeds = list(range(s.seeds))
    values = {dt: per_seed_values(results, jobs, dt, seeds) for dt in sorted(s.dts)}
    rows, passes = compare(values, s.tolerance)
    body = report_body(rows, passes, s)
    summary = {
        "passes": {str(k): v for k, v in passes.items()},
        "largest_passing_dt": largest_passing(passes),
    }
    report = Report("dt_fidelity", "Physics time step and fidelity", body, rows, summary)
    written = report.write(out, provenance)
    return Outcome(out, written, body)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
