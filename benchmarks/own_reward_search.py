"""The settings search of the own-reward learner (`tavc_agents.learners.own_reward`), on TRAINING
seeds only: a declared grid of its three settings, each combination run on every scenario of the
suite on training seeds 0, 1 and 2 (never an evaluation seed: those are 10000-10019), scored by
the mean normalised score (`tavc_env.scenarios.SCENARIOS[name].score`) over scenarios x seeds.
The best combination becomes the learner's defaults and its leaderboard row.

Every episode is the scenario's full episode from its start (`convergence_s=0`, `measured_s` the
scenario's `episode_s`), with the default observation (`values="paid"`), as the leaderboard runs
it. Writes `own_reward_search.{md,csv,json}` and every episode under trials/.

    python benchmarks/own_reward_search.py --update-reference --workers 2   # 12 x 7 x 3 episodes
    python benchmarks/own_reward_search.py --quick                            # smoke run
"""

from __future__ import annotations

import itertools
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from tavc_agents.analysis.reports import Report, markdown_table
from tavc_agents.evaluation import value_per_hour
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import Outcome, StudySettings, refuse_invalid, run_study
from tavc_agents.experiments.sweep import TrialSpec
from tavc_env.scenarios import SCENARIOS

GRID: Mapping[str, tuple[float, ...]] = {
    "epsilon": (0.01, 0.03, 0.1),
    "recency": (0.05, 0.2),
    "hysteresis": (0.0, 0.05),
}
"""The declared grid: 3 x 2 x 2 = 12 combinations."""


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The search's settings (its command line)."""

    reference: ClassVar = "own_reward_search"
    quick_sizes: ClassVar = {"train_seeds": (0,), "episode_h": 0.25}
    recorded_fields: ClassVar = "scenarios train_seeds episode_h grid"

    quick: bool = False
    """smoke run: one training seed, 15-min episodes"""
    scenarios: tuple[str, ...] = tuple(SCENARIOS)
    """the scenarios (names in tavc_env.scenarios.SCENARIOS)"""
    train_seeds: tuple[int, ...] = (0, 1, 2)
    """training seeds per scenario (an evaluation seed is refused)"""
    episode_h: float | None = None
    """episode length, simulated hours (default: the scenario's)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        evaluation = {s for n in self.scenarios if n in SCENARIOS for s in SCENARIOS[n].eval_seeds}
        refuse_invalid(
            self,
            [
                (
                    "scenarios",
                    len(self.scenarios) >= 1 and all(n in SCENARIOS for n in self.scenarios),
                    f"one or more of {', '.join(SCENARIOS)}",
                ),
                (
                    "train_seeds",
                    len(self.train_seeds) >= 1
                    and all(isinstance(s, int) and s >= 0 for s in self.train_seeds)
                    and not evaluation & set(self.train_seeds),
                    "seeds >= 0 that are not evaluation seeds (10000-10019)",
                ),
            ],
        )

    @property
    def grid(self) -> dict[str, list[float]]:
        return {k: list(v) for k, v in GRID.items()}


def combinations() -> list[dict[str, float]]:
    """Every combination of the grid, in its declared order."""
    return [dict(zip(GRID, values)) for values in itertools.product(*GRID.values())]


def label(combo: Mapping[str, float]) -> str:
    return "_".join(f"{k}={v:g}" for k, v in combo.items())


def specs(s: Settings) -> list[TrialSpec]:
    out = []
    for combo in combinations():
        for name in s.scenarios:
            episode_s = SCENARIOS[name].episode_s if s.episode_h is None else s.episode_h * 3600.0
            for seed in s.train_seeds:
                out.append(
                    TrialSpec(
                        key=f"{name}__{label(combo)}__{seed}",
                        allocator="own_reward",
                        allocator_kwargs=dict(combo),
                        seed=seed,
                        env_kwargs={"scenario": name},
                        convergence_s=0.0,
                        measured_s=episode_s,
                        snapshot_every_s=episode_s,
                        tags={"scenario": name, "combo": label(combo), "seed": seed},
                    )
                )
    return out


def report(s: Settings, jobs: Sequence[TrialSpec], results: Mapping[str, TrialResult]) -> Report:
    rows: list[dict[str, Any]] = []
    for spec in jobs:
        name = str(spec.tags["scenario"])
        value = value_per_hour(results[spec.key])
        rows.append(
            {
                "combo": spec.tags["combo"],
                **dict(spec.allocator_kwargs),
                "scenario": name,
                "seed": spec.seed,
                "value_per_h": value,
                "score": SCENARIOS[name].score(value),
            }
        )
    table = []
    combos: dict[str, Any] = {}
    for combo in combinations():
        mine = [r for r in rows if r["combo"] == label(combo)]
        per = {
            n: float(np.mean([r["score"] for r in mine if r["scenario"] == n])) for n in s.scenarios
        }
        mean = float(np.mean([r["score"] for r in mine]))
        combos[label(combo)] = {"settings": combo, "mean": mean, "per_scenario": per}
        table.append((mean, combo, per))
    table.sort(key=lambda t: -t[0])
    best = table[0][1]
    header = [*GRID, *(SCENARIOS[n].id for n in s.scenarios), "mean (the criterion)"]
    lines = [
        [*(f"{combo[k]:g}" for k in GRID), *(f"{per[n]:.3f}" for n in s.scenarios), f"**{m:.3f}**"]
        for m, combo, per in table
    ]
    body = (
        f"The own-reward learner's grid ({' x '.join(str(len(v)) for v in GRID.values())} = "
        f"{len(combinations())} combinations of {', '.join(GRID)}), each on {len(s.scenarios)} "
        f"scenarios x training seeds {list(s.train_seeds)} ({len(rows)} episodes, default "
        "observation, the scenario's full episode from its start). The criterion is the mean "
        "normalised score over scenarios x seeds (0 = random, 1 = the model optimum); no "
        "evaluation seed was run. Best first.\n\n"
        + markdown_table(header, lines)
        + "\n\nChosen: "
        + ", ".join(f"`{k}={v:g}`" for k, v in best.items())
        + f" (mean {table[0][0]:.3f}; the runner-up {table[1][0]:.3f})."
    )
    summary: dict[str, Any] = {"chosen": best, "combinations": combos}
    return Report(
        "own_reward_search",
        "Own-reward learner: settings search on training seeds",
        body,
        rows,
        summary,
    )


def run(settings: Settings) -> Outcome:
    """Run (or resume) every episode of the grid, then write the table of combinations."""
    s = settings.sized()
    out = s.out_dir()
    jobs = specs(s)
    results, provenance = s.run_trials(jobs)
    rep = report(s, jobs, results)
    written = rep.write(out, provenance)
    return Outcome(out, written, rep.body)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
