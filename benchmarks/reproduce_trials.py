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
from pathlib import Path
from typing import Any

import numpy as np

from agents.experiments.runner import Event, TrialResult
from agents.experiments.sweep import TrialSpec, run_spec

IGNORED = ("wall_s", "spec")  # wall-clock time; the spec itself is what is re-run


def comparable(result: TrialResult, fields: set[str]) -> Any:
    data = {k: v for k, v in result.to_dict().items() if k in fields and k not in IGNORED}
    return json.loads(json.dumps(data))


def check(path: str) -> tuple[str, bool, int]:
    stored_data = json.loads(Path(path).read_text())
    stored = TrialResult.from_dict(stored_data)
    if not stored.spec:
        raise ValueError(
            f"{path} has no stored spec; allowed: trials saved by agents.experiments.sweep"
        )
    spec = {k: v for k, v in stored.spec.items() if k != "arena"}  # a digest, not an argument
    spec["events"] = tuple(Event(**e) for e in spec.get("events", ()))
    fresh = run_spec(TrialSpec(**spec))
    # fields added to trial records after this one was saved are not compared
    fields = set(stored_data)
    return path, comparable(stored, fields) == comparable(fresh, fields), fresh.escapes


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
