"""The study contract: what every study shares, so that a study is a short program over the library.

A study is a program (`benchmarks/<name>.py` in the source repository) with a `Settings` class, a
`run(settings) -> Outcome` function and a `main(argv)` over `run_study`. `Settings`
is a frozen dataclass deriving from `StudySettings`: its fields are the study's command line
(`parse_settings`), and its class says the rest in a few lines: what `--quick` changes
(`quick_sizes`), which settings its report records (`recorded_fields`), and its committed
reference folder (`reference`). `StudySettings` brings where a run writes (a new run folder by
default, never the committed reference results unless asked), and `run_jobs` runs a study's jobs
with those settings recorded as their provenance. `run` computes, writes its report and returns
what it wrote; `run_study` is the command line of every study, which also compares a run's tables
with the committed reference. Below the contract: the settings checks studies share (`at_least`,
`refuse_invalid`, `choices`, ...), `KEY=VALUE` arena overrides and the `--figure-only` redraw.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as _dt
import itertools
import sys
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Annotated, Any, ClassVar, Literal, TypeVar

import tyro

from tavc_agents.experiments.command_line import parse_key_values
from tavc_agents.experiments.files import REPORT_MAX_BYTES, atomic_path, read_report, read_text
from tavc_agents.experiments.folders import FolderError, check_out_folder, hold_folder
from tavc_agents.experiments.limits import check_settings
from tavc_agents.experiments.packs import pack_new
from tavc_agents.experiments.provenance import (
    CHECKOUT,
    load_provenance,
    replaceable_provenance,
    run_metadata,
    save_provenance,
)
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.sweep import TRIALS, JobKind, SaveError, TrialSpec, run_jobs
from tavc_env.scenarios import SCENARIOS, Scenario
from tavc_env.validation import is_integer, is_number

RESULTS_DIR = (CHECKOUT or Path()) / "benchmarks" / "results"
"""The committed reference results of the source checkout (changed only with `--update-reference`).
An installed wheel has none: then `benchmarks/results` under the working directory, which a run
only reads (to compare its tables with, if it exists), as `RUNS_DIR` is relative to it too."""
RUNS_DIR = Path("runs")
"""Where a study writes by default: `runs/<study>-<UTC time>/` under the working directory
(ignored by git in a checkout)."""

J = TypeVar("J")
R = TypeVar("R")
S = TypeVar("S")
SettingsT = TypeVar("SettingsT", bound="StudySettings")


def study_name(settings_type: type) -> str:
    """The name of the study a settings class belongs to: its program's file name without `.py`
    (a study run as `python benchmarks/NAME.py` is the module `__main__`)."""
    module = sys.modules.get(settings_type.__module__)
    path = getattr(module, "__file__", None)
    return Path(path).stem if path else settings_type.__module__.rpartition(".")[2]


@dataclass(frozen=True, kw_only=True)
class StudySettings:
    """A study's settings: the fields every study shares (how its jobs run and where it writes;
    not part of what it measures, so not recorded), and the class-level description each study
    gives of its own fields."""

    reference: ClassVar[str | None] = None
    """The committed reference folder's name under `RESULTS_DIR` (None: `RESULTS_DIR` itself); a
    study whose folder depends on its settings overrides `reference_name`."""
    quick_reference_apart: ClassVar[bool] = True
    """Whether a `--quick` run's reference is a folder of its own, `<reference>_quick`."""
    quick_sizes: ClassVar[Mapping[str, Any]] = {}
    """What `--quick` changes (for a study with a `quick` field): field -> smoke-run value."""
    recorded_fields: ClassVar[str] = ""
    """The settings the report records, in order, separated by spaces: attribute names (properties
    too), `key=name` where the recorded name differs from the attribute's. Read from `sized()`."""
    recorded_as_text: ClassVar[bool] = False
    """Whether the report records every setting as text (older studies' reports did)."""

    workers: int | None = None
    """processes, or Ray CPUs; None: all cores"""
    backend: Literal["local", "ray"] = "local"
    """local process pool, or Ray tasks (pip install 'tavc-env[ray]'; set RAY_ADDRESS to use a
    cluster); results and resume are the same either way"""
    out: Path | None = None
    """output folder; None: a new run folder runs/<study>-<time>/, which git ignores"""
    resume: Path | None = None
    """continue an unfinished run in its folder (trials already saved there are not rerun)"""
    update_reference: bool = False
    """write into the committed reference results (benchmarks/results/...) instead of a run folder"""
    run_dir: tyro.conf.Suppress[Path | None] = None
    """the new run folder, chosen once when the settings are made (none with --out, --resume or
    --update-reference)"""

    def __post_init__(self) -> None:
        check_settings(self)  # seeds, hours, the Ray backend (before any work)
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
            name = reference.name if reference != RESULTS_DIR else study_name(type(self))
            object.__setattr__(self, "run_dir", new_run_dir(name))

    @property
    def is_quick(self) -> bool:
        """Whether this is a smoke run (`--quick`, for a study that has one)."""
        return bool(getattr(self, "quick", False))

    def sized(self: SettingsT) -> SettingsT:
        """These settings with `--quick`'s sizes applied (validated again)."""
        if not (self.is_quick and self.quick_sizes):
            return self
        return dataclasses.replace(self, **self.quick_sizes)

    def reference_name(self) -> str | None:
        """The committed reference folder's name (before any `_quick`)."""
        return self.reference

    def reference_dir(self) -> Path:
        """The study's committed reference results."""
        name = self.reference_name()
        if name is None:
            return RESULTS_DIR
        quick = self.is_quick and self.quick_reference_apart
        return RESULTS_DIR / (f"{name}_quick" if quick else name)

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

    @property
    def out_option(self) -> str:
        """How the output folder was chosen, to name it in a message."""
        if self.update_reference:
            return "--update-reference's folder"
        if self.resume is not None:
            return "--resume"
        return "--out" if self.out is not None else "the new run folder"

    @property
    def out_text(self) -> str:
        """The output folder as text (recorded by the studies that record it)."""
        return str(self.out_dir())

    def recorded(self) -> dict[str, Any]:
        """What the report records as the settings: `recorded_fields`."""
        return self.recorded_of(self.recorded_fields)

    def recorded_of(self, fields: str) -> dict[str, Any]:
        """`fields` (as `recorded_fields` names them) of the sized settings, tuples as lists."""
        sized = self.sized()
        recorded = {}
        for entry in fields.split():
            key, _, name = entry.partition("=")
            value = getattr(sized, name or key)
            value = list(value) if isinstance(value, tuple) else value
            recorded[key] = str(value) if self.recorded_as_text else value
        return recorded

    def run_jobs(
        self,
        jobs: Sequence[J],
        kind: JobKind[J, R],
        jobs_in: str | Path,
        *,
        provenance_in: str | Path = "",
        wall_of: Callable[[R], float] | None = None,
        progress_bar: bool = True,
    ) -> tuple[dict[str, R], dict[str, Any]]:
        """Run (or resume) `jobs` with a progress bar, each saved in the output folder's `jobs_in`
        as it finishes, with this run's workers and backend; return the results by key and their
        provenance, which records these settings and is kept in `provenance_in` (see
        `run_recorded`)."""
        out = self.out_dir()
        return run_recorded(
            jobs,
            kind,
            out / jobs_in,
            out / provenance_in,
            self.recorded(),
            workers=self.workers,
            backend=self.backend,
            wall_of=wall_of,
            progress_bar=progress_bar,
        )

    def run_trials(
        self, specs: Sequence[TrialSpec], folder: str | Path = ""
    ) -> tuple[dict[str, TrialResult], dict[str, Any]]:
        """`run_jobs` for trials of the trial runner: saved in `folder`/trials of the output folder,
        their provenance in `folder`."""
        return self.run_jobs(
            specs,
            TRIALS,
            Path(folder, "trials"),
            provenance_in=folder,
            wall_of=lambda result: result.wall_s,
        )


def new_run_dir(study: str) -> Path:
    """A run folder that does not exist yet: `runs/<study>-<UTC time>[-k]`."""
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    folder = RUNS_DIR / f"{study}-{stamp}"
    k = 1
    while folder.exists():
        k += 1
        folder = RUNS_DIR / f"{study}-{stamp}-{k}"
    return folder


@dataclass
class Outcome:
    """What running a study left: the folder it wrote, the files, the text to print (the results
    table a person reads first), and what failed (each a line; the command then exits 1)."""

    out_dir: Path
    written: list[Path]
    text: str
    failures: list[str] = field(default_factory=list)

    @property
    def failed(self) -> bool:
        return bool(self.failures)


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


# -- the command line of every study ----------------------------------------------------------------
def run_study(
    module: ModuleType, argv: Sequence[str] | None, description: str, prog: str | None = None
) -> int:
    """Parse a study's settings from `argv`, say where it writes, run it, print its results table,
    where it wrote, and whether its tables agree with the committed reference (the module's
    `agreement(out, reference)` if it has one, else `compare_tables`). The exit code is 1 if the
    study says it failed (`outcome.failures`, e.g. a long run that found a gap). The output folder
    is checked before any work and held for the whole run (`folders`): a folder that cannot be
    used, or that another run is writing, is refused in one line with exit code 2."""
    given = list(sys.argv[1:] if argv is None else argv)
    command = prog or f"python {sys.argv[0]}"
    out: Path | None = None
    started = False  # whether the study has begun to run (and may have saved jobs)
    try:  # Ctrl-C at any moment, from the first (reading the settings), is one line
        settings = parse_settings(module.Settings, given, description, prog)
        out = settings.out_dir()
        for option in ("--out", "--resume"):  # a Path cannot tell "" from "."
            if _given_empty(given, option):
                check_out_folder("", option)
        check_out_folder(out, settings.out_option)
        with hold_folder(out):  # a second run on this folder is refused until this one ends
            print(f"Writing to {out}/", flush=True)
            started = True
            outcome: Outcome = module.run(settings)
    except FolderError as error:  # refused before any work, in one line
        print(f"{command}: {error}", file=sys.stderr)
        return 2
    except SaveError as error:
        print(f"\n{command}: {error}; continue with `{command} --resume {out}`", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM during a sweep: one line, not a traceback
        if not started:
            print(
                f"\n{command}: interrupted before the study started; nothing was written.",
                file=sys.stderr,
            )
            return 130
        print(
            f"\nInterrupted. The finished jobs are saved in {out}/; continue with "
            f"`{command} --resume {out}` (and the same other options).",
            file=sys.stderr,
        )
        return 130
    print(outcome.text)
    for line in outcome.failures:
        print(line, file=sys.stderr)
    if settings.update_reference:  # trials added to packed reference folders join their packs
        for packed in pack_new(out):
            print(packed.line())
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
    return 1 if outcome.failed else 0


def _given_empty(argv: Sequence[str], option: str) -> bool:
    """Whether `argv` gives `option` an empty value (`--out ""` or `--out=`)."""
    return f"{option}=" in argv or any(a == option and b == "" for a, b in itertools.pairwise(argv))


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
        settings = read_report(report)["metadata"]["settings"]
    except (ValueError, KeyError, TypeError):
        return None
    return {k: v for k, v in settings.items() if k != "out"} if isinstance(settings, dict) else None


def differing_cells(a: Path, b: Path) -> tuple[int, int]:
    """How many cells of CSV `a` differ from CSV `b` (cells of rows or columns only one has
    count as differing), and how many cells the larger has."""
    rows_a = list(csv.reader(read_text(a, REPORT_MAX_BYTES, "CSV table").splitlines()))
    rows_b = list(csv.reader(read_text(b, REPORT_MAX_BYTES, "CSV table").splitlines()))
    differ = total = 0
    for k in range(max(len(rows_a), len(rows_b))):
        ra = rows_a[k] if k < len(rows_a) else []
        rb = rows_b[k] if k < len(rows_b) else []
        for j in range(max(len(ra), len(rb))):
            total += 1
            differ += (ra[j] if j < len(ra) else None) != (rb[j] if j < len(rb) else None)
    return differ, total


# -- what studies share beyond the contract: checks of their settings, comma-separated choices,
# `KEY=VALUE` arena overrides, and the `--figure-only` redraw of a finished run's figure ----------

SweepOptions = StudySettings
"""The contract's settings under their earlier name."""

Overrides = Annotated[tuple[str, ...], tyro.conf.UseAppendAction]
"""The type of a study's `set` field: arena overrides `KEY=VALUE`, one per `--set` (repeatable)."""


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


def choices(settings: object, name: str, known: Collection[str]) -> list[str]:
    """The comma-separated items of the text field `name` of `settings` (blanks dropped); a
    ValueError naming the field unless there is at least one and each is one of `known`."""
    text = getattr(settings, name)
    chosen = [item.strip() for item in text.split(",") if item.strip()]
    if not chosen or any(item not in known for item in chosen):
        raise ValueError(
            f"{name} = {text!r} is invalid; allowed: a comma-separated subset of {', '.join(known)}"
        )
    return chosen


def arena_overrides(items: Sequence[str]) -> dict[str, Any]:
    """Arena overrides from `--set KEY=VALUE` items; the arena's own validation then names any
    key or value it rejects."""
    return parse_key_values(items, "--set", "source_service_s=15")


def replace(settings: S, **changes: Any) -> S:
    """`settings` with some fields changed (validated again)."""
    return dataclasses.replace(settings, **changes)  # type: ignore[type-var]


def redraw_source(path: Path) -> Path:
    """`path`, the report file a `--figure-only` run redraws its figure from; a ValueError naming
    it when it is not there (such a run computes nothing, so it needs a finished run's report)."""
    if not Path(path).is_file():
        raise ValueError(
            f"figure_only: there is no report {str(path)!r} to redraw from; allowed: the output "
            "folder of a finished run (--update-reference, --out or --resume)"
        )
    return Path(path)


def redraw(out: Path, figure: str, draw: Callable[[Path], None]) -> Outcome:
    """A `--figure-only` run: draw the figure `figure` into `out` with `draw` (replacing it whole,
    or not at all on an error) and write nothing else: the report it reads stays as it was."""
    with atomic_path(Path(out) / figure) as tmp:
        draw(tmp)
    text = f"Redrew {figure} from the report in {out}/ (nothing run; no other file written)."
    return Outcome(Path(out), [Path(out) / figure], text)


# -- jobs run with their provenance ----------------------------------------------------------
def run_recorded(
    jobs: Sequence[J],
    kind: JobKind[J, R],
    jobs_dir: str | Path,
    report_dir: str | Path,
    settings: Mapping[str, Any],
    *,
    workers: int | None = None,
    backend: str = "local",
    wall_of: Callable[[R], float] | None = None,
    progress_bar: bool = True,
) -> tuple[dict[str, R], dict[str, Any]]:
    """Run (or resume) `jobs` in `jobs_dir` with a progress bar; return the results by key and the
    provenance of the results.

    When this run computes any job, the provenance is this run's (taken before the jobs start,
    so it names the commit they ran from), with its wall time and how many jobs were run or
    resumed, and it is saved in `report_dir`, also when the run is interrupted (Ctrl-C, SIGTERM,
    a refused save) after computing some jobs (then marked `interrupted`). When every job is
    resumed, the provenance saved there by the run that computed them is returned (or, if there
    is none, this run's). A damaged provenance.json (garbled, not a JSON object) is named in one
    line and replaced by this run's; one that is not a regular file (a folder, a FIFO, a link) is
    refused before any job runs, as a run could only replace it by deleting it."""
    started = time.perf_counter()
    damaged = replaceable_provenance(Path(report_dir))  # before any job runs
    meta = run_metadata(settings=dict(settings))
    finished: list[str] = []
    resumed: list[str] = []
    trial_wall = 0.0

    def note(job: J, result: R, was_resumed: bool) -> None:
        nonlocal trial_wall
        if wall_of is not None:
            trial_wall += wall_of(result)
        finished.append(kind.key(job))
        if was_resumed:
            resumed.append(kind.key(job))

    def counted(**extra: Any) -> dict[str, Any]:
        counts: dict[str, Any] = dict(
            wall_time_s=time.perf_counter() - started,
            trials_resumed=len(resumed),
            trials_run=len(finished) - len(resumed),
            **extra,
        )
        if wall_of is not None:
            counts["trial_wall_s_total"] = trial_wall
        return {**meta, **counts}

    try:
        results = run_jobs(
            jobs, kind, jobs_dir, workers, note, progress_bar=progress_bar, backend=backend
        )
    except BaseException:
        # The jobs an interrupted run computed are saved; so is its provenance, so that a report
        # rendered later from them names the commit and machine that made them.
        if len(finished) > len(resumed):
            try:
                save_provenance(report_dir, counted(interrupted=True))
            except Exception as error:  # the interruption is the news; this is one line beside it
                print(f"provenance of the interrupted run not saved: {error}", file=sys.stderr)
        raise
    stored = None if damaged else load_provenance(report_dir)
    if len(resumed) == len(jobs) and stored is not None:
        return results, stored
    meta = counted()
    if len(resumed) < len(jobs) or damaged:
        if damaged:
            print(f"{damaged}; replaced by this run's provenance", file=sys.stderr)
        save_provenance(report_dir, meta)
    return results, meta


# -- the settings of the studies of the suite's evaluation episodes -------------------------------
@dataclass(frozen=True, kw_only=True)
class EvaluationSettings(StudySettings):
    """What every study of the suite's evaluation episodes takes: the scenarios, how many of their
    evaluation seeds, and the episode length (the scenario's unless given)."""

    min_seeds: ClassVar[int] = 1

    scenarios: tuple[str, ...] = tuple(SCENARIOS)
    """the scenarios (names in tavc_env.scenarios.SCENARIOS)"""
    seeds: int | None = None
    """evaluation seeds per scenario (default: all of the scenario's)"""
    episode_h: float | None = None
    """episode length, simulated hours (default: the scenario's)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                (
                    "scenarios",
                    len(self.scenarios) >= 1 and all(n in SCENARIOS for n in self.scenarios),
                    f"one or more of {', '.join(SCENARIOS)}",
                ),
                (
                    "seeds",
                    self.seeds is None or at_least(self.seeds, self.min_seeds),
                    f"None or >= {self.min_seeds}",
                ),
                ("episode_h", self.episode_h is None or positive(self.episode_h), "hours > 0"),
            ],
        )

    @property
    def seeds_text(self) -> str:
        return "all" if self.seeds is None else str(self.seeds)

    @property
    def episode_text(self) -> str:
        return "scenario's" if self.episode_h is None else str(float(self.episode_h))

    def seeds_of(self, scenario: Scenario) -> tuple[int, ...]:
        return scenario.eval_seeds if self.seeds is None else scenario.eval_seeds[: self.seeds]

    def episode_s(self, scenario: Scenario) -> float:
        return scenario.episode_s if self.episode_h is None else float(self.episode_h) * 3600.0


@dataclass(frozen=True, kw_only=True)
class ScoredSettings(StudySettings):
    """What a study that scores episodes against the scenarios' references takes: the committed
    references, and the bootstrap's resamples and seed."""

    references: Path = RESULTS_DIR / "scenarios" / "references.json"
    """the scenarios' committed references (random, stay, optimum) that normalise the scores"""
    resamples: int = 10_000
    """bootstrap resamples of every interval"""
    seed: int = 0
    """the bootstrap's generator seed"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                ("resamples", at_least(self.resamples, 100), "an integer >= 100"),
                ("seed", at_least(self.seed, 0), "an integer >= 0"),
                (
                    "references",
                    Path(self.references).is_file(),
                    "the scenarios study's references.json (python benchmarks/scenarios.py "
                    "--stage measure)",
                ),
            ],
        )
