"""Re-run saved trials from their stored settings and check that they come out bit for bit the same.

Every trial a sweep saves carries the `TrialSpec` it was run from. This script runs those specs
again with the code checked out now and compares everything the trial recorded (timeline,
deliveries, Q snapshots, counters; not the wall-clock time). Use it to check that a change of code
or machine leaves saved results reproducible.

    python benchmarks/reproduce_trials.py benchmarks/results/table1_dahl2004_scaled/trials/*.json
    python benchmarks/reproduce_trials.py --sample 4 --seed 1 'benchmarks/results/*/trials/*.json'

Exit status 1 if any trial differs.
"""

from __future__ import annotations

import argparse
import glob
import json
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from agents.runner import TrialResult
from agents.sweep import TrialSpec, run_spec

IGNORED = ("wall_s", "spec")  # wall-clock time; the spec itself is what is re-run


def comparable(result: TrialResult) -> Any:
    data = result.to_dict()
    for key in IGNORED:
        data.pop(key, None)
    return json.loads(json.dumps(data))


def check(path: str) -> tuple[str, bool, int]:
    stored = TrialResult.load(path)
    if not stored.spec:
        raise ValueError(f"{path} has no stored spec; allowed: trials saved by agents.sweep")
    fresh = run_spec(TrialSpec(**stored.spec))
    return path, comparable(stored) == comparable(fresh), fresh.escapes


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("patterns", nargs="+", help="trial JSON files or glob patterns")
    ap.add_argument(
        "--sample", type=int, default=None, help="check only this many, drawn at random"
    )
    ap.add_argument("--seed", type=int, default=0, help="seed of the random sample")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    paths = sorted({p for pattern in args.patterns for p in glob.glob(pattern)})
    if not paths:
        ap.error(f"no trial files match {args.patterns}")
    if args.sample is not None and args.sample < len(paths):
        rng = np.random.default_rng(args.seed)
        paths = sorted(rng.choice(paths, size=args.sample, replace=False).tolist())
    differ = 0
    with ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        for path, same, escapes in pool.map(check, paths):
            differ += not same
            print(f"{'IDENTICAL' if same else 'DIFFERENT'}  {path}  (escapes now: {escapes})")
    print(f"{len(paths) - differ} of {len(paths)} trials reproduced bit for bit")
    return 1 if differ else 0


if __name__ == "__main__":
    raise SystemExit(main())
