"""The scenario suite's references (`tavc_env.scenarios`): `--stage predict` computes, from the
measured TAVC models alone, every scenario's random, stay and optimum value per hour on its
evaluation seeds and the predicted headroom (1 - stay / optimum); `--stage measure` runs the physics
episodes of random, stay and the static model optimum on those seeds and writes the reference
table the leaderboard normalises with.

Writes `prediction.{md,csv,json}` (predict) or `references.{md,csv,json}` and every episode under
trials/ (measure) into a new run folder under runs/ (git ignores it), `--out`, or with
`--update-reference` benchmarks/results/scenarios_prediction/ or benchmarks/results/scenarios/;
`--resume RUN_DIR` continues an interrupted run.

    python benchmarks/scenarios.py --stage predict     # seconds, no physics
    python benchmarks/scenarios.py --stage measure     # minutes: 3 x 20 episodes per scenario
    python benchmarks/scenarios.py --quick --stage measure   # smoke run

The scenario suite's references (`tavc_env.scenarios`), in two stages whose order the git history
shows:

1. `--stage predict` (no physics): for every scenario and evaluation seed, the episode's phases
   (priority shifts, breakdowns and repairs) and, from the measured TAVC model of its arena
   (`tavc_agents.model`), the value per hour of the optimum (per phase the best allocation of the
   working robots under the phase's values, weighted by time), of `stay` (the start allocation
   held; a repaired robot returns to it) and of random allocation (every working robot on a
   uniformly drawn circuit: the expectation over the multinomial of splits). The predicted headroom
   is 1 - stay / optimum; the suite asks for >= 15 % in every scenario but the paper's.
2. `--stage measure`: physics episodes on the evaluation seeds of `random`, `stay` and the model's
   optimum at the start held as a static allocation; the reference table: random, stay and the
   model optimum (per seed), the normalised score of stay and of the static optimum, and the
   measured headroom with its 95 % interval. A scenario below 15 % headroom is flagged.

The metric is `tavc_env.scenarios.METRIC`: delivered value per simulated hour over the whole
episode. The script is `benchmarks/scenarios.py`.
"""

from __future__ import annotations

import itertools
import json
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

import tavc_env.scenarios
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.evaluation import (
    episode_key,
    episode_spec,
    value_per_hour,
)
from tavc_agents.experiments.files import write_text
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import (
    EvaluationSettings,
    Outcome,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import TrialSpec
from tavc_agents.model import CompletionModel, SpeedClasses, load_model
from tavc_env.scenarios import REFERENCES_FILE, SCENARIOS, Scenario, ScenarioEnv

MIN_HEADROOM = 0.15
"""The suite's rule: optimum - stay >= 15 % of the optimum in every scenario but the paper's."""
MEASURED = ("random", "stay", "static")
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(EvaluationSettings):
    """The references' settings (their command line)."""

    quick_sizes: ClassVar = {"seeds": 2, "episode_h": 0.5}
    recorded_fields: ClassVar = "stage scenarios seeds_text episode_text"

    stage: Literal["predict", "measure"] = "predict"
    """predict (the model's references, no physics) or measure (physics episodes)"""
    quick: bool = False
    """smoke run: 2 seeds, 0.5-h episodes"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self, [("stage", self.stage in ("predict", "measure"), "predict or measure")]
        )

    def reference_name(self) -> str:
        return "scenarios_prediction" if self.stage == "predict" else "scenarios"


# -- an episode's phases and the model's values ------------------------------------------------------
@dataclass(frozen=True)
class Phase:
    """A stretch of an episode with one set of values and one set of working robots."""

    start_s: float
    end_s: float
    values: tuple[float, ...]
    working: tuple[int, ...]


def episode(scenario: Scenario, seed: int, episode_s: float) -> tuple[list[int], list[Phase]]:
    """The start circuits and the phases of the episode that `run_trial(seed=seed, scenario=...)`
    plays: its env reset as the trial resets it (the priority shifts are drawn there), and the
    arena's breakdowns and repairs."""
    env = ScenarioEnv(scenario, max_sim_time_s=episode_s)
    _, infos = env.reset(seed=seed)  # the episode of evaluation seed `seed` (runner.reset_seed)
    start = [int(infos[a]["circuit"]) for a in env.possible_agents]
    shifts = [(0.0, env.circuit_values), *env.value_plan]
    broken: list[tuple[float, float, int]] = [
        (b.at_s, math.inf if b.repair_after_s is None else b.at_s + b.repair_after_s, b.robot)
        for b in env.config.breakdowns
    ]
    cuts = {0.0, episode_s, *(t for t, _ in shifts)}
    cuts |= {t for a, r, _ in broken for t in (a, r) if t < episode_s}
    bounds = sorted(t for t in cuts if t <= episode_s)
    phases = []
    for a, b in itertools.pairwise(bounds):
        values = next(v for t, v in reversed(shifts) if t <= a)
        down = {robot for at, back, robot in broken if at <= a < back}
        working = tuple(i for i in range(len(start)) if i not in down)
        phases.append(Phase(a, b, tuple(values), working))
    return start, phases


def random_value_rate(model: CompletionModel, team: Sequence[int]) -> float:
    """The expected value rate when every robot of `team` serves a uniformly drawn circuit: by
    linearity, per circuit the expectation over its group, whose count of each class is
    binomial(n_k, 1 / m) (exact, without enumerating the team's splits)."""
    m = model.n_circuits
    total = 0.0
    for group in itertools.product(*(range(n + 1) for n in team)):
        if sum(group) == 0:
            continue
        chance = math.prod(
            math.comb(n, g) * (1 / m) ** g * (1 - 1 / m) ** (n - g) for n, g in zip(team, group)
        )
        total += chance * sum(w * model.rate(i, group) for i, w in enumerate(model.values))
    return total


def phase_values(
    model: CompletionModel, classes: SpeedClasses, start: Sequence[int], phase: Phase
) -> dict[str, float]:
    """The model's value per hour of the optimum, stay and random allocation in `phase`."""
    at = model.with_values(phase.values)
    m = model.n_circuits
    team = tuple(
        sum(1 for i in phase.working if classes.of_robot[i] == k)
        for k in range(len(classes.labels))
    )
    groups = [[0] * len(team) for _ in range(m)]
    for i in phase.working:
        groups[start[i]][classes.of_robot[i]] += 1
    stay = tuple(tuple(g) for g in groups)
    return {
        "optimum": at.value_rate(at.optimum(team)) * 3600.0,
        "stay": at.value_rate(stay) * 3600.0,
        "random": random_value_rate(at, team) * 3600.0,
    }


def predicted(scenario: Scenario, seed: int, episode_s: float) -> Row:
    """The model's references of one evaluation episode (time-weighted over its phases)."""
    model = load_model(scenario.model)
    config = scenario.config()
    classes = SpeedClasses.of(config)
    model.check_team(classes)
    start, phases = episode(scenario, seed, episode_s)
    totals = dict.fromkeys(("optimum", "stay", "random"), 0.0)
    for phase in phases:
        for name, value in phase_values(model, classes, start, phase).items():
            totals[name] += value * (phase.end_s - phase.start_s) / episode_s
    return {
        "scenario": scenario.name,
        "seed": seed,
        "phases": len(phases),
        **{f"{k}_per_h": v for k, v in totals.items()},
        "headroom": 1.0 - totals["stay"] / totals["optimum"],
    }


# -- physics -----------------------------------------------------------------------------------------
def measure_specs(s: Settings) -> list[TrialSpec]:
    """Every physics episode of the measure stage: the suite's evaluation episodes
    (`tavc_agents.evaluation.episode_spec`) of random allocation, `stay` and the static optimum."""
    episode_h = None if s.episode_h is None else float(s.episode_h)
    return [
        episode_spec(name, seed, allocator, {}, episode_h)
        for name in s.scenarios
        for allocator in MEASURED
        for seed in s.seeds_of(SCENARIOS[name])
    ]


def write_package_references(summary: Mapping[str, Mapping[str, Any]]) -> Path:
    """Write the measured references into the package data the scenario envs and
    `tavc_agents.evaluation` score with (`tavc_env.scenarios.REFERENCES_FILE`)."""
    path = Path(tavc_env.scenarios.__file__).parent / REFERENCES_FILE
    references = {
        v["id"]: {k: v[k] for k in ("random_per_h", "stay_per_h", "optimum_per_h", "seeds")}
        for v in summary.values()
    }
    text = json.dumps({"note": PACKAGE_NOTE, "references": references}, indent=1, sort_keys=True)
    write_text(path, text + "\n")
    return path


PACKAGE_NOTE = (
    "written by python benchmarks/scenarios.py --stage measure --update-reference (its "
    "references.json summary): value per simulated hour of random allocation, stay and the model "
    "optimum on each scenario's evaluation seeds"
)


# -- reports -----------------------------------------------------------------------------------------
def _ci(values: Sequence[float], digits: int = 0) -> str:
    mean, low, high, _ = mean_ci(values)
    return fmt_ci(mean, low, high, digits)


def prediction_report(s: Settings, rows: list[Row]) -> Report:
    table = []
    summary: dict[str, Any] = {}
    for name in s.scenarios:
        mine = [r for r in rows if r["scenario"] == name]
        headroom = [r["headroom"] for r in mine]
        mean, low, high, _ = mean_ci(headroom)
        exempt = SCENARIOS[name].headroom_exempt
        ok = exempt or mean >= MIN_HEADROOM
        summary[name] = {"headroom": mean, "headroom_ci": [low, high], "meets_rule": ok}
        table.append(
            [
                SCENARIOS[name].id,
                len(mine),
                _ci([r["random_per_h"] for r in mine]),
                _ci([r["stay_per_h"] for r in mine]),
                _ci([r["optimum_per_h"] for r in mine]),
                fmt_ci(100 * mean, 100 * low, 100 * high, 1),
                "exempt (the paper's)" if exempt else ("yes" if ok else "**no**"),
            ]
        )
    header = [
        "scenario",
        "seeds",
        "random (value/h)",
        "stay (value/h)",
        "optimum (value/h)",
        "headroom % [95 % CI]",
        ">= 15 %",
    ]
    body = (
        "The measured TAVC model's prediction of every scenario's references, before any "
        "physics episode of the scenario ran: value per simulated hour, mean over the "
        "evaluation seeds [Student-t 95 % interval]. Headroom = 1 - stay / optimum, per seed.\n\n"
        + markdown_table(header, table)
    )
    return Report("prediction", "Scenario suite: the model's references", body, rows, summary)


def measure_report(
    s: Settings, results: Mapping[str, TrialResult], predictions: list[Row]
) -> Report:
    rows: list[Row] = []
    table = []
    summary: dict[str, Any] = {}
    for name in s.scenarios:
        scenario = SCENARIOS[name]
        per_seed: list[Row] = []
        for seed in s.seeds_of(scenario):
            got = {a: value_per_hour(results[episode_key(name, a, seed)]) for a in MEASURED}
            model = next(r for r in predictions if r["scenario"] == name and r["seed"] == seed)
            optimum = float(model["optimum_per_h"])
            span = optimum - got["random"]
            row = {
                "scenario": name,
                "seed": seed,
                **{f"{a}_per_h": v for a, v in got.items()},
                "optimum_per_h": optimum,
                "stay_score": (got["stay"] - got["random"]) / span,
                "static_score": (got["static"] - got["random"]) / span,
                "headroom": 1.0 - got["stay"] / optimum,
            }
            rows.append(row)
            per_seed.append(row)
        headroom = mean_ci([r["headroom"] for r in per_seed])
        ok = scenario.headroom_exempt or headroom[0] >= MIN_HEADROOM
        summary[name] = {
            "id": scenario.id,
            "random_per_h": float(np.mean([r["random_per_h"] for r in per_seed])),
            "stay_per_h": float(np.mean([r["stay_per_h"] for r in per_seed])),
            "optimum_per_h": float(np.mean([r["optimum_per_h"] for r in per_seed])),
            "headroom": headroom[0],
            "headroom_ci": [headroom[1], headroom[2]],
            "meets_rule": ok,
            "seeds": len(per_seed),
        }
        table.append(
            [
                scenario.id,
                len(per_seed),
                _ci([r["random_per_h"] for r in per_seed]),
                _ci([r["stay_per_h"] for r in per_seed]),
                _ci([r["static_per_h"] for r in per_seed]),
                _ci([r["optimum_per_h"] for r in per_seed]),
                _ci([r["stay_score"] for r in per_seed], 2),
                fmt_ci(100 * headroom[0], 100 * headroom[1], 100 * headroom[2], 1),
                "exempt (the paper's)" if scenario.headroom_exempt else ("yes" if ok else "**no**"),
            ]
        )
    header = [
        "scenario",
        "seeds",
        "random",
        "stay",
        "static optimum",
        "optimum (model)",
        "stay, normalised",
        "headroom %",
        ">= 15 %",
    ]
    body = (
        "Each scenario's references on its evaluation seeds: delivered value per simulated hour "
        "over the episode, physics episodes of `random`, `stay` and the model optimum at the "
        "start held as a static allocation, beside the model optimum (per phase, weighted by "
        "time); mean [Student-t 95 % interval] over seeds. Normalised score = (value - random) / "
        "(optimum - random); headroom = 1 - stay / optimum, per seed.\n\n"
        + markdown_table(header, table)
    )
    return Report("references", "Scenario suite: references", body, rows, summary)


def run(settings: Settings) -> Outcome:
    """Predict from the model, or measure in physics, and write the report."""
    s = settings.sized()
    out = s.out_dir()
    predictions = [
        predicted(SCENARIOS[name], seed, s.episode_s(SCENARIOS[name]))
        for name in s.scenarios
        for seed in s.seeds_of(SCENARIOS[name])
    ]
    if s.stage == "predict":
        report = prediction_report(s, predictions)
        written = report.write(out, run_metadata(settings=s.recorded()))
        return Outcome(out, written, report.body)
    results, provenance = s.run_trials(measure_specs(s))
    report = measure_report(s, results, predictions)
    written = report.write(out, provenance)
    full = not s.is_quick and s.seeds is None and s.episode_h is None
    if s.update_reference and full and tuple(s.scenarios) == tuple(SCENARIOS):
        written.append(write_package_references(report.summary))
    return Outcome(out, written, report.body)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
