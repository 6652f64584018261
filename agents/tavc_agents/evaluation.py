"""The suite's evaluation protocol, shared by the leaderboards and by anyone scoring an agent on
the scenarios: which episodes (a scenario's evaluation seeds and episode length), the metric (value
delivered per simulated hour), the committed references that normalise it (0 = random allocation,
1 = the model optimum), the interquartile mean with its stratified bootstrap interval (as rliable's),
and the allocators the leaderboard compares.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from scipy import stats

from tavc_agents.experiments.files import read_report
from tavc_agents.experiments.registry import REGISTRY
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import (
    RESULTS_DIR,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
)
from tavc_agents.model import CompletionModel
from tavc_env.scenarios import SCENARIOS, Scenario


# -- the episodes and the metric --------------------------------------------------------------------
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


def value_per_hour(result: TrialResult) -> float:
    """The suite's metric of one episode: delivered value (w at delivery) per simulated hour."""
    return float(sum(result.delivery_value)) / (result.end_s / 3600.0)


# -- normalisation and aggregation ---------------------------------------------------------------
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


# -- the allocators the leaderboard compares ------------------------------------------------------
@dataclass(frozen=True)
class Allocator:
    name: str  # the row's name in trial keys, tables and trials.csv
    label: str
    kwargs: Mapping[str, Any]
    registry: str = ""  # the allocator's registry name, if not `name`

    @property
    def allocator(self) -> str:
        return self.registry or self.name


def allocators(
    model: CompletionModel,
    networks: Mapping[str, Path] | None = None,
    plugins: Sequence[str] = (),
) -> list[Allocator]:
    """The allocators compared, in report order (the model-based ones get `model`; `networks`:
    trained networks by learning run; `plugins`: more allocators by registry name)."""
    m = model.to_dict()
    extra = [Allocator(name, name, {"model": m} if takes_model(name) else {}) for name in plugins]
    trained = [
        Allocator(f"network_{run}", f"{run} (trained network)", {"weights": str(path)}, "network")
        for run, path in (networks or {}).items()
    ]
    return [
        Allocator("random", "random", {}),
        Allocator("stay", "stay (the start's circuits)", {}),
        Allocator("epsilon_tavc", "epsilon TAVC", {"epsilon": 0.1, "init": "scaled"}),
        Allocator("softmax_tavc", "softmax TAVC", {"temperature": 0.005, "init": "scaled"}),
        Allocator("response_threshold", "response threshold", {}),
        Allocator("auction", "auction", {"model": m}),
        Allocator("greedy", "greedy (model)", {"model": m}),
        Allocator("static", "static (model optimum)", {"model": m}),
        *trained,
        *extra,
    ]


def takes_model(name: str) -> bool:
    """Whether the factory of allocator `name` has a `model` parameter."""
    return "model" in inspect.signature(REGISTRY.get(name).factory).parameters
