"""What every study shares: the sweep options of its settings, `KEY=VALUE` arena overrides, the
default results folder, and running its trials with their provenance recorded.

A study module defines a frozen `Settings` dataclass (the study's command line, through
`parse_settings`, and what its report records), the trials it runs, and the report it writes.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

import tyro

from agents.experiments.provenance import PACKAGE_ROOT, run_recorded
from agents.experiments.runner import TrialResult
from agents.experiments.sweep import TRIALS, TrialSpec

RESULTS_DIR = PACKAGE_ROOT / "benchmarks" / "results"

Overrides = Annotated[tuple[str, ...], tyro.conf.UseAppendAction]
"""The type of a study's `set` field: arena overrides `KEY=VALUE`, one per `--set` (repeatable)."""


@dataclass(frozen=True, kw_only=True)
class SweepOptions:
    """How a study's jobs run; not part of what it measures, so not recorded as a setting."""

    workers: int | None = None
    """processes, or Ray CPUs (default: all cores)"""
    backend: Literal["local", "ray"] = "local"
    """local process pool, or Ray tasks (pip install 'tavc-env[ray]'; set RAY_ADDRESS to use a
    cluster); results and resume are the same either way"""
    out: Path | None = None
    """output folder (default: under benchmarks/results/)"""

    def __post_init__(self) -> None:
        if self.workers is not None and (not isinstance(self.workers, int) or self.workers < 1):
            raise ValueError(f"workers = {self.workers!r} is invalid; allowed: an integer >= 1")


def parse_key_values(items: Sequence[str], option: str, example: str) -> dict[str, Any]:
    """`KEY=VALUE` items (as given to `option`) as a dict: values that parse as JSON (numbers,
    true/false, lists) are used as such, anything else as a string; whoever receives them then
    names any key or value it does not accept. A ValueError shows `example` for a malformed one."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise ValueError(f"{option} {item!r} is invalid; allowed: KEY=VALUE, e.g. {example}")
        try:
            out[key] = json.loads(text)
        except json.JSONDecodeError:
            out[key] = text
    return out


def arena_overrides(items: Sequence[str]) -> dict[str, Any]:
    """Arena overrides from `--set KEY=VALUE` items; the arena's own validation then names any
    key or value it rejects."""
    return parse_key_values(items, "--set", "source_service_s=15")


@dataclass
class Outcome:
    """What running a study left: the folder it wrote, the files, and the text to print (the
    results table a person reads first)."""

    out_dir: Path
    written: list[Path]
    text: str


S = TypeVar("S")


def parse_settings(settings_type: type[S], argv: Sequence[str] | None, description: str) -> S:
    """The settings of a study from a command line (`argv`, default: sys.argv[1:]): one option
    per field, its help from the field's docstring; `--set` (an `Overrides` field) repeats. A
    setting its `__post_init__` refuses is a usage error that names it."""
    return tyro.cli(settings_type, args=argv, description=description)


def replace(settings: S, **changes: Any) -> S:
    """`settings` with some fields changed (validated again)."""
    return dataclasses.replace(settings, **changes)  # type: ignore[type-var]


def run_trials(
    specs: Sequence[TrialSpec],
    out_dir: Path,
    options: SweepOptions,
    recorded_settings: Mapping[str, Any],
) -> tuple[dict[str, TrialResult], dict[str, Any]]:
    """Run (or resume) `specs` with a progress bar, each trial saved under `out_dir`/trials as it
    finishes; return the results by key and their provenance (see
    `agents.experiments.provenance.run_recorded`)."""
    return run_recorded(
        specs,
        TRIALS,
        out_dir / "trials",
        out_dir,
        recorded_settings,
        workers=options.workers,
        backend=options.backend,
        wall_of=lambda result: result.wall_s,
    )
