"""One decisive cell of the committed regime map recomputed from nothing: how long it takes now, and
whether every trial comes out as committed.

Runs the cell's trials (default `dahl2004`, softmax TAVC at T = 0.005: 400 physics trials of
15 h + 5 h) through the regime map's own jobs into a temporary folder on `--workers` processes,
times the whole sweep (wall clock, with the machine's load average before and after: the pool's
workers are not this process's children, so their CPU time is not read here), and compares
each trial's record with the committed one in `benchmarks/results/regime_map/trials/` (every
measure but the trial's own wall time; NaN equals NaN). Writes `regime_cell.{md,json}` into
`--out` (default: benchmarks/results/regime_cell/).

    python benchmarks/regime_cell.py                      # 400 trials, 2 workers
    python benchmarks/regime_cell.py --trials 20          # a quick look
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import arena_runs
from tavc_agents.experiments.files import write_text
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.study import RESULTS_DIR
from tavc_agents.experiments.sweep import run_jobs, saved_results


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--arena", default="dahl2004", choices=sorted(arena_runs.MAPPED))
    parser.add_argument(
        "--condition", default="softmax_T0.005", choices=sorted(arena_runs.CONDITIONS)
    )
    parser.add_argument("--trials", type=int, default=400, help="trials 0..N-1 of the cell")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=RESULTS_DIR / "regime_cell")
    args = parser.parse_args(argv)
    if not 1 <= args.trials <= 400 or args.workers < 1:
        parser.error(
            f"--trials {args.trials} / --workers {args.workers} is invalid; allowed: trials in "
            "1..400 (the committed cells' size), workers >= 1"
        )
    committed = RESULTS_DIR / "regime_map"
    kept = arena_runs.Settings(out=committed)
    jobs = [
        arena_runs.MapTrial(
            args.arena,
            args.condition,
            kept.seed + k,
            kept.convergence_h,
            kept.measured_h,
            arena_sha=arena_runs.digest(args.arena),
        )
        for k in range(args.trials)
    ]
    reference = saved_results(jobs, arena_runs.TRIALS, committed / "trials")
    if len(reference) < len(jobs):
        parser.error(f"the committed regime map has {len(reference)} of these {len(jobs)} trials")
    with tempfile.TemporaryDirectory(prefix="regime-cell-") as tmp:
        load_before, wall0 = os.getloadavg(), time.perf_counter()
        results = run_jobs(jobs, arena_runs.TRIALS, tmp, args.workers, progress_bar=True)
        wall, load_after = time.perf_counter() - wall0, os.getloadavg()
    differ = [
        key
        for key, result in results.items()
        if not all(_same(v, reference[key][k]) for k, v in result.items() if k != "wall_s")
    ]
    found = {
        "arena": args.arena,
        "condition": args.condition,
        "trials": len(jobs),
        "workers": args.workers,
        "wall_s": round(wall, 1),
        "load_average_before": load_before,
        "load_average_after": load_after,
        "identical_to_committed": len(jobs) - len(differ),
        "differ": differ,
        "metadata": run_metadata(),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "regime_cell.json", json.dumps(found, indent=2) + "\n")
    text = (
        f"# One regime-map cell recomputed\n\n`{args.arena}`, {args.condition}: {len(jobs)} "
        f"physics trials of {kept.convergence_h:g} h + {kept.measured_h:g} h on {args.workers} "
        f"workers took **{wall / 60:.1f} min** wall (1-minute load average {load_before[0]:.1f} "
        f"before, {load_after[0]:.1f} after). **{found['identical_to_committed']} "
        f"of {len(jobs)} trials are identical** to the committed ones in every measure but their "
        "wall time.\n\nCommand: `python benchmarks/regime_cell.py"
        + "".join(f" {a}" for a in (sys.argv[1:] if argv is None else argv))
        + f"`; commit `{found['metadata']['git'].get('commit')}`.\n"
    )
    write_text(args.out / "regime_cell.md", text)
    print(text)
    return 0 if not differ else 1


if __name__ == "__main__":
    raise SystemExit(main())
