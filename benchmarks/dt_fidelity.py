"""Does the physics time step change the results? Task times and the interference curve at several dt.

For each physics step `dt` (default 0.05, 0.1, 0.2 and 0.25 s) and each seed:

1. the interference curve t(n), n = 1..6, of the homogeneous arena (`dahl2004_homogeneous`, fixed
   allocations, exactly the runs of `interference.py`'s first experiment);
2. the mean task time of fast and of slow robots in `dahl2004` under random allocation.

Each quantity at each dt is compared with the finest step (a ratio of seed means with a 95 %
interval, `_common.ratio_ci`); a step passes when every quantity is within `--tolerance` (3 %) of
the finest. The package's default step is the largest that passes. Outputs in
`benchmarks/results/dt_fidelity/`: `dt_fidelity.{md,csv,json}`; runs are kept in `cache/` as they
finish, so a rerun resumes.

    python benchmarks/dt_fidelity.py
    python benchmarks/dt_fidelity.py --quick
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from _common import (
    RESULTS_DIR,
    add_sweep_options,
    fmt_ci,
    markdown_table,
    mean_ci,
    ratio_ci,
    run_metadata,
    write_results,
)
from interference import HOMOG, Job, run_job_rows

from agents.allocators.baselines import RandomAllocator
from agents.experiments.estimation import measured_rate
from agents.experiments.runner import run_trial
from agents.experiments.sweep import json_jobs, run_jobs
from tavc_env import make_config

QUANTITIES = [f"t({n})" for n in range(1, 7)] + ["t fast (random)", "t slow (random)"]


@dataclass(frozen=True)
class Run:
    kind: str  # "t_n" (one fixed allocation of the homogeneous arena) or "random"
    dt: float
    seed: int
    hours: float
    n_on_0: int = 0  # t_n: robots on circuit 0 (the rest on circuit 1)


def run(job: Run) -> dict[str, Any]:
    """One run's task times: per circuit group (t_n) or per speed class (random)."""
    if job.kind == "t_n":
        alloc = tuple([0] * job.n_on_0 + [1] * (6 - job.n_on_0))
        rows = run_job_rows(
            Job("t_n", HOMOG, alloc, job.seed, job.hours, 600.0, 2, arena=(("dt", job.dt),))
        )["rows"]
        return {
            "t_n": [
                [r["n_on_circuit"], r["n_tasks"], r["mean_task_time_s"]]
                for r in rows
                if r["robot_class"] == "all" and r["task_kind"] == "own"
            ]
        }
    result = run_trial(
        lambda agent: RandomAllocator(),
        seed=job.seed,
        convergence_s=600.0,
        measured_s=job.hours * 3600.0,
        preset="dahl2004",
        dt=job.dt,
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


RUNS = json_jobs(
    run,
    lambda j: f"{j.kind}_dt{j.dt:g}_n{j.n_on_0}_s{j.seed}_{j.hours:g}h",
    unit="run",
)


def per_seed_values(results: dict[str, dict[str, Any]], jobs: Sequence[Run], dt: float, seeds):
    """Quantity -> one value per seed at step `dt`."""
    values: dict[str, list[float]] = {q: [] for q in QUANTITIES}
    for seed in seeds:
        pooled: dict[int, list[tuple[int, float]]] = {}
        for j in jobs:
            if j.dt != dt or j.seed != seed:
                continue
            r = results[RUNS.key(j)]
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dts", type=float, nargs="+", default=[0.05, 0.1, 0.2, 0.25])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--hours", type=float, default=3.0, help="simulated hours per run")
    parser.add_argument("--tolerance", type=float, default=0.03)
    parser.add_argument("--out", type=Path, default=RESULTS_DIR / "dt_fidelity")
    parser.add_argument("--quick", action="store_true", help="2 seeds x 0.3 h (smoke run)")
    add_sweep_options(parser)
    args = parser.parse_args(argv)
    if args.quick:
        args.seeds, args.hours = 2, 0.3
    if args.seeds < 2:
        parser.error(f"--seeds = {args.seeds}; allowed: >= 2 (for confidence intervals)")
    for dt in args.dts:
        try:
            make_config("dahl2004", dt=dt)
        except ValueError as error:
            parser.error(f"--dts: {error}")
    dts = sorted(args.dts)
    seeds = list(range(args.seeds))
    jobs = [Run("t_n", dt, s, args.hours, k) for dt in dts for s in seeds for k in range(7)]
    jobs += [Run("random", dt, s, args.hours) for dt in dts for s in seeds]
    # the finest steps are the slowest: start them first so the pool does not end on them
    jobs.sort(key=lambda j: j.dt)
    meta = run_metadata(settings={k: str(v) for k, v in vars(args).items() if k != "workers"})
    started = time.perf_counter()
    results = run_jobs(
        jobs,
        RUNS,
        args.out / "cache",
        workers=args.workers,
        progress_bar=True,
        backend=args.backend,
    )

    reference = dts[0]
    ref = per_seed_values(results, jobs, reference, seeds)
    rows: list[dict[str, Any]] = []
    passes: dict[float, bool] = {}
    for dt in dts:
        vals = per_seed_values(results, jobs, dt, seeds)
        ok = True
        for q in QUANTITIES:
            m, lo, hi, _ = mean_ci(vals[q])
            ratio = ratio_ci(vals[q], ref[q]) if dt != reference else (1.0, 1.0, 1.0)
            within = abs(ratio[0] - 1.0) <= args.tolerance
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
    chosen = max(dt for dt, ok in passes.items() if ok)
    header = ["quantity", *(f"dt = {dt:g} s" for dt in dts)]
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
    body = "\n".join(
        [
            f"{args.seeds} seeds x {args.hours:g} simulated h per run; task times in seconds, mean "
            f"[95 % CI] over seeds; in brackets the difference from the finest step "
            f"({reference:g} s). Tolerance {100 * args.tolerance:g} %.",
            "",
            markdown_table(header, table),
            "",
            "Within tolerance at every quantity: "
            + ", ".join(f"dt = {dt:g} s: {'yes' if ok else 'no'}" for dt, ok in passes.items())
            + f". Largest passing step: **{chosen:g} s**.",
        ]
    )
    meta["wall_time_s"] = time.perf_counter() - started
    write_results(
        args.out,
        "dt_fidelity",
        rows,
        body,
        meta,
        "Physics time step and fidelity",
        {"passes": {str(k): v for k, v in passes.items()}, "largest_passing_dt": chosen},
    )
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
