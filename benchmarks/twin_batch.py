"""The batched model twin (thousands of twin trials in seconds, for power analyses) checked
against the Policy-based twin in every cell of the regime map, and timed against the physics. The
design is in the study's docstring (`benchmarks/twin_batch.py`).

Writes `twin_batch.{md,csv,json}` and every cell's batch (`cells/`) into a new run folder
(`--update-reference`: benchmarks/results/twin_batch/); `--resume RUN_DIR` continues.

    python benchmarks/twin_batch.py           # 36 cells x 2000 trials, then the speed timing
    python benchmarks/twin_batch.py --quick   # smoke run

The batched model twin (`tavc_agents.experiments.twin_batch`) checked against the Policy-based twin,
and how much faster than the physics it is.

For every cell of the regime map (arena x softmax T = 0.002, 0.005, 0.01, 0.02, epsilon 0.1,
random), `--trials` batched twin trials (15 h + 5 h, the regime map's tables) are set against the
regime map's twin trials of the same cell (`benchmarks/results/regime_map/trials/`, run through
`run_trial` with the TAVC `Policy` objects): fast - slow, performance and the fast robots' minus the
slow robots' Q gap, each as a Welch 95 % interval of the difference. The two implementations agree
where that interval holds 0; with 36 cells x 3 measures, about 5 disagreements are expected by
chance alone at the 5 % level.

Speed, measured in one process in this run: seconds per trial of the physics, of the Policy-based
twin and of the batched twin, on `dahl2004` with softmax TAVC at T = 0.005 (the paper's cell).
The script is `benchmarks/twin_batch.py`.
"""

from __future__ import annotations

import functools
import math
import os
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

import arena_runs
import tavc_env
from arena_runs import learner_of, run_batch
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.registry import make_allocator
from tavc_agents.experiments.runner import env_arguments, run_trial
from tavc_agents.experiments.study import (
    RESULTS_DIR,
    Outcome,
    StudySettings,
    at_least,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import json_jobs, saved_results
from tavc_env.twin import InterferenceTables

Row = dict[str, Any]
MEASURES = ("fast_minus_slow", "performance", "q_gap_fast_minus_slow")
SPEED_CELL = ("dahl2004", arena_runs.softmax_condition(0.005))


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The batched twin's check (its command line)."""

    reference: ClassVar = "twin_batch"
    quick_sizes: ClassVar = {"trials": 50, "speed_physics": 1, "speed_twin": 2}
    recorded_fields: ClassVar = (
        "trials seed speed_physics speed_twin periods_h regime_map_dir=regime_map_name"
    )

    trials: int = 2000
    """batched twin trials per cell"""
    seed: int = 0
    """cell k's batch draws from a generator seeded [seed, k]"""
    speed_physics: int = 2
    """physics trials timed for the speed ratio"""
    speed_twin: int = 10
    """Policy-based twin trials timed for the speed ratio"""
    regime_map_dir: Path = RESULTS_DIR / "regime_map"
    """the regime map whose twin trials and tables are the reference"""
    quick: bool = False
    """smoke run: 50 trials per cell, one physics and two twin trials timed"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                ("trials", at_least(self.trials, 2), "an integer >= 2"),
                ("seed", at_least(self.seed, 0), "an integer >= 0"),
                ("speed_physics", at_least(self.speed_physics, 1), "an integer >= 1"),
                ("speed_twin", at_least(self.speed_twin, 1), "an integer >= 1"),
                (
                    "regime_map_dir",
                    (Path(self.regime_map_dir) / "twin_tables").is_dir(),
                    "a regime map's results folder (with twin_tables/ and trials/)",
                ),
            ],
        )

    def regime_map_settings(self) -> arena_runs.Settings:
        """The settings of the regime map compared with (its defaults, in its folder)."""
        return arena_runs.Settings(out=Path(self.regime_map_dir))

    @property
    def periods_h(self) -> tuple[float, float]:
        """The regime map's periods (those of the trials compared with)."""
        kept = self.regime_map_settings()
        return kept.convergence_h, kept.measured_h

    @property
    def regime_map_name(self) -> str:
        return Path(self.regime_map_dir).name


# -- jobs ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Cell:
    """`trials` batched twin trials of one regime-map cell, drawing from [seed, index]."""

    arena: str
    condition: str
    index: int
    trials: int
    seed: int
    convergence_h: float
    measured_h: float
    tables_sha256: str
    tables: Mapping[str, Any] | None = None


def cell_key(cell: Cell) -> str:
    return f"{cell.arena}__{cell.condition}"


def run_cell(cell: Cell) -> dict[str, Any]:
    """The cell's batch: per trial fast share, slow share, performance and Q gaps (rounded), and
    the batch's wall time."""
    assert cell.tables is not None, "a cell needs its tables"
    started = time.perf_counter()
    out = run_batch(
        arena_runs.arena_config(cell.arena),
        InterferenceTables.from_dict(cell.tables),
        learner_of(cell.condition),
        cell.trials,
        np.random.default_rng([cell.seed, cell.index]),
        cell.convergence_h * 3600.0,
        cell.measured_h * 3600.0,
    )
    wall = time.perf_counter() - started

    def listed(values: np.ndarray) -> list[float | None]:
        return [None if math.isnan(v) else round(float(v), 6) for v in values]

    return {
        "fast_share": listed(out.fast_share),
        "slow_share": listed(out.slow_share),
        "performance": listed(out.performance),
        "q_gap_fast": listed(out.q_gap_fast),
        "q_gap_slow": listed(out.q_gap_slow),
        "wall_s": round(wall, 3),
    }


CELLS = json_jobs(run_cell, cell_key, unit="cell", omit=("tables",))


def reference(s: Settings) -> tuple[dict[str, dict[str, Any]], dict[str, list[dict[str, Any]]]]:
    """The regime map's tables by arena and its twin trials by cell key."""
    kept = s.regime_map_settings()
    arenas = kept.arena_list
    table_jobs = [
        arena_runs.TablesJob(
            a, tuple(range(kept.table_seeds)), kept.table_hours, arena_runs.digest(a)
        )
        for a in arenas
    ]
    stored = saved_results(table_jobs, arena_runs.TABLES, Path(s.regime_map_dir) / "twin_tables")
    tables = {job.arena: stored[arena_runs.TABLES.key(job)] for job in table_jobs}
    twin_jobs = arena_runs.twin_trials(kept, tables)
    found = saved_results(twin_jobs, arena_runs.TRIALS, Path(s.regime_map_dir) / "trials")
    trials: dict[str, list[dict[str, Any]]] = {}
    for job in twin_jobs:
        if arena_runs.trial_key(job) in found:
            trials.setdefault(f"{job.arena}__{job.condition}", []).append(
                found[arena_runs.trial_key(job)]
            )
    return tables, trials


# -- analysis -----------------------------------------------------------------------------------
def per_trial(
    records: Mapping[str, Sequence[Any]] | Sequence[Mapping[str, Any]],
) -> dict[str, list[float]]:
    """Each measure per trial, from a batch (lists by measure) or from twin trial records."""
    if isinstance(records, Mapping):
        columns = {k: np.array(v, dtype=float) for k, v in records.items() if k != "wall_s"}
    else:
        keys = ("fast_share", "slow_share", "performance", "q_gap_fast", "q_gap_slow")
        columns = {k: np.array([r[k] for r in records], dtype=float) for k in keys}
    return {
        "fast_minus_slow": list(columns["fast_share"] - columns["slow_share"]),
        "performance": list(columns["performance"]),
        "q_gap_fast_minus_slow": list(columns["q_gap_fast"] - columns["q_gap_slow"]),
    }


def compare(batch: Mapping[str, list[float]], twin: Mapping[str, list[float]]) -> Row:
    """Per measure: both means with 95 % intervals and the Welch interval of their difference."""
    row: Row = {}
    for m in MEASURES:
        a = [x for x in batch[m] if math.isfinite(x)]
        b = [x for x in twin[m] if math.isfinite(x)]
        for name, values in (("batch", a), ("twin", b)):
            mean, lo, hi, n = mean_ci(values)
            row |= {f"{m}_{name}": mean, f"{m}_{name}_lo": lo, f"{m}_{name}_hi": hi}
            row.setdefault(f"n_{name}", n)  # trials (the first measure has a value in every one)
        d = arena_runs.welch_difference(a, b)
        row |= {f"{m}_diff": d[0], f"{m}_diff_lo": d[1], f"{m}_diff_hi": d[2]}
        row[f"{m}_agree"] = bool(d[1] <= 0 <= d[2]) if math.isfinite(d[1]) else None
    return row


def time_speed(s: Settings, tables: Mapping[str, Any]) -> Row:
    """CPU seconds per trial (`time.process_time`: other processes on a shared machine do not
    count) of the physics, the Policy-based twin and the batched twin in the speed cell, timed one
    after the other in this process."""
    arena, condition = SPEED_CELL
    allocator, params = arena_runs.CONDITIONS[condition]
    convergence_h, measured_h = s.periods_h
    twin_env = functools.partial(
        tavc_env.twin_parallel_env, tables=InterferenceTables.from_dict(tables)
    )

    def per_trial_s(count: int, factory: Any) -> float:
        started = time.process_time()
        for seed in range(count):
            run_trial(
                make_allocator(allocator, **params),
                seed=seed,
                convergence_s=convergence_h * 3600.0,
                measured_s=measured_h * 3600.0,
                env_factory=factory,
                **env_arguments(arena_runs.ARENAS[arena]),
            )
        return (time.process_time() - started) / count

    physics = per_trial_s(s.speed_physics, None)
    twin = per_trial_s(s.speed_twin, twin_env)
    started = time.process_time()
    run_batch(
        arena_runs.arena_config(arena),
        InterferenceTables.from_dict(tables),
        learner_of(condition),
        s.trials,
        np.random.default_rng([s.seed, 10_000]),
        convergence_h * 3600.0,
        measured_h * 3600.0,
    )
    batch = (time.process_time() - started) / s.trials
    meta = run_metadata()
    return {
        # when and where it was timed (a resumed run keeps its cells' provenance)
        "measured_utc": meta["timestamp_utc"],
        "measured_commit": meta["git"]["commit"],
        "load_1min": os.getloadavg()[0],
        "physics_s": physics,
        "twin_s": twin,
        "batch_s": batch,
        "twin_speedup": physics / twin,
        "batch_speedup": physics / batch,
    }


def report_body(rows: Sequence[Row], speed: Row, s: Settings) -> str:
    def ci(r: Row, key: str, digits: int) -> str:
        return fmt_ci(r[key], r[f"{key}_lo"], r[f"{key}_hi"], digits)

    table = []
    for r in rows:
        cells = [r["arena"], r["condition"], f"{r['n_twin']} / {r['n_batch']}"]
        for m, digits in zip(MEASURES, (3, 4, 5)):
            mark = "" if r[f"{m}_agree"] in (True, None) else " **differ**"
            cells += [ci(r, f"{m}_twin", digits), ci(r, f"{m}_batch", digits) + mark]
        table.append(cells)
    verdicts = [r[f"{m}_agree"] for r in rows for m in MEASURES if r[f"{m}_agree"] is not None]
    agree = sum(1 for v in verdicts if v)
    return "\n".join(
        [
            f"Batched twin: {s.trials} trials per cell; Policy-based twin: the regime map's twin "
            "trials. Mean [95 % CI] over trials; **differ**: the Welch 95 % interval of the "
            "difference excludes 0.",
            "",
            f"**Agreement: {agree} of {len(verdicts)} comparisons** (at the 5 % level about "
            f"{0.05 * len(verdicts):.0f} would differ by chance alone).",
            "",
            markdown_table(
                [
                    "arena",
                    "condition",
                    "N (twin / batch)",
                    "fast - slow: twin",
                    "batch",
                    "performance: twin",
                    "batch",
                    "Q gap fast - slow: twin",
                    "batch",
                ],
                table,
            ),
            "",
            f"**Speed** (`{SPEED_CELL[0]}`, `{SPEED_CELL[1]}`, one process, one after the other, "
            f"CPU seconds; timed {speed['measured_utc']} at commit "
            f"`{str(speed['measured_commit'])[:12]}`, load {speed['load_1min']:.1f}): physics {speed['physics_s']:.2f} s per trial ({s.speed_physics} trials), "
            f"Policy-based twin {speed['twin_s']:.3f} s ({s.speed_twin} trials, "
            f"{speed['twin_speedup']:.0f}x faster), batched twin {1000 * speed['batch_s']:.2f} ms "
            f"({s.trials} trials in one batch, **{speed['batch_speedup']:.0f}x faster** than the "
            "physics).",
        ]
    )


def run(settings: Settings) -> Outcome:
    """Run (or resume) every cell's batch, compare it with the regime map's twin trials, time the
    three engines, write the report."""
    s = settings.sized()
    out = s.out_dir()
    tables, twin = reference(s)
    convergence_h, measured_h = s.periods_h
    cells = [
        Cell(
            arena,
            condition,
            index,
            s.trials,
            s.seed,
            convergence_h,
            measured_h,
            arena_runs.tables_digest(tables[arena]),
            tables[arena],
        )
        for index, (arena, condition) in enumerate(
            (a, c) for a in tables for c in arena_runs.CONDITIONS
        )
    ]
    results, provenance = s.run_jobs(cells, CELLS, "cells")
    rows = []
    for cell in cells:
        reference_trials = twin.get(cell_key(cell), [])
        if len(reference_trials) < 2:
            continue
        row: Row = {"arena": cell.arena, "condition": cell.condition}
        row |= compare(per_trial(results[cell_key(cell)]), per_trial(reference_trials))
        rows.append(row)
    speed = time_speed(s, tables[SPEED_CELL[0]])
    body = report_body(rows, speed, s)
    report = Report(
        "twin_batch",
        "The batched model twin against the Policy-based twin",
        body,
        rows,
        summary={"speed": speed},
    )
    written = report.write(out, provenance)
    return Outcome(out, written, body)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
