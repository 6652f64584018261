"""What every study shares: the sweep options of its settings (where it writes: a new run folder by
default, never the committed reference results unless asked), `KEY=VALUE` arena overrides,
running its trials with their provenance recorded, and the command line every benchmark script
and `tavc bench` share (`run_study`).

A study module defines a frozen `Settings` dataclass (the study's command line, through
`parse_settings`, and what its report records), the trials it runs, and the report it writes.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as _dt
import json
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Annotated, Any, Literal, TypeVar

import tyro

from tavc_agents.experiments.provenance import CHECKOUT, run_recorded
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.sweep import TRIALS, TrialSpec
from tavc_env._validation import is_integer, is_number

RESULTS_DIR = (CHECKOUT or Path()) / "benchmarks" / "results"
"""The committed reference results of the source checkout (changed only with `--update-reference`).
An installed wheel has none: then `benchmarks/results` under the working directory, which a run
only reads (to compare its tables with, if it exists), as `RUNS_DIR` is relative to it too."""
RUNS_DIR = Path("runs")
"""Where a study writes by default: `runs/<study>-<UTC time>/` under the working directory
(ignored by git in a checkout)."""

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
    """output folder (default: a new run folder runs/<study>-<time>/, which git ignores)"""
    resume: Path | None = None
    """continue an unfinished run in its folder (trials already saved there are not rerun)"""
    update_reference: bool = False
    """write into the committed reference results (benchmarks/results/...) instead of a run folder"""
    run_dir: tyro.conf.Suppress[Path | None] = None
    """the new run folder, chosen once when the settings are made (none with --out, --resume or
    --update-reference)"""

    def __post_init__(self) -> None:
        if self.workers is not None and (not isinstance(self.workers, int) or self.workers < 1):
            raise ValueError(f"workers = {self.workers!r} is invalid; allowed: an integer >= 1")
        given = [
            name
            for name, value in (
                ("--out", self.out),
                ("--resume", self.resume),
                ("--update-reference", self.update_reference or None),
            )
            if value is not None
        ]
        if len(given) > 1:
            raise ValueError(
                f"{' and '.join(given)} are invalid together; allowed: at most one of --out "
                "(a folder of your choice), --resume (an earlier run's folder), "
                "--update-reference"
            )
        if self.update_reference and CHECKOUT is None:
            raise ValueError(
                "--update-reference is invalid here: it rewrites the committed reference results "
                "of a source checkout, and this package is installed (not run from a checkout); "
                "allowed: --out FOLDER, or a new run folder (the default)"
            )
        if self.resume is not None and not Path(self.resume).is_dir():
            raise ValueError(
                f"--resume {str(self.resume)!r} is invalid; allowed: the folder of an earlier run "
                "(there is no such folder)"
            )
        if not given and self.run_dir is None:
            reference = self.reference_dir()
            name = reference.name if reference != RESULTS_DIR else type(self).__module__
            object.__setattr__(self, "run_dir", new_run_dir(name.rpartition(".")[2]))

    def reference_dir(self) -> Path:
        """The study's committed reference results (each study names its folder)."""
        return RESULTS_DIR

    def out_dir(self) -> Path:
        """Where this run writes: `--update-reference`, `--resume`, `--out`, or a new run folder."""
        if self.update_reference:
            return self.reference_dir()
        if self.resume is not None:
            return Path(self.resume)
        if self.out is not None:
            return Path(self.out)
        assert self.run_dir is not None
        return self.run_dir


def at_least(value: object, least: int) -> bool:
    """An integer (numpy's too, not a bool) >= `least`: a count of trials, seeds, workers."""
    return is_integer(value) and value >= least  # type: ignore[operator]


def positive(value: object) -> bool:
    """A finite real number > 0 (not a bool): hours, a duration, a rate."""
    return is_number(value) and value > 0  # type: ignore[operator]


def refuse_invalid(settings: object, checks: Sequence[tuple[str, bool, str]]) -> None:
    """A ValueError for the first (field name, is valid, what is allowed) of `checks` that is not
    valid, naming the field and its value in `settings`."""
    for name, ok, allowed in checks:
        if not ok:
            raise ValueError(f"{name} = {getattr(settings, name)!r} is invalid; allowed: {allowed}")


def new_run_dir(study: str) -> Path:
    """A run folder that does not exist yet: `runs/<study>-<UTC time>[-k]`."""
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    folder = RUNS_DIR / f"{study}-{stamp}"
    k = 1
    while folder.exists():
        k += 1
        folder = RUNS_DIR / f"{study}-{stamp}-{k}"
    return folder


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


def parse_settings(
    settings_type: type[S],
    argv: Sequence[str] | None,
    description: str,
    prog: str | None = None,
) -> S:
    """The settings of a study from a command line (`argv`, default: sys.argv[1:]): one option
    per field, its help from the field's docstring; `--set` (an `Overrides` field) repeats. A
    setting its `__post_init__` refuses is a usage error that names it."""
    return tyro.cli(settings_type, args=argv, description=description, prog=prog)


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
    `tavc_agents.experiments.provenance.run_recorded`)."""
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


# -- the command line of every study ----------------------------------------------------------------
def run_study(
    module: ModuleType, argv: Sequence[str] | None, description: str, prog: str | None = None
) -> int:
    """Parse a study's settings from `argv`, say where it writes, run it, print its results table,
    where it wrote, and whether its tables agree with the committed reference. The exit code is
    1 if the study says it failed (`outcome.failed`, e.g. a long run that found a gap)."""
    settings = parse_settings(module.Settings, argv, description, prog)
    out = settings.out_dir()
    print(f"Writing to {out}/", flush=True)
    outcome = module.run(settings)
    print(outcome.text)
    for line in getattr(module, "failure_lines", lambda _: [])(outcome):
        print(line, file=sys.stderr)
    print(f"\nResults in {outcome.out_dir}/")
    reference = settings.reference_dir()
    if CHECKOUT is None and not reference.is_dir():
        print(
            "Not compared with the committed reference: it is part of a source checkout "
            "(benchmarks/results/), and this package is installed."
        )
    elif Path(outcome.out_dir).resolve() != reference.resolve():
        compare = getattr(module, "agreement", compare_tables)
        for line in compare(Path(outcome.out_dir), reference):
            print(line)
    return 1 if getattr(outcome, "failed", False) else 0


def compare_tables(out: Path, reference: Path) -> list[str]:
    """Whether each report table written in `out` equals the committed reference's, cell by cell.
    A report table is a CSV beside a JSON report (`name.csv`, `name.json`) whose metadata records
    the settings; tables of runs with other settings than the reference's are not compared."""
    lines = []
    for fresh in sorted(out.glob("*.csv")):
        ref = reference / fresh.name
        mine, theirs = recorded_settings(fresh), recorded_settings(ref)
        if not ref.is_file() or mine is None or theirs is None:
            continue
        if mine != theirs:
            changed = sorted(k for k in {*mine, *theirs} if mine.get(k) != theirs.get(k))
            lines.append(
                f"{fresh.name}: not compared with the committed reference {ref}: other settings "
                f"({', '.join(changed)})"
            )
            continue
        differ, total = differing_cells(fresh, ref)
        verdict = "identical to" if differ == 0 else f"{differ} of {total} cells differ from"
        lines.append(f"{fresh.name}: {verdict} the committed reference {ref}")
    return lines or [f"No committed reference report to compare with in {reference}/."]


def recorded_settings(table: Path) -> dict[str, Any] | None:
    """The settings recorded in the JSON report beside the CSV `table` (None if there is none),
    without the output folder (where, not what)."""
    report = table.with_suffix(".json")
    if not report.is_file():
        return None
    try:
        settings = json.loads(report.read_text(encoding="utf-8"))["metadata"]["settings"]
    except (ValueError, KeyError, TypeError):
        return None
    return {k: v for k, v in settings.items() if k != "out"} if isinstance(settings, dict) else None


def differing_cells(a: Path, b: Path) -> tuple[int, int]:
    """How many cells of CSV `a` differ from CSV `b` (cells of rows or columns only one has
    count as differing), and how many cells the larger has."""
    rows_a = list(csv.reader(a.read_text(encoding="utf-8").splitlines()))
    rows_b = list(csv.reader(b.read_text(encoding="utf-8").splitlines()))
    differ = total = 0
    for k in range(max(len(rows_a), len(rows_b))):
        ra = rows_a[k] if k < len(rows_a) else []
        rb = rows_b[k] if k < len(rows_b) else []
        for j in range(max(len(ra), len(rb))):
            total += 1
            differ += (ra[j] if j < len(ra) else None) != (rb[j] if j < len(rb) else None)
    return differ, total
