"""The regime map: where does the paper's differentiation appear, where does it reverse, and why?

For each arena (the shipped `dahl2004` family, the congestion arena and the bays arena of the
second design search, spanning the crowding elasticity e) and each condition (softmax TAVC at T = 0.002, 0.005, 0.01, 0.02, epsilon-greedy
TAVC with epsilon 0.1, random allocation), physics trials of 15 h + 5 h report, with 95 %
intervals over trials: fast minus slow share of the measured period on the high-value circuit
(the paper's effect: > 0), the time in the state 3:0 (all three robots on the high-value circuit
fast), the learned Q gap of fast robots minus that of slow ones, and performance relative to
random allocation. Beside each cell, the model twin's prediction (`tavc_env.twin`, its tables
measured in the same arena): a what-if tool, never a substitute for the physics columns.

Each arena's e is measured first (`tavc_agents.studies.elasticity.measure_elasticity`, the interference
study's runs and settings), then its twin tables (`tavc_env.twin.build_tables`).
The cells that decide the question (softmax T = 0.005 and 0.01 on `dahl2004_congestion` and on
`dahl2004`) get `decisive_trials` physics trials; the congestion arena's run first, then the
twin's trials, then `dahl2004`'s decisive cells and the rest. Every other cell gets `trials`.
Trial k of every cell uses seed `seed + k`.

Every trial is kept as a compact record (its measures, about 1 KB) under `<out>/trials/` as it
finishes, so an interrupted sweep resumes where it stopped; the report is written when all
trials are in. The script is `benchmarks/regime_map.py`.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from scipy import stats

import tavc_env
from tavc_agents.analysis.elasticity import Elasticity
from tavc_agents.analysis.measures import measure
from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci, ratio_ci
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.registry import make_allocator
from tavc_agents.experiments.runner import env_arguments, run_trial
from tavc_agents.experiments.study import Outcome, StudySettings
from tavc_agents.experiments.sweep import arena_digest, json_jobs, run_jobs, saved_results
from tavc_agents.studies.common import at_least, choices, positive, refuse_invalid, replace
from tavc_agents.studies.elasticity import measure_elasticity
from tavc_env import metrics
from tavc_env.twin import InterferenceTables, build_tables

ARENAS: Mapping[str, Mapping[str, Any]] = {
    "dahl2004": {"preset": "dahl2004"},
    "dahl2004_instant_docks": {
        "preset": "dahl2004",
        "source_service_s": 0.0,
        "sink_service_s": 0.0,
    },
    "dahl2004_competence": {"preset": "dahl2004_competence"},
    "dahl2004_light_stations": {"preset": "dahl2004_light_stations"},
    "dahl2004_congestion": {"preset": "dahl2004_congestion"},
    "dahl2004_bays": {"preset": "dahl2004_bays"},
    "dahl2004_passing": {"preset": "dahl2004_passing"},
}
"""Arena name -> `tavc_env.parallel_env` keyword arguments (a preset and its overrides)."""
MAPPED = tuple(a for a in ARENAS if a != "dahl2004_passing")
"""the arenas of the committed map; `dahl2004_passing` has its own decisive test
(`tavc_agents.studies.passing`), which runs its cells through this module's jobs"""

TEMPERATURES = (0.002, 0.005, 0.01, 0.02)
EPSILON = 0.1
DECISIVE = (
    ("dahl2004_congestion", 0.005),
    ("dahl2004_congestion", 0.01),
    ("dahl2004", 0.005),
    ("dahl2004", 0.01),
)
"""(arena, softmax temperature) of the cells that decide the question, in the order they run."""

Z_POWER = stats.norm.ppf(0.975) + stats.norm.ppf(0.80)  # two-sided 5 %, 80 % power
Engine = Literal["physics", "twin"]
Row = dict[str, Any]


def softmax_condition(temperature: float) -> str:
    return f"softmax_T{temperature:g}"


CONDITIONS: Mapping[str, tuple[str, Mapping[str, Any]]] = {
    **{
        softmax_condition(t): ("softmax_tavc", {"temperature": t, "init": "scaled"})
        for t in TEMPERATURES
    },
    "epsilon_0.1": ("epsilon_tavc", {"epsilon": EPSILON, "init": "scaled"}),
    "random": ("random", {}),
}
"""Condition name -> (allocator, its parameters)."""


QUICK_DESIGN: Mapping[str, Any] = {
    "convergence_h": 0.3,
    "measured_h": 0.2,
    "e_seeds": 2,
    "e_hours": 0.4,
    "table_seeds": 2,
    "table_hours": 0.4,
}
"""`CellDesign`'s sizes in a smoke run (`--quick`)"""


@dataclass(frozen=True, kw_only=True)
class CellDesign(StudySettings):
    """How an arena's cells are made: the trials' periods and seeds, and the runs that measure the
    arena's e and twin tables (the regime map's, and the passing arena's decisive test's)."""

    convergence_h: float = 15.0
    """convergence period, simulated hours"""
    measured_h: float = 5.0
    """measured period, simulated hours"""
    e_seeds: int = 5
    """seeds of each arena's elasticity runs"""
    e_hours: float = 3.0
    """simulated hours per elasticity run"""
    table_seeds: int = 3
    """seeds of each arena's twin-table runs"""
    table_hours: float = 1.0
    """simulated hours per twin-table run"""
    seed: int = 0
    """trial k of every cell uses seed + k"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                ("convergence_h", positive(self.convergence_h), "a finite number > 0"),
                ("measured_h", positive(self.measured_h), "a finite number > 0"),
                ("e_seeds", at_least(self.e_seeds, 2), "an integer >= 2"),
                ("e_hours", positive(self.e_hours), "a finite number > 0"),
                ("table_seeds", at_least(self.table_seeds, 1), "an integer >= 1"),
                ("table_hours", positive(self.table_hours), "a finite number > 0"),
                ("seed", at_least(self.seed, 0), "an integer >= 0"),
            ],
        )


@dataclass(frozen=True, kw_only=True)
class Settings(CellDesign):
    """The regime map's settings (its command line)."""

    reference: ClassVar = "regime_map"
    quick_sizes: ClassVar = {**QUICK_DESIGN, "trials": 2, "decisive_trials": 3}
    recorded_fields: ClassVar = (
        "arenas=arena_list trials decisive_trials decisive_cells twin_trials convergence_h "
        "measured_h e_seeds e_hours table_seeds table_hours seed"
    )

    arenas: str = ",".join(MAPPED)
    """comma-separated subset of the arenas dahl2004, dahl2004_instant_docks, dahl2004_competence,
    dahl2004_light_stations, dahl2004_congestion, dahl2004_bays"""
    trials: int = 60
    """physics trials per cell"""
    decisive_trials: int = 400
    """physics trials in the cells that decide the question (softmax T = 0.005 and 0.01 on
    dahl2004_congestion and dahl2004)"""
    twin_trials: int = 100
    """model-twin trials per cell (0: no twin)"""
    quick: bool = False
    """smoke run: 2 trials (3 in decisive cells, 2 twin) of 0.3 + 0.2 h, short e and table runs"""
    interim: bool = False
    """run no trial: write `regime_map_interim.*` from the trials saved so far (an unfinished
    sweep; every cell states its N, and cells with fewer than 2 trials are left out)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        choices(self, "arenas", ARENAS)  # an unknown arena is refused
        checks = [
            ("trials", at_least(self.trials, 2), "an integer >= 2"),
            ("decisive_trials", at_least(self.decisive_trials, 2), "an integer >= 2"),
            ("twin_trials", at_least(self.twin_trials, 0), "an integer >= 0"),
        ]
        refuse_invalid(self, checks)

    @property
    def arena_list(self) -> list[str]:
        return choices(self, "arenas", ARENAS)

    @property
    def decisive_cells(self) -> list[str]:
        return [f"{a} {softmax_condition(t)}" for a, t in DECISIVE]

    def sized(self) -> Settings:
        """These settings with `--quick`'s sizes applied (and at most 2 twin trials)."""
        sized = super().sized()
        return replace(sized, twin_trials=min(self.twin_trials, 2)) if self.quick else sized

    def trials_in(self, arena: str, condition: str) -> int:
        decisive = {(a, softmax_condition(t)) for a, t in DECISIVE}
        return self.decisive_trials if (arena, condition) in decisive else self.trials


def digest(arena: str) -> str:
    """The digest of the arena's configuration (`tavc_agents.experiments.sweep.arena_digest`)."""
    return arena_digest(ARENAS[arena])


def arena_config(arena: str) -> tavc_env.ArenaConfig:
    kwargs = dict(ARENAS[arena])
    return tavc_env.make_config(kwargs.pop("preset"), **kwargs)


# -- jobs ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TablesJob:
    """Measure one arena's twin tables. `arena_sha` is the digest of the arena's configuration,
    so a stored result is not resumed for an arena whose name now means another configuration."""

    arena: str
    seeds: tuple[int, ...]
    hours: float
    arena_sha: str = ""


def run_tables(job: TablesJob) -> dict[str, Any]:
    return build_tables(arena_config(job.arena), seeds=job.seeds, hours=job.hours).to_dict()


TABLES = json_jobs(run_tables, lambda job: f"tables_{job.arena}", unit="arena")


@dataclass(frozen=True)
class MapTrial:
    """One trial of one cell, on the physics or on the twin (whose tables travel with the job and
    are recorded by their digest)."""

    arena: str
    condition: str
    seed: int
    convergence_h: float
    measured_h: float
    engine: Engine = "physics"
    tables_sha256: str = ""
    arena_sha: str = ""  # the arena configuration's digest (see `TablesJob`)
    tables: Mapping[str, Any] | None = field(default=None, compare=False, repr=False)


def tables_digest(tables: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(tables, sort_keys=True).encode()).hexdigest()


def trial_key(job: MapTrial) -> str:
    return f"{job.arena}__{job.condition}__{job.engine}__seed{job.seed}"


def run_map_trial(job: MapTrial) -> dict[str, Any]:
    """Run `job` and return its compact record: the measures of `tavc_agents.analysis.measures`."""
    allocator, params = CONDITIONS[job.condition]
    factory = None
    if job.engine == "twin":
        assert job.tables is not None, "a twin trial needs its tables"
        tables = InterferenceTables.from_dict(job.tables)
        factory = functools.partial(tavc_env.twin_parallel_env, tables=tables)
    started = time.perf_counter()
    result = run_trial(
        make_allocator(allocator, **params),
        seed=job.seed,
        convergence_s=job.convergence_h * 3600.0,
        measured_s=job.measured_h * 3600.0,
        snapshot_every_s=(job.convergence_h + job.measured_h) * 3600.0,
        env_factory=factory,
        **env_arguments(ARENAS[job.arena]),
    )
    m = measure(result)
    return {
        "fast_share": m.fast_share,
        "slow_share": m.slow_share,
        "performance": m.performance,
        "q_gap_fast": m.q_gap_fast,
        "q_gap_slow": m.q_gap_slow,
        "states_pct": {f"{f}:{s}": round(v, 4) for (f, s), v in sorted(m.states.items())},
        "deliveries": len(result.delivery_time_s),
        "jams": result.jams,
        "sim_s": round(result.end_s, 1),
        "wall_s": round(time.perf_counter() - started, 2),
    }


TRIALS = json_jobs(run_map_trial, trial_key, unit="trial", omit=("tables",))


def physics_trials(s: Settings) -> list[MapTrial]:
    """The physics trials: the decisive cells first (in `DECISIVE` order, seed by seed within
    each arena), then the other cells seed by seed, so that a sweep stopped early leaves whole
    seeds in every cell it reached."""

    def trial(arena: str, condition: str, k: int) -> MapTrial:
        return MapTrial(
            arena, condition, s.seed + k, s.convergence_h, s.measured_h, arena_sha=digest(arena)
        )

    arenas = s.arena_list
    decisive = [(a, softmax_condition(t)) for a, t in DECISIVE if a in arenas]
    jobs = []
    for arena in dict.fromkeys(a for a, _ in decisive):
        cells = [c for a, c in decisive if a == arena]
        jobs += [trial(arena, c, k) for k in range(s.decisive_trials) for c in cells]
    rest = [(a, c) for a in arenas for c in CONDITIONS if (a, c) not in decisive]
    jobs += [trial(a, c, k) for k in range(s.trials) for a, c in rest]
    return jobs


def twin_trials(s: Settings, tables: Mapping[str, Mapping[str, Any]]) -> list[MapTrial]:
    return [
        MapTrial(
            a,
            c,
            s.seed + k,
            s.convergence_h,
            s.measured_h,
            "twin",
            tables_digest(tables[a]),
            digest(a),
            tables[a],
        )
        for k in range(s.twin_trials)
        for a in s.arena_list
        for c in CONDITIONS
    ]


# -- analysis -----------------------------------------------------------------------------------
def _values(records: Sequence[Mapping[str, Any]], key: str) -> list[float]:
    return [float(r[key]) for r in records]


def diff_of(records: Sequence[Mapping[str, Any]]) -> list[float]:
    """Per trial, the fast robots' share of time on the high-value circuit minus the slow ones'."""
    return [float(r["fast_share"]) - float(r["slow_share"]) for r in records]


def minimal_detectable(values: Sequence[float]) -> float:
    """The smallest mean effect that `len(values)` trials of this spread detect with 80 % power
    in a two-sided 5 % test: (z_0.975 + z_0.80) sd / sqrt(n)."""
    if len(values) < 2:
        return math.nan
    return float(Z_POWER * np.std(values, ddof=1) / math.sqrt(len(values)))


def cell_row(records: Sequence[Mapping[str, Any]], random: Sequence[Mapping[str, Any]]) -> Row:
    """One engine's summary of one cell (against that engine's random cell of the same arena)."""
    diff = diff_of(records)
    d, d_lo, d_hi, n = mean_ci(diff)
    s30, s30_lo, s30_hi, _ = mean_ci([r["states_pct"]["3:0"] for r in records])
    q, q_lo, q_hi, _ = mean_ci([float(r["q_gap_fast"]) - float(r["q_gap_slow"]) for r in records])
    perf, perf_lo, perf_hi, _ = mean_ci(_values(records, "performance"))
    ratio = (
        ratio_ci(_values(records, "performance"), _values(random, "performance"))
        if len(random) >= 2
        else (math.nan,) * 3
    )
    return {
        "trials": n,
        "fast_share": float(np.mean(_values(records, "fast_share"))),
        "slow_share": float(np.mean(_values(records, "slow_share"))),
        "fast_minus_slow": d,
        "fast_minus_slow_lo": d_lo,
        "fast_minus_slow_hi": d_hi,
        "fast_minus_slow_sd": float(np.std(diff, ddof=1)) if n >= 2 else math.nan,
        "detectable_80": minimal_detectable(diff),
        "time_3_0_pct": s30,
        "time_3_0_lo": s30_lo,
        "time_3_0_hi": s30_hi,
        "q_gap_fast_minus_slow": q,
        "q_gap_lo": q_lo,
        "q_gap_hi": q_hi,
        "performance": perf,
        "performance_lo": perf_lo,
        "performance_hi": perf_hi,
        "ratio_to_random": ratio[0],
        "ratio_lo": ratio[1],
        "ratio_hi": ratio[2],
        "jams": int(sum(int(r["jams"]) for r in records)),
        "wall_s": float(sum(float(r["wall_s"]) for r in records)),
    }


def welch_difference(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    """Mean of `a` minus mean of `b` with its Welch 95 % interval (nan where undefined)."""
    if len(a) < 2 or len(b) < 2:
        return (math.nan, math.nan, math.nan)
    res = stats.ttest_ind(a, b, equal_var=False)
    ci = res.confidence_interval(0.95)
    return (float(np.mean(a) - np.mean(b)), float(ci.low), float(ci.high))


def overlap(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return a[0] <= b[1] and b[0] <= a[1]


def direction(row: Row) -> str:
    """The paper's direction (interval above 0), reversed (below 0) or not detectable."""
    lo, hi = row["fast_minus_slow_lo"], row["fast_minus_slow_hi"]
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return "undetermined"
    if lo > 0:
        return "paper's direction"
    if hi < 0:
        return "reversed"
    return "not detectable"


def summarise(
    records: Mapping[tuple[str, str, Engine], Sequence[Mapping[str, Any]]],
    e: Mapping[str, Elasticity],
    arenas: Sequence[str],
) -> list[Row]:
    """One row per arena and condition: the physics cell, the twin's beside it, and whether they
    agree (fast - slow: the Welch interval of their difference holds 0; performance / random: the
    two intervals overlap)."""
    rows = []
    for arena in arenas:
        for condition in CONDITIONS:
            phys = records.get((arena, condition, "physics"), [])
            if len(phys) < 2:
                continue  # an unfinished sweep's cell
            row: Row = {
                "arena": arena,
                "e": e[arena].e,
                "e_lo": e[arena].low,
                "e_hi": e[arena].high,
                "condition": condition,
                **cell_row(phys, records.get((arena, "random", "physics"), [])),
            }
            row["direction"] = direction(row)
            twin = records.get((arena, condition, "twin"), [])
            if len(twin) >= 2:
                t = cell_row(twin, records.get((arena, "random", "twin"), []))
                row.update({f"twin_{k}": v for k, v in t.items() if k != "wall_s"})
                row["twin_wall_s"] = t["wall_s"]
                dd = welch_difference(diff_of(phys), diff_of(twin))
                row.update({"physics_minus_twin": dd[0], "pmt_lo": dd[1], "pmt_hi": dd[2]})
                row["agree_fast_minus_slow"] = bool(dd[1] <= 0 <= dd[2])
                intervals = ((row["ratio_lo"], row["ratio_hi"]), (t["ratio_lo"], t["ratio_hi"]))
                known = all(math.isfinite(x) for pair in intervals for x in pair)
                # None: a random cell is missing, so there is no ratio to compare
                row["agree_ratio"] = overlap(*intervals) if known else None
            rows.append(row)
    return rows


# -- report -------------------------------------------------------------------------------------
def _ci(row: Row, key: str, lo: str, hi: str, digits: int = 3) -> str:
    return fmt_ci(row[key], row[lo], row[hi], digits)


def verdict_lines(rows: Sequence[Row]) -> list[str]:
    lines = []
    for arena, t in DECISIVE:
        row = next(
            (r for r in rows if r["arena"] == arena and r["condition"] == softmax_condition(t)),
            None,
        )
        if row is None:
            continue
        lines.append(
            f"- `{arena}` (e = {_ci(row, 'e', 'e_lo', 'e_hi')}), softmax T = {t:g}: fast - slow "
            f"= {_ci(row, 'fast_minus_slow', 'fast_minus_slow_lo', 'fast_minus_slow_hi')} over "
            f"{row['trials']} trials: **{row['direction']}** (the smallest effect {row['trials']} "
            f"trials detect with 80 % power: {row['detectable_80']:.3f})."
        )
    return lines


def cells_table(rows: Sequence[Row]) -> str:
    header = [
        "arena",
        "e",
        "condition",
        "N",
        "fast - slow (95 % CI)",
        "twin: N, fast - slow",
        "3:0 time %",
        "Q gap fast - slow",
        "perf / random",
        "twin perf / random",
    ]
    body = []
    for r in rows:
        twin = (
            f"{r['twin_trials']}, "
            + _ci(r, "twin_fast_minus_slow", "twin_fast_minus_slow_lo", "twin_fast_minus_slow_hi")
            if "twin_trials" in r
            else "-"
        )
        body.append(
            [
                r["arena"],
                f"{r['e']:.2f}",
                r["condition"],
                r["trials"],
                _ci(r, "fast_minus_slow", "fast_minus_slow_lo", "fast_minus_slow_hi"),
                twin,
                _ci(r, "time_3_0_pct", "time_3_0_lo", "time_3_0_hi", 1),
                _ci(r, "q_gap_fast_minus_slow", "q_gap_lo", "q_gap_hi", 4)
                if math.isfinite(r["q_gap_fast_minus_slow"])
                else "-",
                _ci(r, "ratio_to_random", "ratio_lo", "ratio_hi"),
                _ci(r, "twin_ratio_to_random", "twin_ratio_lo", "twin_ratio_hi")
                if "twin_trials" in r
                else "-",
            ]
        )
    return markdown_table(header, body)


def twin_table(rows: Sequence[Row]) -> str:
    header = [
        "arena",
        "condition",
        "physics - twin, fast - slow (95 % CI)",
        "agree",
        "perf / random agree",
    ]
    body = [
        [
            r["arena"],
            r["condition"],
            _ci(r, "physics_minus_twin", "pmt_lo", "pmt_hi"),
            "yes" if r["agree_fast_minus_slow"] else "**no**",
            "-" if r["agree_ratio"] is None else "yes" if r["agree_ratio"] else "**no**",
        ]
        for r in rows
        if "physics_minus_twin" in r and r["condition"] != "random"
    ]
    return markdown_table(header, body) if body else "(no twin trials)"


def wall_lines(rows: Sequence[Row], s: Settings) -> list[str]:
    phys = sum(r["wall_s"] for r in rows)
    n_phys = sum(r["trials"] for r in rows)
    twin = sum(r.get("twin_wall_s", 0.0) for r in rows)
    n_twin = sum(r.get("twin_trials", 0) for r in rows)
    per = phys / max(n_phys, 1)
    lines = [
        f"- Physics: {n_phys} trials, {phys / 3600:.2f} h of trial wall time in all, "
        f"{per:.1f} s per trial: a {s.decisive_trials}-trial cell takes about "
        f"{s.decisive_trials * per / 2 / 60:.0f} min on 2 workers.",
    ]
    if n_twin:
        lines.append(
            f"- Twin: {n_twin} trials, {twin / 3600:.2f} h, {twin / n_twin:.2f} s per trial "
            f"({per / max(twin / n_twin, 1e-9):.0f}x faster than the physics)."
        )
    return lines


def report_body(rows: Sequence[Row], s: Settings) -> str:
    agree = [r for r in rows if "agree_fast_minus_slow" in r and r["condition"] != "random"]
    n_agree = sum(bool(r["agree_fast_minus_slow"]) for r in agree)
    return "\n".join(
        [
            "## Verdict",
            "",
            *verdict_lines(rows),
            "",
            f"Twin against physics (fast - slow): {n_agree} of {len(agree)} learning cells agree "
            "(the Welch 95 % interval of physics minus twin holds 0).",
            "",
            "## Method",
            "",
            f"Arenas {', '.join(f'`{a}`' for a in s.arena_list)}; e from the interference "
            f"study's cross runs ({s.e_seeds} seeds x {s.e_hours:g} h, percentile bootstrap over "
            f"seeds). Trials of {s.convergence_h:g} h convergence + {s.measured_h:g} h measured, "
            f"trial k with seed {s.seed} + k; {s.decisive_trials} physics trials in the decisive "
            f"cells, {s.trials} in the others, {s.twin_trials} twin trials per cell (twin tables: "
            f"{s.table_seeds} seeds x {s.table_hours:g} h of fixed-allocation physics runs per "
            "arena). Fast - slow: per trial, the mean share of the measured period fast robots "
            "spend on the high-value circuit minus the slow robots'; mean and Student-t 95 % "
            "interval over trials. 3:0: % of the measured period with the three fast robots on "
            "the high-value circuit and no slow one (the paper's T, Eq. 3, for fair coins: "
            f"{metrics.combinatorial_expectation(3, 3)[(3, 0)]:.2f} %; the random rows measure it "
            "in each arena). Q gap: per robot, the mean over states of "
            "Q(high) - Q(other) in its final table; fast robots' mean minus slow robots' per "
            "trial. Perf / random: ratio of mean performance to the same engine's random cell "
            "(delta-method interval).",
            "",
            "## Cells",
            "",
            cells_table(rows),
            "",
            "## The twin against the physics",
            "",
            twin_table(rows),
            "",
            "## Wall time",
            "",
            *wall_lines(rows, s),
            "",
        ]
    )


def plot(rows: Sequence[Row], path: Path) -> None:
    """Fast - slow against e: physics points with 95 % intervals, the twin's curve, per
    condition."""

    import matplotlib

    fig, ax = subplots(figsize=(8, 5))
    learning = [c for c in CONDITIONS if c != "random"]
    colours = matplotlib.colormaps["viridis"](np.linspace(0, 0.9, len(learning)))
    for k, (condition, colour) in enumerate(zip(learning, colours)):
        pts = sorted((r for r in rows if r["condition"] == condition), key=lambda r: r["e"])
        if not pts:
            continue
        x = np.array([r["e"] for r in pts]) + (k - len(learning) / 2) * 0.012
        y = np.array([r["fast_minus_slow"] for r in pts])
        err = np.vstack(
            [y - [r["fast_minus_slow_lo"] for r in pts], [r["fast_minus_slow_hi"] for r in pts] - y]
        )
        ax.errorbar(
            x, y, yerr=err, fmt="o", color=colour, capsize=3, label=f"{condition} (physics)"
        )
        if all("twin_fast_minus_slow" in r for r in pts):
            ax.plot(
                [r["e"] for r in pts],
                [r["twin_fast_minus_slow"] for r in pts],
                "--",
                color=colour,
                linewidth=1,
            )
    ax.axhline(0, color="black", linewidth=0.8)
    ax.axvline(1, color="grey", linewidth=0.8, linestyle=":")
    ax.set_xlabel("crowding elasticity e (1: crowding costs every robot the same fraction)")
    ax.set_ylabel("fast - slow share of time on the high-value circuit")
    ax.set_title("Differentiation against e (points: physics, 95 % CI; dashed: model twin)")
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


# -- the study ----------------------------------------------------------------------------------
def run(settings: Settings) -> Outcome:
    """Measure e and the twin tables of every arena, run (or resume) every trial, then write the
    report and the figure."""
    s = settings.sized()
    out = s.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    arenas = s.arena_list
    print(f"regime map: arenas {arenas}; results in {out}", flush=True)
    e = {
        a: measure_elasticity(
            arena_config(a),
            range(s.e_seeds),
            s.e_hours,
            workers=s.workers,
            out=out / "elasticity" / a,
        )
        for a in arenas
    }
    tables: dict[str, Mapping[str, Any]] = {}
    if s.twin_trials:
        jobs = [TablesJob(a, tuple(range(s.table_seeds)), s.table_hours, digest(a)) for a in arenas]
        done = run_jobs(jobs, TABLES, out / "twin_tables", s.workers, backend=s.backend)
        tables = {job.arena: done[TABLES.key(job)] for job in jobs}
    physics = physics_trials(s)
    twin = twin_trials(s, tables) if tables else []
    # The first arena's decisive cells, then the twin (cheap: its predictions for every cell
    # early), then the other physics trials.
    first = physics[0].arena
    n_first = sum(
        1
        for j in physics
        if j.arena == first and s.trials_in(j.arena, j.condition) == s.decisive_trials
    )
    order = physics[:n_first] + twin + physics[n_first:]
    print(f"{len(physics)} physics trials, {len(twin)} twin trials", flush=True)
    if s.interim:
        results = saved_results(order, TRIALS, out / "trials")
        provenance = run_metadata(
            settings=s.recorded(), interim=True, trials_saved=len(results), trials=len(order)
        )
    else:
        results, provenance = s.run_jobs(
            order, TRIALS, "trials", wall_of=lambda result: float(result["wall_s"])
        )
    records: dict[tuple[str, str, Engine], list[dict[str, Any]]] = {}
    for job in order:
        if trial_key(job) in results:
            records.setdefault((job.arena, job.condition, job.engine), []).append(
                results[trial_key(job)]
            )
    rows = summarise(records, e, arenas)
    name = "regime_map_interim" if s.interim else "regime_map"
    body = report_body(rows, s)
    if s.interim:
        body = (
            f"**Interim report of an unfinished sweep: {len(results)} of {len(order)} trials "
            "saved so far.** Each cell states its N; the sweep resumes with the same command "
            "without `--interim`.\n\n" + body
        )
    report = Report(
        name,
        "The regime map: differentiation against crowding elasticity"
        + (" (interim)" if s.interim else ""),
        body,
        rows,
        summary={
            "elasticity": {a: {"e": v.e, "low": v.low, "high": v.high} for a, v in e.items()},
            "decisive": [
                r
                for r in rows
                if (r["arena"], r["condition"]) in {(a, softmax_condition(t)) for a, t in DECISIVE}
            ],
        },
        figures=[(f"{name}.png", lambda path: plot(rows, path))],
    )
    written = report.write(out, provenance)
    text = "\n".join([*verdict_lines(rows), f"wrote {out / (name + '.md')}"])
    return Outcome(out, written, text)
