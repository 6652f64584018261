"""The decisive test of emergent differentiation where robots can pass (`dahl2004_passing`), in two
stages: `--stage predict` measures the arena's e, rho and twin tables and commits the batched twin's
prediction of fast - slow with the physics trials each cell needs for 80 % power (the plan);
`--stage test` runs exactly those physics trials (resumable) and sets each result beside its
prediction.

Writes `prediction.{md,csv,json}` and `prediction_trials.csv` (predict), or `passing.{md,csv,json}`
and every trial under trials/ (test), into a new run folder under runs/ (git ignores it), `--out`,
or with `--update-reference` benchmarks/results/passing_prediction/ or benchmarks/results/passing/;
`--resume RUN_DIR` continues an interrupted run.

    python benchmarks/passing.py --stage predict    # minutes: e, twin tables, 5 x 2000 twin trials
    python benchmarks/passing.py --stage test       # hours: about a thousand 20-h physics trials
    python benchmarks/passing.py --quick --arena dahl2004_bays   # smoke run

The decisive test of emergent differentiation, in the arena where robots can pass
(`dahl2004_passing`, chosen by the third design search of `benchmarks/congestion_design.py`
from physics alone), in two stages whose order the git history shows:

1. `--stage predict`: the arena's crowding elasticity e and pace in company rho (the interference
   study's cross runs), its twin tables (`build_tables`, as the regime map measures them), then
   `--twin-trials` batched twin trials per condition (softmax TAVC at T = 0.002, 0.005 and 0.01,
   epsilon 0.1, random; 15 h + 5 h) predict fast - slow with its 95 % interval. From the twin's
   per-trial spread sd and predicted effect d, the physics trials a cell needs for 80 % power in a
   two-sided 5 % test, n = ((z_0.975 + z_0.80) sd / d)^2, at least `min_decisive`. The plan: the
   two temperatures with the largest predicted fast - slow get those trials (at most
   `max_decisive`), random allocation `control_trials`, the other conditions `other_trials`. The
   prediction and the plan are written before any physics learning trial runs on the arena.
2. `--stage test`: the physics trials of the committed plan (`--prediction`), resumable, and the
   report: per cell fast - slow (mean, Student-t 95 % interval, a Wilcoxon signed-rank test against
   0), the time in 3:0, the learned Q gap of fast minus slow robots, performance relative to
   random, each beside the twin's prediction.

The script is `benchmarks/passing.py`.
"""

from __future__ import annotations

import itertools
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from scipy import stats

import arena_runs
from arena_runs import learner_of, measure_elasticity, run_batch, trials_for_power
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table, write_csv
from tavc_agents.analysis.stats import mean_ci, ratio_ci
from tavc_agents.experiments.files import read_report
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.study import RESULTS_DIR, Outcome, at_least, refuse_invalid, run_study
from tavc_agents.experiments.sweep import run_jobs
from tavc_agents.model import (
    CompletionModel,
    SpeedClasses,
    allocation_of,
    load_model,
    missing_model,
)
from tavc_env import ArenaConfig
from tavc_env.twin import InterferenceTables
from tavc_env.validation import require

TEMPERATURES = (0.002, 0.005, 0.01)
CONDITIONS = (*(arena_runs.softmax_condition(t) for t in TEMPERATURES), "epsilon_0.1", "random")
PROMISING = 2
"""softmax cells that get the decisive number of trials"""
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(arena_runs.CellDesign):
    """The decisive test's settings (its command line); the twin's cell k draws from [seed, k]."""

    quick_sizes: ClassVar = {
        **arena_runs.QUICK_DESIGN,
        "twin_trials": 50,
        "min_decisive": 3,
        "max_decisive": 3,
        "control_trials": 2,
        "other_trials": 2,
    }

    stage: Literal["predict", "test"] = "predict"
    """predict (twin only: the prediction and the plan) or test (the plan's physics trials)"""
    arena: str = "dahl2004_passing"
    """the arena (a name of the regime map's arenas)"""
    twin_trials: int = 2000
    """batched twin trials per condition (predict)"""
    min_decisive: int = 430
    """the fewest physics trials of a decisive cell (predict)"""
    max_decisive: int = 2000
    """the most physics trials of a decisive cell, whatever the power analysis asks (predict)"""
    control_trials: int = 100
    """physics trials of random allocation (predict)"""
    other_trials: int = 60
    """physics trials of every other condition (predict)"""
    prediction: Path = RESULTS_DIR / "passing_prediction" / "prediction.json"
    """the committed prediction whose plan the test stage runs (test)"""
    quick: bool = False
    """smoke run: 50 twin trials, 2 to 3 physics trials of 0.3 + 0.2 h, short e and table runs"""

    def __post_init__(self) -> None:
        super().__post_init__()

        refuse_invalid(
            self,
            [
                ("stage", self.stage in ("predict", "test"), "predict or test"),
                (
                    "arena",
                    self.arena in arena_runs.ARENAS,
                    f"one of {', '.join(arena_runs.ARENAS)}",
                ),
                ("twin_trials", at_least(self.twin_trials, 2), "an integer >= 2"),
                ("min_decisive", at_least(self.min_decisive, 2), "an integer >= 2"),
                (
                    "max_decisive",
                    at_least(self.max_decisive, 2) and self.max_decisive >= self.min_decisive,
                    "an integer >= min_decisive",
                ),
                ("control_trials", at_least(self.control_trials, 2), "an integer >= 2"),
                ("other_trials", at_least(self.other_trials, 2), "an integer >= 2"),
            ],
        )

    @property
    def arena_sha(self) -> str:
        return arena_runs.digest(self.arena)

    @property
    def prediction_name(self) -> str:
        return Path(self.prediction).name

    def reference_name(self) -> str:
        return "passing_prediction" if self.stage == "predict" else "passing"

    def recorded(self) -> dict[str, Any]:
        both = "stage arena arena_sha convergence_h measured_h seed"
        if self.stage == "test":
            return self.recorded_of(f"{both} prediction=prediction_name")
        predict = "twin_trials min_decisive max_decisive control_trials other_trials"
        return self.recorded_of(f"{both} {predict} e_seeds e_hours table_seeds table_hours")


# -- stage 1: the prediction --------------------------------------------------------------------
def _effect(row: Row, prefix: str = "") -> str:
    """A row's fast - slow with its 95 % interval (`prefix` "predicted_": the twin's)."""
    key = f"{prefix}fast_minus_slow"
    return fmt_ci(row[key], row[f"{key}_lo"], row[f"{key}_hi"], 3)


def predict_cell(
    condition: str, diff: np.ndarray, perf: np.ndarray, random_perf: np.ndarray
) -> Row:
    """The twin's prediction for one condition from its per-trial fast - slow and performance."""
    d, lo, hi, n = mean_ci(diff.tolist())
    sd = float(np.std(diff, ddof=1))
    ratio = ratio_ci(perf.tolist(), random_perf.tolist())
    return {
        "condition": condition,
        "twin_trials": n,
        "fast_minus_slow": d,
        "fast_minus_slow_lo": lo,
        "fast_minus_slow_hi": hi,
        "fast_minus_slow_sd": sd,
        "trials_for_80_power": trials_for_power(sd, d),
        "ratio_to_random": ratio[0],
        "ratio_lo": ratio[1],
        "ratio_hi": ratio[2],
    }


def plan(rows: Sequence[Row], s: Settings) -> dict[str, int]:
    """Physics trials per condition: the `PROMISING` softmax cells with the largest predicted
    fast - slow get what the power analysis asks for (within [min_decisive, max_decisive])."""
    softmax = [r for r in rows if r["condition"].startswith("softmax")]
    best = sorted(softmax, key=lambda r: -r["fast_minus_slow"])[:PROMISING]
    out = {r["condition"]: s.other_trials for r in rows}
    out["random"] = s.control_trials
    for r in best:
        needed = r["trials_for_80_power"]
        wanted = s.max_decisive if not math.isfinite(needed) else math.ceil(needed)
        out[r["condition"]] = min(max(wanted, s.min_decisive), s.max_decisive)
    return out


def _twin_outcomes(
    s: Settings, tables: Mapping[str, Any]
) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per condition the batched twin's per-trial fast share, slow share and performance."""
    config = arena_runs.arena_config(s.arena)
    twin = InterferenceTables.from_dict(tables)
    out = {}
    for k, condition in enumerate(CONDITIONS):
        batch = run_batch(
            config,
            twin,
            learner_of(condition),
            s.twin_trials,
            np.random.default_rng([s.seed, k]),
            s.convergence_h * 3600.0,
            s.measured_h * 3600.0,
        )
        out[condition] = (batch.fast_share, batch.slow_share, batch.performance)
    return out


def _prediction_body(s: Settings, e: Any, rows: Sequence[Row], trials: Mapping[str, int]) -> str:
    table = markdown_table(
        [
            "condition",
            "twin trials",
            "predicted fast - slow (95 % CI)",
            "per-trial sd",
            "trials for 80 % power",
            "twin perf / random",
            "physics trials planned",
        ],
        [
            [
                r["condition"],
                r["twin_trials"],
                _effect(r),
                f"{r['fast_minus_slow_sd']:.3f}",
                "inf"
                if not math.isfinite(r["trials_for_80_power"])
                else f"{math.ceil(r['trials_for_80_power'])}",
                fmt_ci(r["ratio_to_random"], r["ratio_lo"], r["ratio_hi"], 3),
                trials[r["condition"]],
            ]
            for r in rows
        ],
    )
    decisive = [c for c, n in trials.items() if n >= s.min_decisive and c.startswith("softmax")]
    lines = [
        f"- `{r['condition']}`: the twin predicts fast - slow = "
        + _effect(r)
        + f"; {trials[r['condition']]} physics trials planned."
        for r in rows
        if r["condition"] in decisive
    ]
    return "\n".join(
        [
            "## Prediction",
            "",
            f"`{s.arena}`: e = {e.text()}, rho = {e.rho_text()} (alone {e.rho_alone:.3f}), "
            f"{e.n_seeds} seeds x {s.e_hours:g} h.",
            "",
            *lines,
            "",
            "Committed before any physics learning trial ran on this arena; the test stage "
            "(`python benchmarks/passing.py --stage test`) runs exactly the planned trials.",
            "",
            "## Method",
            "",
            f"Twin tables: {s.table_seeds} seeds x {s.table_hours:g} h of fixed-allocation physics "
            f"runs (as the regime map measures them). {s.twin_trials} batched twin trials per "
            f"condition, {s.convergence_h:g} h + {s.measured_h:g} h. Fast - slow per trial: the "
            "fast robots' share of the measured period on the high-value circuit minus the slow "
            "robots'; mean with a Student-t 95 % interval. Trials for 80 % power in a two-sided "
            "5 % test: ((z_0.975 + z_0.80) sd / d)^2 from the twin's sd and predicted d. The two "
            f"temperatures with the largest predicted d get max({s.min_decisive}, that) trials "
            f"(at most {s.max_decisive}); random {s.control_trials}; the others "
            f"{s.other_trials}.",
            "",
            "## Conditions",
            "",
            table,
            "",
        ]
    )


def run_predict(s: Settings) -> Outcome:
    out = s.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    e = measure_elasticity(
        arena_runs.arena_config(s.arena),
        range(s.e_seeds),
        s.e_hours,
        workers=s.workers,
        out=out / "elasticity",
    )
    job = arena_runs.TablesJob(
        s.arena, tuple(range(s.table_seeds)), s.table_hours, arena_runs.digest(s.arena)
    )
    tables = run_jobs([job], arena_runs.TABLES, out / "twin_tables", s.workers, backend=s.backend)[
        arena_runs.TABLES.key(job)
    ]
    outcomes = _twin_outcomes(s, tables)
    random_perf = outcomes["random"][2]
    rows = [
        predict_cell(c, fast - slow, perf, random_perf)
        for c, (fast, slow, perf) in outcomes.items()
    ]
    trials = plan(rows, s)
    per_trial = [
        {
            "condition": c,
            "trial": k,
            "fast_share": float(fast[k]),
            "slow_share": float(slow[k]),
            "performance": float(perf[k]),
        }
        for c, (fast, slow, perf) in outcomes.items()
        for k in range(len(fast))
    ]
    write_csv(out / "prediction_trials.csv", per_trial, list(per_trial[0]))
    provenance = run_metadata(settings=s.recorded())
    body = _prediction_body(s, e, rows, trials)
    report = Report(
        "prediction",
        f"The twin's prediction for `{s.arena}`, before its physics",
        body,
        rows,
        summary={
            "arena": s.arena,
            "elasticity": {"e": e.e, "low": e.low, "high": e.high, "n_seeds": e.n_seeds},
            "pace_in_company": {"rho": e.rho, "low": e.rho_low, "high": e.rho_high},
            "rho_alone": e.rho_alone,
            "plan": trials,
            "conditions": rows,
            "settings": s.recorded(),
        },
    )
    written = [out / "prediction_trials.csv", *report.write(out, provenance)]
    return Outcome(out, written, body.split("## Method")[0])


# -- stage 2: the physics -----------------------------------------------------------------------
def load_plan(path: Path) -> tuple[dict[str, int], Mapping[str, Any], list[Row]]:
    """The plan, settings and predicted rows of a committed prediction (`prediction.json`)."""
    try:
        data = read_report(path)
        summary = data["summary"]
        return dict(summary["plan"]), summary["settings"], list(summary["conditions"])
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ValueError(
            f"prediction = {str(path)!r} is invalid ({error}); allowed: the prediction.json the "
            "predict stage wrote"
        ) from None


def test_jobs(s: Settings, trials: Mapping[str, int]) -> list[arena_runs.MapTrial]:
    """The planned physics trials, seed by seed across cells (a sweep stopped early leaves the
    same seeds in every cell, the decisive cells' extra seeds last)."""
    most = max(trials.values())
    return [
        arena_runs.MapTrial(
            s.arena,
            c,
            s.seed + k,
            s.convergence_h,
            s.measured_h,
            arena_sha=arena_runs.digest(s.arena),
        )
        for k in range(most)
        for c in CONDITIONS
        if k < trials[c]
    ]


def test_row(
    condition: str,
    records: Sequence[Mapping[str, Any]],
    random: Sequence[Mapping[str, Any]],
    predicted: Row,
) -> Row:
    row: Row = {"condition": condition, **arena_runs.cell_row(records, random)}
    diff = arena_runs.diff_of(records)
    row["wilcoxon_p"] = (
        float(stats.wilcoxon(diff).pvalue) if len(diff) >= 10 and any(diff) else math.nan
    )
    row["direction"] = arena_runs.direction(row)
    for key in ("fast_minus_slow", "fast_minus_slow_lo", "fast_minus_slow_hi", "ratio_to_random"):
        row[f"predicted_{key}"] = predicted[key]
    return row


def start_value(model: CompletionModel, config: ArenaConfig) -> float:
    """The model's performance of the start allocation, expected over the random order `reset`
    draws (robots at ranks 0, 2, 4, ... on circuit 0 of two): what `stay` holds all along."""
    require(config.n_circuits == 2, "config.n_circuits", config.n_circuits, "2")
    classes = SpeedClasses.of(config)
    n = config.n_robots
    values = [
        model.performance(
            allocation_of([0 if i in first else 1 for i in range(n)], classes, config.n_circuits)
        )
        for first in itertools.combinations(range(n), (n + 1) // 2)
    ]
    return float(np.mean(values))


def value_lines(arena: str, rows: Sequence[Row]) -> list[str]:
    """The model optimum, the start allocation (`stay`) and each cell as fractions of it, from the
    arena's shipped TAVC model (a line saying why not, where it has none)."""
    preset = arena_runs.ARENAS[arena]
    why = missing_model(str(preset["preset"])) if set(preset) == {"preset"} else "overrides"
    if why is not None:
        return [f"No TAVC model of `{arena}` to value its allocations against ({why})."]
    config = arena_runs.arena_config(arena)
    model = load_model(str(preset["preset"]))
    best = model.optimum()
    optimum = model.performance(best)
    start = start_value(model, config)
    lines = [
        f"Model optimum ({' | '.join(f'c{i}: {model.describe(g)}' for i, g in enumerate(best))}): "
        f"{optimum:.4f} per robot per 10 s. The start allocation, which `stay` keeps, is worth "
        f"{start / optimum:.3f} of it (expected over the random start order).",
        "",
    ]
    for r in rows:
        lo, hi = r["performance_lo"] / optimum, r["performance_hi"] / optimum
        lines.append(
            f"- `{r['condition']}`: " + fmt_ci(r["performance"] / optimum, lo, hi, 3) + " of it."
        )
    return lines


def _test_body(s: Settings, rows: Sequence[Row], trials: Mapping[str, int], done: int) -> str:
    planned = sum(trials.values())
    table = markdown_table(
        [
            "condition",
            "N (planned)",
            "fast - slow (95 % CI)",
            "Wilcoxon p",
            "predicted",
            "3:0 time %",
            "Q gap fast - slow",
            "perf / random",
        ],
        [
            [
                r["condition"],
                f"{r['trials']} ({trials[r['condition']]})",
                _effect(r),
                f"{r['wilcoxon_p']:.2g}" if math.isfinite(r["wilcoxon_p"]) else "-",
                _effect(r, "predicted_"),
                fmt_ci(r["time_3_0_pct"], r["time_3_0_lo"], r["time_3_0_hi"], 1),
                fmt_ci(r["q_gap_fast_minus_slow"], r["q_gap_lo"], r["q_gap_hi"], 4),
                fmt_ci(r["ratio_to_random"], r["ratio_lo"], r["ratio_hi"], 3),
            ]
            for r in rows
        ],
    )
    status = (
        f"All {planned} planned trials are in."
        if done >= planned
        else f"**Interim: {done} of {planned} planned trials saved so far.** Each cell states its "
        "N; the same command resumes the sweep."
    )
    return "\n".join(
        [
            "## Result",
            "",
            status,
            "",
            *[
                f"- `{r['condition']}`: fast - slow = "
                + _effect(r)
                + f" over {r['trials']} trials (**{r['direction']}**); the twin predicted "
                + _effect(r, "predicted_")
                + "."
                for r in rows
                if r["condition"] != "random"
            ],
            "",
            "## What the allocation is worth",
            "",
            *value_lines(s.arena, rows),
            "",
            "## Method",
            "",
            f"`{s.arena}`, physics trials of {s.convergence_h:g} h + {s.measured_h:g} h, trial k "
            f"with seed {s.seed} + k, as planned by the committed prediction. Fast - slow: mean "
            "and Student-t 95 % interval over trials, and a two-sided Wilcoxon signed-rank test "
            "against 0. 3:0: % of the measured period with the three fast robots on the "
            "high-value circuit and no slow one. Q gap: per robot the mean over states of "
            "Q(high) - Q(other) in its final table, fast minus slow. Perf / random: ratio of "
            "mean performance to random allocation's (delta-method interval).",
            "",
            "## Cells",
            "",
            table,
            "",
        ]
    )


def run_test(s: Settings) -> Outcome:
    out = s.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    trials, predicted_settings, predicted = load_plan(s.prediction)
    if predicted_settings.get("arena_sha") != arena_runs.digest(s.arena):
        raise ValueError(
            f"prediction = {str(s.prediction)!r} is invalid for arena {s.arena!r}: it was made for "
            f"{predicted_settings.get('arena')!r} with another configuration; allowed: a "
            "prediction of this arena as it is now"
        )
    jobs = test_jobs(s, trials)
    results, provenance = s.run_jobs(
        jobs, arena_runs.TRIALS, "trials", wall_of=lambda result: float(result["wall_s"])
    )
    records: dict[str, list[dict[str, Any]]] = {}
    for job in jobs:
        if arena_runs.trial_key(job) in results:
            records.setdefault(job.condition, []).append(results[arena_runs.trial_key(job)])
    by_condition = {r["condition"]: r for r in predicted}
    rows = [
        test_row(c, records[c], records.get("random", []), by_condition[c])
        for c in CONDITIONS
        if len(records.get(c, [])) >= 2
    ]
    body = _test_body(s, rows, trials, len(results))
    report = Report(
        "passing",
        f"Emergent differentiation where robots can pass (`{s.arena}`)",
        body,
        rows,
        summary={"plan": trials, "trials_saved": len(results)},
    )
    written = report.write(out, provenance)
    return Outcome(out, written, body.split("## Method")[0])


def run(settings: Settings) -> Outcome:
    s = settings.sized()
    return run_predict(s) if s.stage == "predict" else run_test(s)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
