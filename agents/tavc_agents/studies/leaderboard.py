"""The leaderboard: every allocator of the package on every scenario of the suite
(`tavc_env.scenarios`), on the scenarios' evaluation seeds, scored as the field reports benchmarks.

Each episode's delivered value per hour (`tavc_env.scenarios.METRIC`) is normalised between the
scenario's committed references (`benchmarks/results/scenarios/references.json`, the `scenarios`
study): `(value - random) / (optimum - random)`, random measured in physics and the optimum the
model's. Per scenario and allocator: the interquartile mean (IQM) of the normalised scores over
seeds with a percentile bootstrap 95 % interval; over the suite, the IQM of all scores with a
stratified bootstrap (seeds resampled within each scenario), as rliable computes them (here with
`scipy.stats.trim_mean` and `scipy.stats.bootstrap`). The learning allocators (TAVC) learn online,
within each episode, from nothing: their score includes their learning. Deep learners trained
offline are evaluated on the same seeds by their own scripts and added to the same table.

The script is `benchmarks/leaderboard.py`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from scipy import stats

from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, markdown_table
from tavc_agents.experiments.files import read_report
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import RESULTS_DIR, Outcome, StudySettings
from tavc_agents.experiments.sweep import TrialSpec
from tavc_agents.model import load_model
from tavc_agents.studies.allocators import allocators
from tavc_agents.studies.common import at_least, refuse_invalid
from tavc_agents.studies.scenarios import EvaluationSettings, value_per_hour
from tavc_env.scenarios import SCENARIOS

FIGURE = "leaderboard.png"
Row = dict[str, Any]


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


@dataclass(frozen=True, kw_only=True)
class Settings(EvaluationSettings, ScoredSettings):
    """The leaderboard's settings (its command line)."""

    reference: ClassVar = "leaderboard"
    min_seeds: ClassVar = 2  # an interval needs two
    quick_sizes: ClassVar = {"seeds": 2, "episode_h": 0.5, "resamples": 200}
    recorded_fields: ClassVar = "scenarios seeds_text episode_text resamples seed"

    quick: bool = False
    """smoke run: 2 seeds, 0.5-h episodes, 200 resamples"""


def specs(s: Settings) -> list[TrialSpec]:
    """Every episode: scenario by scenario, allocator by allocator, seed by seed. The model-based
    allocators get the scenario's model at its start values."""
    out = []
    for name in s.scenarios:
        scenario = SCENARIOS[name]
        values = [c.value for c in scenario.config().circuits]
        model = load_model(scenario.model).with_values(values)
        for allocator in allocators(model):
            for seed in s.seeds_of(scenario):
                out.append(
                    TrialSpec(
                        key=f"{name}__{allocator.name}__{seed}",
                        allocator=allocator.allocator,
                        allocator_kwargs=allocator.kwargs,
                        seed=seed,
                        env_kwargs={"scenario": name},
                        convergence_s=0.0,
                        measured_s=s.episode_s(scenario),
                        snapshot_every_s=s.episode_s(scenario),
                        tags={"scenario": name, "allocator": allocator.name, "seed": seed},
                    )
                )
    return out


def iqm(scores: Sequence[float]) -> float:
    """The interquartile mean: the mean of the middle half (scipy's 25 % trimmed mean)."""
    return float(stats.trim_mean(np.asarray(scores, dtype=float), 0.25))


def iqm_ci(
    groups: Sequence[Sequence[float]], resamples: int, rng: np.random.Generator
) -> tuple[float, float, float]:
    """The IQM of all scores of `groups` pooled, with a 95 % percentile bootstrap interval that
    resamples each group (scenario) on its own: stratified, as rliable's."""
    samples = [np.asarray(g, dtype=float) for g in groups]

    def pooled(*resampled: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.asarray(stats.trim_mean(np.concatenate(resampled, axis=axis), 0.25, axis=axis))

    point = float(stats.trim_mean(np.concatenate(samples), 0.25))
    if all(np.ptp(g) == 0 for g in samples):
        return point, point, point
    result = stats.bootstrap(
        samples,
        pooled,
        n_resamples=resamples,
        method="percentile",
        paired=False,
        vectorized=True,
        random_state=rng,
    )
    return point, float(result.confidence_interval.low), float(result.confidence_interval.high)


def references(path: Path) -> dict[str, dict[str, float]]:
    """The random and optimum value per hour of every scenario, from the committed references."""
    summary = read_report(path)["summary"]
    return {
        name: {"random": float(v["random_per_h"]), "optimum": float(v["optimum_per_h"])}
        for name, v in summary.items()
    }


def rows_of(
    specs_run: Sequence[TrialSpec],
    results: Mapping[str, TrialResult],
    refs: Mapping[str, Mapping[str, float]],
) -> list[Row]:
    rows = []
    for spec in specs_run:
        name, allocator = str(spec.tags["scenario"]), str(spec.tags["allocator"])
        value = value_per_hour(results[spec.key])
        ref = refs[name]
        rows.append(
            {
                "scenario": name,
                "allocator": allocator,
                "seed": spec.seed,
                "value_per_h": value,
                "score": (value - ref["random"]) / (ref["optimum"] - ref["random"]),
                "wall_s": results[spec.key].wall_s,
            }
        )
    return rows


def report(s: Settings, rows: list[Row]) -> Report:
    rng = np.random.default_rng(s.seed)
    names = list(dict.fromkeys(r["allocator"] for r in rows))
    cells: dict[tuple[str, str], tuple[float, float, float]] = {}
    summary: dict[str, Any] = {}
    for allocator in names:
        per_scenario = []
        for name in s.scenarios:
            scores = [
                r["score"] for r in rows if r["allocator"] == allocator and r["scenario"] == name
            ]
            per_scenario.append(scores)
            cells[(allocator, name)] = iqm_ci([scores], s.resamples, rng)
        cells[(allocator, "suite")] = iqm_ci(per_scenario, s.resamples, rng)
        summary[allocator] = {
            key: {"iqm": v[0], "ci": [v[1], v[2]]}
            for key, v in ((k, cells[(allocator, k)]) for k in (*s.scenarios, "suite"))
        }
    order = sorted(names, key=lambda a: -cells[(a, "suite")][0])

    def cell(v: tuple[float, float, float]) -> str:
        return f"{v[0]:.2f} [{v[1]:.2f}, {v[2]:.2f}]"

    header = ["allocator", *(SCENARIOS[n].id for n in s.scenarios), "suite (IQM, stratified)"]
    table = [[a, *(cell(cells[(a, n)]) for n in (*s.scenarios, "suite"))] for a in order]
    seeds = sorted({len(s.seeds_of(SCENARIOS[n])) for n in s.scenarios})
    wall = sum(r["wall_s"] for r in rows)
    body = (
        "Normalised score (0 = random allocation, 1 = the model optimum; the scenarios' committed "
        "references) of every allocator: interquartile mean over "
        f"{'/'.join(str(k) for k in seeds)} evaluation seeds per scenario [95 % percentile "
        f"bootstrap, {s.resamples} resamples; the suite's column resamples seeds within each "
        "scenario]. Allocators are sorted by the suite's IQM. The TAVC learners learn online "
        f"within each episode. {len(rows)} episodes, {wall / 60:.1f} min of episode wall time "
        "in all (one process).\n\n" + markdown_table(header, table)
    )
    rep = Report(
        "leaderboard", "Leaderboard: every allocator on every scenario", body, rows, summary
    )
    rep.figures.append((FIGURE, lambda path: draw(path, order, s.scenarios, cells)))
    return rep


def draw(
    path: Path,
    order: Sequence[str],
    scenarios: Sequence[str],
    cells: Mapping[tuple[str, str], tuple[float, float, float]],
) -> None:
    """One panel per scenario and one for the suite: each allocator's IQM with its interval."""
    keys = [*scenarios, "suite"]
    fig, axes = subplots(
        1, len(keys), figsize=(2.2 * len(keys), 0.35 * len(order) + 1.5), sharey=True
    )
    y = np.arange(len(order))
    for ax, key in zip(np.atleast_1d(axes), keys):
        values = np.array([cells[(a, key)] for a in order])
        ax.errorbar(
            values[:, 0],
            y,
            xerr=[values[:, 0] - values[:, 1], values[:, 2] - values[:, 0]],
            fmt="o",
            ms=4,
        )
        ax.axvline(0.0, color="grey", lw=0.5)
        ax.axvline(1.0, color="grey", lw=0.5, ls="--")
        ax.set_title(key if key == "suite" else SCENARIOS[key].id.removeprefix("tavc/"), fontsize=8)
        ax.set_xlabel("IQM score", fontsize=8)
        ax.set_ylabel("allocator", fontsize=8)
    first = np.atleast_1d(axes)[0]
    first.set_yticks(y)
    first.set_yticklabels(order, fontsize=8)
    first.invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


def run(settings: Settings) -> Outcome:
    """Run (or resume) every episode, then write the table, the per-episode rows and the figure."""
    s = settings.sized()
    out = s.out_dir()
    refs = references(s.references)
    jobs = specs(s)
    results, provenance = s.run_trials(jobs)
    rep = report(s, rows_of(jobs, results, refs))
    written = rep.write(out, provenance)
    return Outcome(out, written, rep.body)
