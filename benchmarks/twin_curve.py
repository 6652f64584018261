"""The model twin's fast - slow against the crowding elasticity e, on synthetic tables of e from 0.75
to 2.0 (2000 batched twin trials per point and condition: softmax TAVC at T = 0.002, 0.005, 0.01,
epsilon 0.1; 15 h + 5 h), the break-even e per condition, and the figure of the differentiation
page: these curves, the regime map's physics cells and the dahl2004_passing prediction and result
where committed. The design is in the study's docstring (`benchmarks/twin_curve.py`).

Writes `twin_curve.{md,csv,json}`, `twin_curve_trials.csv` and `differentiation.png` into a new
run folder (`--update-reference`: benchmarks/results/twin_curve/); `--resume RUN_DIR` continues.

    python benchmarks/twin_curve.py --workers 2        # 56 batches of 2000 trials: about 15 min
    python benchmarks/twin_curve.py --quick            # smoke run (seconds)
    python benchmarks/twin_curve.py --update-reference --figure-only   # redraw, run nothing

The twin's curve: fast - slow against the crowding elasticity e, on synthetic tables that differ
only in e (`tavc_agents.analysis.synthetic_tables`), and the figure that tells the package's story.

For every e of the grid (default 0.75 to 2.0; the family keeps the knee t(4) / t(3) >= 1.1 only
down to e = 0.744) and every condition (softmax TAVC at T = 0.002, 0.005, 0.01 and epsilon-greedy
TAVC with epsilon 0.1, scaled initialisation, 15 h + 5 h), `trials` batched twin trials
(`tavc_agents.experiments.twin_batch.run_batch`) give fast - slow (the fast robots' share of the
measured period on the high-value circuit minus the slow robots') with its Student-t 95 %
interval. Per condition, the break-even e where the curve crosses 0 (linear interpolation between
grid points), with a percentile bootstrap interval that resamples each point's trials.

The figure (`differentiation.png`): these curves with their intervals, the regime map's physics
cells of the same conditions at every arena's measured e (`benchmarks/results/regime_map/`), and,
where committed, the prediction and the physics result for `dahl2004_passing`
(`benchmarks/results/passing_prediction/prediction.json`, `benchmarks/results/passing/passing.csv`).
`--figure-only` redraws it from a finished run's report (after the passing results land) without
running a trial.

Each cell's batch is kept under `<out>/cache/` (git ignores it in the reference folder; the
per-trial values are in `twin_curve_trials.csv`), so `--resume RUN_DIR` continues a stopped run.
The script is `benchmarks/twin_curve.py`.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

import arena_runs
import tavc_env
from arena_analysis import Family, reach, with_elasticity
from arena_runs import learner_of, run_batch
from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table, write_csv
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.files import read_csv, read_report
from tavc_agents.experiments.study import (
    RESULTS_DIR,
    Outcome,
    StudySettings,
    at_least,
    positive,
    redraw_source,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import json_jobs

CONDITIONS = (*(arena_runs.softmax_condition(t) for t in (0.002, 0.005, 0.01)), "epsilon_0.1")
GRID = "0.75,0.8,0.9,1,1.1,1.2,1.3,1.4,1.5,1.6,1.7,1.8,1.9,2"
FIGURE = "differentiation.png"
PASSING = "dahl2004_passing"
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The twin's curve (its command line)."""

    quick_sizes: ClassVar = {
        "elasticities": "0.8,1,1.5",
        "trials": 40,
        "convergence_h": 1.0,
        "measured_h": 0.5,
        "resamples": 200,
    }
    recorded_fields: ClassVar = (
        "elasticities=grid above conditions trials convergence_h measured_h seed resamples family"
    )

    elasticities: str = GRID
    """comma-separated e of the synthetic tables, each within what the family reaches"""
    above: Literal["pace", "wait"] = "pace"
    """what makes e > 1: the fast robots' pace in slow company (reaches e = 2.04) or an additive
    wait equal for everyone (reaches only 1.17)"""
    trials: int = 2000
    """batched twin trials per e and condition"""
    convergence_h: float = 15.0
    """convergence period, simulated hours"""
    measured_h: float = 5.0
    """measured period, simulated hours"""
    seed: int = 0
    """the batch of grid point i and condition j draws from a generator seeded [seed, i, j]"""
    resamples: int = 2000
    """bootstrap resamples of the break-even e"""
    regime_map_dir: Path = RESULTS_DIR / "regime_map"
    """the regime map whose physics cells the figure shows"""
    passing_prediction: Path = RESULTS_DIR / "passing_prediction" / "prediction.json"
    """the twin's committed prediction for dahl2004_passing (drawn if it exists)"""
    passing_result: Path = RESULTS_DIR / "passing" / "passing.csv"
    """the physics result for dahl2004_passing (drawn if it exists)"""
    figure_only: bool = False
    """run nothing: redraw the figure from the report already in the output folder"""
    quick: bool = False
    """smoke run: 3 values of e, 40 trials of 1 h + 0.5 h, 200 resamples"""

    def __post_init__(self) -> None:
        super().__post_init__()
        try:
            grid = self.grid
        except ValueError:
            grid = []
        low, high = reach(Family(), self.above) if self.above in ("pace", "wait") else (0, 0)
        ok = bool(grid) and all(low <= e <= high for e in grid) and len(set(grid)) == len(grid)

        refuse_invalid(
            self,
            [
                ("above", self.above in ("pace", "wait"), "pace or wait"),
                (
                    "elasticities",
                    ok,
                    f"distinct comma-separated numbers in [{low:.4f}, {high:.4f}] (what the "
                    f"family reaches with {self.above!r} above 1)",
                ),
                ("trials", at_least(self.trials, 2), "an integer >= 2"),
                ("convergence_h", positive(self.convergence_h), "a finite number > 0"),
                ("measured_h", positive(self.measured_h), "a finite number > 0"),
                ("seed", at_least(self.seed, 0), "an integer >= 0"),
                ("resamples", at_least(self.resamples, 1), "an integer >= 1"),
                (
                    "regime_map_dir",
                    (Path(self.regime_map_dir) / "regime_map.csv").is_file(),
                    "a regime map's results folder (with regime_map.csv)",
                ),
            ],
        )

    @property
    def grid(self) -> list[float]:
        """The e of the grid, in increasing order (a ValueError for text that is not numbers)."""
        return sorted(float(x) for x in self.elasticities.split(",") if x.strip())

    @property
    def conditions(self) -> list[str]:
        return list(CONDITIONS)

    @property
    def family(self) -> str:
        return Family().describe()

    def reference_name(self) -> str:
        return "twin_curve" + ("_wait" if self.above == "wait" else "")


# -- jobs ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Point:
    """`trials` batched twin trials of one condition on the synthetic tables of elasticity `e`."""

    e: float
    above: str
    condition: str
    index: tuple[int, int]
    trials: int
    seed: int
    convergence_h: float
    measured_h: float
    family: str
    """the solved family member (`Family.describe`), so a changed family is not resumed"""


def point_key(point: Point) -> str:
    return f"e{point.e:g}__{point.condition}"


def family_of(e: float, above: str) -> Family:
    return with_elasticity(e, above="wait" if above == "wait" else "pace")


def run_point(point: Point) -> dict[str, Any]:
    """The batch's per-trial fast share, slow share and performance (rounded) and its wall time."""
    config = tavc_env.make_config("dahl2004")  # the paper's team and circuits, 2200 / 2000
    started = time.perf_counter()
    out = run_batch(
        config,
        family_of(point.e, point.above).tables(config),
        learner_of(point.condition),
        point.trials,
        np.random.default_rng([point.seed, *point.index]),
        point.convergence_h * 3600.0,
        point.measured_h * 3600.0,
    )
    return {
        "fast_share": [round(float(v), 6) for v in out.fast_share],
        "slow_share": [round(float(v), 6) for v in out.slow_share],
        "performance": [round(float(v), 6) for v in out.performance],
        "wall_s": round(time.perf_counter() - started, 3),
    }


POINTS = json_jobs(run_point, point_key, unit="point")


def points(s: Settings) -> list[Point]:
    return [
        Point(
            e,
            s.above,
            c,
            (i, j),
            s.trials,
            s.seed,
            s.convergence_h,
            s.measured_h,
            family_of(e, s.above).describe(),
        )
        for i, e in enumerate(s.grid)
        for j, c in enumerate(CONDITIONS)
    ]


# -- analysis -----------------------------------------------------------------------------------
def diffs(result: Mapping[str, Any]) -> np.ndarray:
    """Per trial, fast share minus slow share."""
    return np.asarray(result["fast_share"], dtype=float) - np.asarray(result["slow_share"], float)


def point_row(point: Point, result: Mapping[str, Any]) -> Row:
    family = family_of(point.e, point.above)
    d = diffs(result)
    mean, lo, hi, n = mean_ci(d.tolist())
    perf, perf_lo, perf_hi, _ = mean_ci(list(result["performance"]))
    return {
        "e": point.e,
        "condition": point.condition,
        "handling_s": family.handling_s,
        "pace": family.pace,
        "wait_s": family.wait_s,
        "knee": family.knee(),
        "trials": n,
        "fast_share": float(np.mean(result["fast_share"])),
        "slow_share": float(np.mean(result["slow_share"])),
        "fast_minus_slow": mean,
        "fast_minus_slow_lo": lo,
        "fast_minus_slow_hi": hi,
        "fast_minus_slow_sd": float(np.std(d, ddof=1)),
        "performance": perf,
        "performance_lo": perf_lo,
        "performance_hi": perf_hi,
        "wall_s": float(result["wall_s"]),
    }


def crossing(e: Sequence[float], values: Sequence[float]) -> float:
    """The first e (in increasing order) where `values` changes sign from >= 0 to < 0, linearly
    interpolated between grid points; nan if it never does."""
    for k in range(len(e) - 1):
        a, b = values[k], values[k + 1]
        if a >= 0 > b:
            return float(e[k] + (e[k + 1] - e[k]) * a / (a - b))
    return math.nan


def break_even(
    e: Sequence[float], per_trial: Sequence[np.ndarray], rng: np.random.Generator, resamples: int
) -> Row:
    """The curve's break-even e and a percentile bootstrap 95 % interval (each point's trials
    resampled independently, draws from `rng`); `no_crossing` is the share of resamples in which
    the curve stays on one side."""
    point = crossing(e, [float(np.mean(x)) for x in per_trial])
    found = []
    for _ in range(resamples):
        means = [float(x[rng.integers(0, len(x), len(x))].mean()) for x in per_trial]
        found.append(crossing(e, means))
    arr = np.asarray(found)
    ok = arr[np.isfinite(arr)]
    lo, hi = (float(v) for v in np.quantile(ok, [0.025, 0.975])) if ok.size else (math.nan,) * 2
    return {
        "break_even_e": point,
        "break_even_lo": lo,
        "break_even_hi": hi,
        "no_crossing": float(1.0 - ok.size / len(arr)),
    }


# -- the figure's other sources -----------------------------------------------------------------
def physics_points(regime_map_dir: Path) -> list[PhysicsPoint]:
    """The regime map's physics cells of `CONDITIONS`, each at its arena's measured e."""
    rows = list(read_csv(Path(regime_map_dir) / "regime_map.csv"))
    return [
        PhysicsPoint(
            r["condition"],
            r["arena"],
            float(r["e"]),
            float(r["e_lo"]),
            float(r["e_hi"]),
            float(r["fast_minus_slow"]),
            float(r["fast_minus_slow_lo"]),
            float(r["fast_minus_slow_hi"]),
            int(r["trials"]),
        )
        for r in rows
        if r["condition"] in CONDITIONS
    ]


def passing_points(prediction: Path, result: Path) -> tuple[list[PhysicsPoint], list[PhysicsPoint]]:
    """The twin's prediction and the physics result for dahl2004_passing (empty where the file
    is not there yet), at the e the prediction measured."""
    if not Path(prediction).is_file():
        return [], []
    summary = read_report(prediction)["summary"]
    e = summary["elasticity"]

    def as_points(rows: Sequence[Mapping[str, Any]], n_key: str) -> list[PhysicsPoint]:
        return [
            PhysicsPoint(
                str(r["condition"]),
                PASSING,
                float(e["e"]),
                float(e["low"] if e["low"] is not None else math.nan),
                float(e["high"] if e["high"] is not None else math.nan),
                float(r["fast_minus_slow"]),
                float(r["fast_minus_slow_lo"]),
                float(r["fast_minus_slow_hi"]),
                int(r[n_key]),
            )
            for r in rows
            if r["condition"] in CONDITIONS
        ]

    predicted = as_points(summary["conditions"], "twin_trials")
    if not Path(result).is_file():
        return predicted, []
    return predicted, as_points(list(read_csv(result)), "trials")


def curves(rows: Sequence[Row]) -> list[Curve]:
    out = []
    for c in CONDITIONS:
        mine = sorted((r for r in rows if r["condition"] == c), key=lambda r: float(r["e"]))
        if mine:
            out.append(
                Curve(
                    c,
                    [float(r["e"]) for r in mine],
                    [float(r["fast_minus_slow"]) for r in mine],
                    [float(r["fast_minus_slow_lo"]) for r in mine],
                    [float(r["fast_minus_slow_hi"]) for r in mine],
                )
            )
    return out


def draw(rows: Sequence[Row], s: Settings, path: Path) -> None:
    predicted, result = passing_points(s.passing_prediction, s.passing_result)
    differentiation_figure(
        curves(rows), physics_points(s.regime_map_dir), predicted, result, path, s.trials
    )


# -- report -------------------------------------------------------------------------------------
def passing_status(s: Settings) -> str:
    predicted, result = passing_points(s.passing_prediction, s.passing_result)
    if not predicted:
        return (
            f"`{PASSING}`: pending (no committed prediction yet); the figure shows it once "
            "`benchmarks/results/passing_prediction/prediction.json` exists "
            "(`--figure-only` redraws)."
        )
    e = predicted[0]
    text = f"`{PASSING}` (e = {e.e:.3f}): the twin's prediction is drawn"
    return text + (
        " with the physics result beside it." if result else "; its physics result is pending."
    )


def scale_note(rows: Sequence[Row]) -> list[str]:
    """Why the softmax curves fall at the lowest e (where there is an H), as paragraph lines."""
    longest = max(rows, key=lambda r: r["handling_s"])
    if longest["handling_s"] <= 0:
        return []
    return [
        f"Reading the lowest e: H lengthens every task (at e = {longest['e']:g} a fast robot "
        f"alone takes {longest['handling_s'] + Family().b_fast_s:.0f} s, against "
        f"{Family().b_fast_s:g} s at e = 1), so every reward w / t is smaller and a fixed "
        "softmax temperature is relatively hotter: the softmax robots explore more and the "
        "higher temperatures differentiate less there. Epsilon-greedy does not depend on the "
        "reward scale.",
        "",
    ]


def report_body(rows: Sequence[Row], evens: Sequence[Row], s: Settings) -> str:
    grid = s.grid
    table = []
    for e in grid:
        at = {r["condition"]: r for r in rows if r["e"] == e}
        first = at[CONDITIONS[0]]
        table.append(
            [
                f"{e:g}",
                f"{first['handling_s']:.1f}",
                f"{first['pace']:.3f}" if s.above == "pace" else f"{first['wait_s']:.1f}",
                f"{first['knee']:.3f}",
                *(
                    fmt_ci(
                        at[c]["fast_minus_slow"],
                        at[c]["fast_minus_slow_lo"],
                        at[c]["fast_minus_slow_hi"],
                        3,
                    )
                    for c in CONDITIONS
                ),
            ]
        )
    lines = [
        f"- `{b['condition']}`: break-even e = "
        + (
            fmt_ci(b["break_even_e"], b["break_even_lo"], b["break_even_hi"], 3)
            if math.isfinite(b["break_even_e"])
            else "none in the grid"
        )
        + (
            f" (no crossing in {100 * b['no_crossing']:.1f} % of resamples)"
            if b["no_crossing"] > 0
            else ""
        )
        for b in evens
    ]
    return "\n".join(
        [
            "## Break-even",
            "",
            "Where the twin's fast - slow crosses 0 (linear interpolation between grid points; "
            f"95 % percentile bootstrap over each point's trials, {s.resamples} resamples):",
            "",
            *lines,
            "",
            passing_status(s),
            "",
            *scale_note(rows),
            "## Method",
            "",
            f"Synthetic tables (`tavc_agents.analysis.synthetic_tables`): {Family().describe()}; "
            f"H solved for e < 1, {'the pace p' if s.above == 'pace' else 'the wait W'} for "
            "e > 1, each by bisection on e of circuit 0's tables. Knee: t(4) / t(3) of a "
            "homogeneous team of the mean speed (free time 72 s). The paper's team (3 fast at "
            "0.30 m/s, 3 slow at 0.20 m/s) on two circuits worth 2200 and 2000. "
            f"{s.trials} batched twin trials per point and condition, {s.convergence_h:g} h + "
            f"{s.measured_h:g} h, scaled initialisation; fast - slow per trial is the fast robots' "
            "mean share of the measured period on the high-value circuit minus the slow robots'; "
            "mean and Student-t 95 % interval over trials. Per-trial values: "
            "`twin_curve_trials.csv`.",
            "",
            "## Fast - slow against e",
            "",
            markdown_table(
                [
                    "e",
                    "H (s)",
                    "pace p" if s.above == "pace" else "W (s)",
                    "t(4)/t(3)",
                    *CONDITIONS,
                ],
                table,
            ),
            "",
            f"![fast - slow against e]({FIGURE})",
            "",
        ]
    )


def read_rows(path: Path) -> list[Row]:
    """The rows of a written `twin_curve.csv` (numbers as floats), for `--figure-only`."""
    return [
        {k: (v if k == "condition" else float(v) if v else math.nan) for k, v in r.items()}
        for r in read_csv(redraw_source(path))
    ]


def run(settings: Settings) -> Outcome:
    """Run (or resume) every point's batch, then write the report, the per-trial CSV and the
    figure; with `figure_only`, redraw the figure from the report in the output folder."""
    s = settings.sized()
    out = s.out_dir()
    if s.figure_only:
        rows = read_rows(out / "twin_curve.csv")
        draw(rows, s, out / FIGURE)
        return Outcome(out, [out / FIGURE], passing_status(s))
    jobs = points(s)
    results, provenance = s.run_jobs(
        jobs, POINTS, "cache", wall_of=lambda result: float(result["wall_s"])
    )
    rows = [point_row(job, results[point_key(job)]) for job in jobs]
    # the bootstrap's own stream: batches draw from [seed, i, j] with i < len(grid)
    rng = np.random.default_rng([s.seed, len(s.grid), len(CONDITIONS)])
    evens = [
        {
            "condition": c,
            **break_even(
                s.grid,
                [diffs(results[point_key(j)]) for j in jobs if j.condition == c],
                rng,
                s.resamples,
            ),
        }
        for c in CONDITIONS
    ]
    per_trial = [
        {
            "e": job.e,
            "condition": job.condition,
            "trial": k,
            "fast_share": results[point_key(job)]["fast_share"][k],
            "slow_share": results[point_key(job)]["slow_share"][k],
            "performance": results[point_key(job)]["performance"][k],
        }
        for job in jobs
        for k in range(job.trials)
    ]
    write_csv(out / "twin_curve_trials.csv", per_trial, list(per_trial[0]))
    body = report_body(rows, evens, s)
    report = Report(
        "twin_curve",
        "The twin's curve: fast - slow against crowding elasticity on synthetic tables",
        body,
        rows,
        summary={"break_even": evens, "passing": passing_status(s), "settings": s.recorded()},
        figures=[(FIGURE, lambda path: draw(rows, s, path))],
    )
    written = [out / "twin_curve_trials.csv", *report.write(out, provenance)]
    return Outcome(out, written, body.split("## Method")[0])


# -- the figure -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Curve:
    """A model-twin curve: fast - slow with its 95 % interval at each e, for one condition."""

    condition: str
    e: Sequence[float]
    mean: Sequence[float]
    low: Sequence[float]
    high: Sequence[float]


@dataclass(frozen=True)
class PhysicsPoint:
    """One cell: a condition in an arena of elasticity `e` [e_low, e_high], its fast - slow
    [low, high] over `trials` trials."""

    condition: str
    arena: str
    e: float
    e_low: float
    e_high: float
    mean: float
    low: float
    high: float
    trials: int


def _error(centre: Sequence[float], low: Sequence[float], high: Sequence[float]) -> np.ndarray:
    """Error-bar lengths below and above (0 where an end is not finite)."""
    c, lo, hi = (np.asarray(x, dtype=float) for x in (centre, low, high))
    return np.nan_to_num(np.vstack([c - lo, hi - c]), nan=0.0).clip(min=0.0)


def differentiation_figure(
    curves: Sequence[Curve],
    physics: Sequence[PhysicsPoint],
    predicted: Sequence[PhysicsPoint],
    result: Sequence[PhysicsPoint],
    path: str | Path,
    twin_trials: int,
) -> None:
    """Fast - slow against crowding elasticity e: the twin's curves on synthetic tables (line and
    95 % band), physics cells of every arena (circles, 95 % intervals; side by side within an
    arena), and the twin's prediction (open diamonds) and physics result (stars) for the arena
    where robots can pass. One colour per condition, in the order of `curves`; the e = 1 and
    zero lines. A note says what is missing when `predicted` or `result` is empty."""
    import matplotlib
    from matplotlib.lines import Line2D

    conditions = [c.condition for c in curves]
    conditions += sorted({p.condition for p in (*physics, *predicted, *result)} - {*conditions})
    palette = matplotlib.colormaps["tab10"]
    colour = {c: palette(k) for k, c in enumerate(conditions)}
    offset = {c: (k - (len(conditions) - 1) / 2) * 0.018 for k, c in enumerate(conditions)}
    fig, ax = subplots(figsize=(10.5, 6.2))
    for curve in curves:
        ax.fill_between(curve.e, curve.low, curve.high, color=colour[curve.condition], alpha=0.18)
        ax.plot(curve.e, curve.mean, "-", color=colour[curve.condition], lw=1.8)
    # within an arena the conditions stand side by side; the passing arena's prediction just
    # left of its result, so that the two do not hide each other
    for points, shift, marker, size, face in (
        (physics, 0.0, "o", 5, None),
        (predicted, -0.011, "D", 6, "white"),
        (result, 0.011, "*", 12, None),
    ):
        for p in points:
            ax.errorbar(
                p.e + 2 * offset[p.condition] * bool(shift) + offset[p.condition] + shift,
                p.mean,
                yerr=_error([p.mean], [p.low], [p.high]),
                fmt=marker,
                ms=size,
                color=colour[p.condition],
                mfc=face or colour[p.condition],
                capsize=2.5,
                lw=1.1,
                zorder=3,
            )
    ax.axhline(0.0, color="black", lw=0.9)
    ax.axvline(1.0, color="grey", lw=0.9, ls=":")
    # room above the data for the arena labels (three staggered rows), anchored to the top
    low, high = ax.get_ylim()
    ax.set_ylim(low, high + 0.22 * (high - low))
    arenas = sorted({(p.e, p.arena) for p in (*physics, *predicted)})
    level = 0
    for k, (e, arena) in enumerate(arenas):
        # labels of arenas closer than a label's width go one row lower, in turn
        level = (level + 1) % 3 if k > 0 and e - arenas[k - 1][0] < 0.35 else 0
        ax.annotate(
            f"{arena}\ne = {e:.2f}",
            (e, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(0, -3 - 21 * level),
            textcoords="offset points",
            ha="center",
            va="top",
            fontsize=7,
            color="0.3",
        )
    ax.annotate(
        "e = 1: crowding costs every robot the same fraction",
        (1.0, 0.0),
        xycoords=("data", "axes fraction"),
        xytext=(-3, 4),
        textcoords="offset points",
        rotation=90,
        ha="right",
        va="bottom",
        fontsize=7,
        color="0.35",
    )
    for sign, text in (
        (1, "\u2191 paper's direction: fast robots on the high-value circuit"),
        (-1, "\u2193 reversed: slow robots on the high-value circuit"),
    ):
        ax.annotate(
            text,
            (0.995, 0.0),
            xycoords=ax.get_yaxis_transform(),  # x in axes fraction, y in data
            xytext=(0, 4 * sign),
            textcoords="offset points",
            ha="right",
            va="bottom" if sign > 0 else "top",
            fontsize=8,
            color="0.35",
        )
    handles = [Line2D([], [], color=colour[c], lw=6, alpha=0.5, label=c) for c in conditions]
    handles += [
        Line2D(
            [],
            [],
            color="0.3",
            lw=1.8,
            label=f"model twin, synthetic tables ({twin_trials} trials per point, 95 % band)",
        ),
        Line2D(
            [],
            [],
            color="0.3",
            marker="o",
            ls="",
            label="physics cell of an arena (regime map, 95 % CI)",
        ),
    ]
    pending = []
    if predicted:
        handles.append(
            Line2D(
                [],
                [],
                color="0.3",
                marker="D",
                mfc="white",
                ls="",
                label=f"{predicted[0].arena}: twin prediction",
            )
        )
    else:
        pending.append("its twin prediction")
    if result:
        handles.append(
            Line2D(
                [],
                [],
                color="0.3",
                marker="*",
                ms=11,
                ls="",
                label=f"{result[0].arena}: physics result",
            )
        )
    else:
        pending.append("its physics result")
    # the empty lower middle: clear of the physics cells near e = 1 and of the lowest arenas
    ax.legend(
        handles=handles, fontsize=7.5, loc="lower left", bbox_to_anchor=(0.47, 0.06), framealpha=0.9
    )
    if pending:
        ax.text(
            0.99,
            0.02,
            "dahl2004_passing (robots can pass): " + " and ".join(pending) + " pending",
            transform=ax.transAxes,
            ha="right",
            va="bottom",
            fontsize=8,
            style="italic",
            color="0.3",
        )
    ax.set_xlabel(
        "crowding elasticity e   (< 1: crowding costs slow robots the larger fraction; > 1: fast robots)"
    )
    ax.set_ylabel("fast - slow share of the measured period\non the high-value circuit")
    ax.set_title(
        "Emergent differentiation against crowding elasticity (softmax / epsilon TAVC, 15 h + 5 h)"
    )
    ax.grid(alpha=0.25)
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
