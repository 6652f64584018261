"""Per-trial reproduction: re-run a random sample of a study's trials from scratch and compare each
one's fresh `trials.csv` row with the saved one, cell by cell as written.

A study whose `trials.csv` rows carry what rebuilds their trial (seed, condition) offers a
`reproduce_rows(settings, sample, seed)` built from these pieces.
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tavc_agents.analysis.reports import write_csv
from tavc_agents.experiments.files import read_csv
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.sweep import TrialSpec, run_sweep


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV, as text."""
    return list(read_csv(path))


def sample_rows(path: Path, sample: int, seed: int) -> list[dict[str, str]]:
    """`sample` rows of the CSV at `path`, drawn without replacement with `seed`, in file order."""
    rows = read_rows(path)
    if not 1 <= sample <= len(rows):
        raise ValueError(f"sample = {sample!r} is invalid; allowed: 1 to {len(rows)} ({path})")
    chosen = np.random.default_rng(seed).choice(len(rows), size=sample, replace=False)
    return [rows[int(k)] for k in sorted(chosen)]


def run_fresh(specs: Sequence[TrialSpec], workers: int | None) -> dict[str, TrialResult]:
    """Run `specs` from scratch (in a temporary folder, nothing resumed); results by key."""
    with tempfile.TemporaryDirectory() as tmp:
        return run_sweep(specs, tmp, workers=workers, progress_bar=True)


def as_written(rows: Sequence[Mapping[str, Any]], fields: Sequence[str]) -> list[dict[str, str]]:
    """`rows` as `write_csv` writes them under the columns `fields`, read back as text."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rows.csv"
        write_csv(path, rows, fields)
        return read_rows(path)


def compare_rows(
    fresh: Sequence[Mapping[str, Any]], saved: Sequence[Mapping[str, str]]
) -> list[bool]:
    """Whether each fresh row has the saved columns and, written as the CSV writes it, equals
    its saved row exactly."""
    if not saved:
        return []
    fields = list(saved[0])
    written = as_written(fresh, fields)
    return [
        list(row) == fields and new == dict(old)
        for row, new, old in zip(fresh, written, saved, strict=True)
    ]
