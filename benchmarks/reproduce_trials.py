"""Re-run saved trials from their stored settings and check that they come out bit for bit the same.

Compares everything a trial recorded (timeline, deliveries, Q snapshots, counters; not the
wall-clock time). Exit status 1 if any trial differs.

    python benchmarks/reproduce_trials.py benchmarks/results/table1_dahl2004_scaled/trials/*.json
    python benchmarks/reproduce_trials.py --sample 4 --seed 1 'benchmarks/results/*/trials/*.json'

Re-run saved trials from their stored settings and check that they come out bit for bit the same.

Every trial a sweep saves carries the `TrialSpec` it was run from. This re-runs those specs with
the code checked out now and compares everything the trial recorded (timeline, deliveries, Q
snapshots, counters; not the wall-clock time). Use it to check that a change of code or machine
leaves saved results reproducible. Trials packed into their folder's `pack.jsonl`
(`tavc_agents.experiments.packs`) are found and named by the path their own file would have.

    python benchmarks/reproduce_trials.py benchmarks/results/table1_dahl2004_scaled/trials/*.json
    python benchmarks/reproduce_trials.py --sample 4 --seed 1 'benchmarks/results/*/trials/*.json'
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import tyro

from tavc_agents.experiments.files import RECORD_MAX_BYTES, read_bytes
from tavc_agents.experiments.packs import read_saved, saved_paths
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import Outcome, parse_settings
from tavc_agents.experiments.sweep import TrialSpec, run_spec, spec_from_record

IGNORED = ("wall_s", "spec")  # wall-clock time; the spec itself is what is re-run


@dataclass(frozen=True, kw_only=True)
class Settings:
    """Which saved trials to re-run."""

    patterns: Annotated[tuple[str, ...], tyro.conf.Positional]
    """trial JSON files or glob patterns (packed trials match as their own files would)"""
    sample: int | None = None
    """check only this many, drawn at random"""
    seed: int = 0
    """seed of the random sample"""
    workers: int = 2
    """processes"""

    def __post_init__(self) -> None:
        if not self.patterns:
            raise ValueError("patterns = () is invalid; allowed: one or more files or globs")
        if self.sample is not None and self.sample < 1:
            raise ValueError(f"sample = {self.sample} is invalid; allowed: an integer >= 1")
        if self.workers < 1:
            raise ValueError(f"workers = {self.workers} is invalid; allowed: an integer >= 1")

    def paths(self) -> list[str]:
        """The matching trial files (a random sample of them, with `sample`). Files that are not
        whole trials are left out: manifests and the compact per-trial records of studies such
        as the liveness check and the regime map (which keep measures, not trajectories)."""
        matched = {p for pattern in self.patterns for p in saved_paths(pattern)}
        paths = sorted(p for p in matched if p.endswith(".json") and not _compact_record(p))
        if not paths:
            raise ValueError(
                f"patterns = {list(self.patterns)} match no whole trial file "
                f"({len(matched)} files matched); allowed: trial files saved by tavc_agents.experiments"
            )
        if self.sample is not None and self.sample < len(paths):
            rng = np.random.default_rng(self.seed)
            paths = sorted(rng.choice(paths, size=self.sample, replace=False).tolist())
        return paths


def _compact_record(path: str) -> bool:
    """Whether `path` holds a study's compact record ({"record": ..., "result": ...})."""
    if not os.path.lexists(path):  # packed
        return list(read_saved(path))[:1] == ["record"]
    return read_bytes(path, RECORD_MAX_BYTES, "saved record")[:11] == b'{"record": '


def comparable(result: TrialResult, fields: set[str]) -> Any:
    data = {k: v for k, v in result.to_dict().items() if k in fields and k not in IGNORED}
    return json.loads(json.dumps(data))


def spec_of(stored: TrialResult, path: str) -> TrialSpec:
    """The spec a saved trial was run from."""
    if not stored.spec:
        raise ValueError(
            f"{path} has no stored spec; allowed: trials saved by tavc_agents.experiments"
        )
    return spec_from_record(stored.spec)


def check(path: str) -> tuple[str, bool, int]:
    """(path, whether a fresh run equals the saved one, escapes in the fresh run)."""
    stored_data = read_saved(path)
    stored = TrialResult.from_dict(stored_data)
    fresh = run_spec(spec_of(stored, path))
    # fields added to trial records after this one was saved are not compared
    fields = set(stored_data)
    return path, comparable(stored, fields) == comparable(fresh, fields), fresh.escapes


def check_all(paths: Sequence[str], workers: int) -> list[tuple[str, bool, int]]:
    with ProcessPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(check, paths))


def run(settings: Settings) -> Outcome:
    """Check every selected trial; the text ends with how many reproduced."""
    paths = settings.paths()
    lines = []
    differ = 0
    for path, same, escapes in check_all(paths, settings.workers):
        differ += not same
        lines.append(f"{'IDENTICAL' if same else 'DIFFERENT'}  {path}  (escapes now: {escapes})")
    lines.append(f"{len(paths) - differ} of {len(paths)} trials reproduced bit for bit")
    return Outcome(Path("."), [], "\n".join(lines))


def all_reproduced(outcome: Outcome) -> bool:
    last = outcome.text.splitlines()[-1].split()
    return last[0] == last[2]


def main(argv: Sequence[str] | None = None) -> int:
    """The command line: it writes nothing, so it runs without a study's output folder; the exit
    status is 1 if any trial differs."""
    outcome = run(parse_settings(Settings, argv, __doc__ or ""))
    print(outcome.text)
    return 0 if all_reproduced(outcome) else 1


if __name__ == "__main__":
    raise SystemExit(main())
