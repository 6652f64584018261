"""The TAVC model measured: completion frequencies, slot values, the predicted optimum, and a check.

Every group of robots serves every circuit alone (fixed allocations) to measure its
task-completion frequency c; Equation 1 gives the slot values and exhaustive search the
model-optimal allocation, which then runs, with its neighbours and the next-best allocations, as a
static allocation in the full arena to check the prediction. Writes model.json (read by the
model-based allocators, allocators.py and vacancy_chain.py), slot_values.{md,csv,json},
group_runs.csv and check.{md,csv,json} into a new runs/ folder (or --out); with
--update-reference, the reports into benchmarks/results/tavc_model/<preset>/ and the model into
the package data the allocators read, agents/tavc_agents/data/models/<preset>.json; runs are kept in
cache/ so `--resume RUN_DIR` continues an interrupted run.

    python benchmarks/tavc_model.py                                        # dahl2004
    python benchmarks/tavc_model.py --preset three_circuits_three_classes --seeds 2

The TAVC model measured: completion frequencies, slot values, the predicted optimum, and a check.

For a preset, every group J of robots (a count per speed class) serves every circuit i alone, as a
fixed allocation, and its task-completion frequency c_{i,J} is measured (`--seeds` runs of
`--measured-h` hours after a `--warmup-min` warm-up). From those, Equation 1 gives the slot values
s_{i,J,j} = w_i (c_{i,J+j} - c_{i,J}) and exhaustive search the model-optimal allocation.

The check: the predicted optimum, its neighbours (one robot moved) and the next-best allocations
run as static allocations in the full arena (`--check-seeds` runs each); the measured delivered
value per robot per 10 s is set beside the model's prediction.

Outputs in `benchmarks/results/tavc_model/<preset>/` (the committed reference; a run writes into a
new `runs/` folder unless `--update-reference` or `--out`): `slot_values.{md,csv,json}`,
`group_runs.csv` (every run's rate), `check.{md,csv,json}`, and `model.json` (the model, read by the
model-based allocators, `tavc trial` and the allocators and vacancy_chain studies). The reference
model ships with the package as `tavc_agents/data/models/<preset>.json`, and
`--update-reference` writes it there. Finished runs are kept in `cache/` (not committed), so an
interrupted run resumes.

    python benchmarks/tavc_model.py                                        # dahl2004
    python benchmarks/tavc_model.py --preset three_circuits_three_classes --seeds 2
"""

from __future__ import annotations

import itertools
import json
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from scipy import stats

from arena_runs import circuit_of, group_of, group_specs, measured_rate
from tavc_agents.analysis.allocation import delivered_performance
from tavc_agents.analysis.reports import Report, markdown_table, write_csv
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.files import write_text
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import TagValue, TrialSpec
from tavc_agents.model import (
    Allocation,
    CompletionModel,
    SpeedClasses,
    model_from_runs,
    model_path,
    robot_circuits,
)
from tavc_env import PRESETS, ArenaConfig, make_config
from tavc_env.validation import is_number


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The model measurement's settings (its command line)."""

    recorded_as_text: ClassVar = True
    recorded_fields: ClassVar = "preset seeds warmup_min measured_h check_seeds top backend"

    preset: str = "dahl2004"
    """arena preset"""
    seeds: int = 3
    """runs per group and circuit"""
    warmup_min: float = 10.0
    """warm-up before each measured period, simulated minutes"""
    measured_h: float = 2.0
    """measured period of every run, simulated hours"""
    check_seeds: int = 3
    """runs per checked allocation"""
    top: int = 6
    """next-best allocations to check"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            ("preset", self.preset in PRESETS, f"one of {sorted(PRESETS)}"),
            ("seeds", at_least(self.seeds, 1), "an integer >= 1"),
            ("warmup_min", is_number(self.warmup_min) and self.warmup_min >= 0, ">= 0"),
            ("measured_h", positive(self.measured_h), "> 0"),
            ("check_seeds", at_least(self.check_seeds, 1), "an integer >= 1"),
            ("top", at_least(self.top, 1), "an integer >= 1"),
        ]
        refuse_invalid(self, checks)

    def reference_name(self) -> str:
        # the reports only: the model itself ships with the package (`model.REFERENCE_MODELS`)
        return f"tavc_model/{self.preset}"


def check_allocations(model: CompletionModel, top: int) -> list[Allocation]:
    """The optimum, its neighbours and the `top` best allocations, without repeats, best first."""
    ranked = [a for _, a in model.ranked_if_few() or [(0.0, model.optimum())]]
    chosen = [ranked[0], *model.neighbours(ranked[0]), *ranked[1:top]]
    unique = list(dict.fromkeys(chosen))
    return sorted(unique, key=lambda a: -model.value_rate(a))


def allocation_key(allocation: Allocation) -> str:
    """An allocation as text for keys and tags, e.g. `3-0_0-3` (groups per circuit)."""
    return "_".join("-".join(map(str, g)) for g in allocation)


def check_key(tags: Mapping[str, TagValue]) -> str:
    return f"{tags['allocation']}_s{tags['seed']}"


def check_specs(settings: Settings, allocations: Sequence[Allocation]) -> list[TrialSpec]:
    """Each allocation as a static allocation in the full arena, `check_seeds` runs each; tagged
    with the allocation (`allocation_key`) and the seed."""
    classes = SpeedClasses.of(make_config(settings.preset))
    warmup, measured = settings.warmup_min * 60.0, settings.measured_h * 3600.0
    out = []
    for a in allocations:
        for seed in range(settings.check_seeds):
            tags: dict[str, TagValue] = {"allocation": allocation_key(a), "seed": seed}
            out.append(
                TrialSpec(
                    key=check_key(tags),
                    allocator="static",
                    allocator_kwargs={"circuits": robot_circuits(a, classes)},
                    seed=seed,
                    env_kwargs={"preset": settings.preset},
                    convergence_s=warmup,
                    measured_s=measured,
                    snapshot_every_s=warmup + measured,
                    tags=tags,
                )
            )
    return out


def run(settings: Settings) -> Outcome:
    """Measure the model, write it and its report, then check its prediction in the full arena."""
    out = settings.out_dir()
    config = make_config(settings.preset)
    warmup, measured = settings.warmup_min * 60.0, settings.measured_h * 3600.0
    specs = group_specs(config, range(settings.seeds), warmup, measured)
    print(f"measuring c for {len(specs)} group runs ({settings.preset})", flush=True)
    results, meta = settings.run_trials(specs, Path("cache", "groups"))
    model = model_from_runs(config, group_runs(specs, results))
    written = [write_csv_path(out / "group_runs.csv", group_rows(specs, results, config))]
    # The reference model is package data (the allocators' default, also in an installed wheel),
    # its one copy; a run folder gets its own model.json
    model_file = model_path(settings.preset) if settings.update_reference else out / "model.json"
    written.append(write_text(model_file, json.dumps(model.to_dict(), indent=1) + "\n"))
    written += slot_report(model, settings.preset).write(out, meta)

    allocations = check_allocations(model, settings.top)
    specs_checked = check_specs(settings, allocations)
    print(f"checking {len(allocations)} allocations in the full arena", flush=True)
    checked, check_meta = settings.run_trials(specs_checked, Path("cache", "check"))
    check_meta = {**check_meta, "model_wall_time_s": meta.get("wall_time_s")}
    rows = check_rows(model, allocations, specs_checked, checked)
    report = check_report(rows, settings)
    written += report.write(out, check_meta)
    text = "\n".join([best_section(model), "", report.body])
    return Outcome(out, written, text)


def write_csv_path(path: Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    write_csv(path, rows)
    return path


# -- the model -----------------------------------------------------------------------------------
def group_runs(
    specs: Sequence[TrialSpec], results: Mapping[str, TrialResult]
) -> list[tuple[int, tuple[int, ...], float]]:
    """(circuit, group, tasks per second) of every group run, for `model_from_runs`."""
    return [(circuit_of(s), group_of(s), measured_rate(results[s.key])) for s in specs]


def group_rows(
    specs: Sequence[TrialSpec], results: Mapping[str, TrialResult], config: ArenaConfig
) -> list[dict[str, Any]]:
    """One row per group run: circuit, robots per class, seed, tasks per hour, escapes."""
    labels = SpeedClasses.of(config).labels
    rows = []
    for spec in specs:
        result = results[spec.key]
        rows.append(
            {
                "circuit": circuit_of(spec),
                **{f"n_{label}": n for label, n in zip(labels, group_of(spec))},
                "seed": spec.seed,
                "tasks_per_h": 3600 * measured_rate(result),
                "escapes": result.escapes,
            }
        )
    return rows


def describe(model: CompletionModel, allocation: Allocation) -> str:
    """An allocation as text, e.g. `c0: 3 fast | c1: 3 slow`."""
    return " | ".join(f"c{i}: {model.describe(g)}" for i, g in enumerate(allocation))


def rates_table(model: CompletionModel) -> str:
    """c of every group on every circuit, tasks per hour +- standard error."""
    groups = [g for g in itertools.product(*(range(n + 1) for n in model.team)) if sum(g)]
    se = model.rates_se if model.rates_se is not None else np.zeros_like(model.rates)
    rows = [
        [model.describe(g)]
        + [
            f"{3600 * model.rate(i, g):.1f} +- {3600 * se[i][g]:.1f}"
            for i in range(model.n_circuits)
        ]
        for g in groups
    ]
    return markdown_table(["group", *(f"circuit {i}" for i in range(model.n_circuits))], rows)


def slot_table(slot_rows: Sequence[Mapping[str, Any]]) -> str:
    return markdown_table(
        ["circuit", "group J", "joining j", "c_J per h", "slot value per h"],
        [
            [
                r["circuit"],
                r["group"],
                r["joining"],
                f"{r['c_group_per_h']:.1f}",
                f"{r['slot_value_per_h']:.0f}",
            ]
            for r in slot_rows
        ],
    )


def best_section(model: CompletionModel) -> str:
    """The ten best allocations of the model, and its optimum and worst allocation."""
    ranked = model.ranked_if_few()
    if ranked is None:  # too many to rank: the optimum alone, found circuit by circuit
        best = model.optimum()
        return "\n".join(
            [
                "## Best allocation (model)",
                "",
                f"Predicted optimum: **{describe(model, best)}**, "
                f"{3600 * model.value_rate(best):.0f} value per hour, "
                f"{model.performance(best):.4f} per robot per 10 s (found circuit by circuit; "
                f"the {model.n_allocations()} allocations are too many to rank).",
            ]
        )
    best_value, best = ranked[0]
    table = markdown_table(
        ["rank", "allocation (groups per circuit)", "value per h", "per robot per 10 s"],
        [
            [k + 1, describe(model, a), f"{3600 * v:.0f}", f"{model.performance(a):.4f}"]
            for k, (v, a) in enumerate(ranked[:10])
        ],
    )
    worst = ranked[-1][1]
    return "\n".join(
        [
            "## Best allocations (model)",
            "",
            table,
            "",
            f"Predicted optimum: **{describe(model, best)}**, {3600 * best_value:.0f} value per "
            f"hour, {model.performance(best):.4f} per robot per 10 s. Worst allocation: "
            f"{describe(model, worst)} ({model.performance(worst):.4f}).",
        ]
    )


def slot_report(model: CompletionModel, preset: str) -> Report:
    """`slot_values.{md,csv,json}`: c of every group, the slot values and the best allocations."""
    ranked = model.ranked_if_few()
    best = model.optimum()
    slot_rows = model.slot_table()
    body = [
        f"Team: {model.describe(model.team)}; circuit values {list(model.values)}.",
        "",
        "## Task-completion frequency c of each group (tasks per hour, mean over runs, +- s.e.)",
        "",
        rates_table(model),
        "",
        "## Slot values s = w_i (c_{i,J+j} - c_{i,J}) (Equation 1, value per hour)",
        "",
        slot_table(slot_rows),
        "",
        best_section(model),
    ]
    summary = {
        "optimum": best,
        "optimum_performance": model.performance(best),
        "ranked_top10": [(a, model.performance(a)) for _, a in (ranked or [])[:10]],
    }
    title = f"TAVC model of {preset}: completion frequencies and slot values"
    return Report("slot_values", title, "\n".join(body), slot_rows, summary)


# -- the check -----------------------------------------------------------------------------------
def check_rows(
    model: CompletionModel,
    allocations: Sequence[Allocation],
    specs: Sequence[TrialSpec],
    results: Mapping[str, TrialResult],
) -> list[dict[str, Any]]:
    """Per checked allocation: its model rank, predicted and measured performance (mean and 95 %
    interval over seeds) and every run's measurement."""
    runs: dict[str, list[float]] = {allocation_key(a): [] for a in allocations}
    for spec in specs:
        result = results[spec.key]
        runs[str(spec.tags["allocation"])].append(
            delivered_performance(result, *result.measured_window)
        )
    ranked = [a for _, a in model.ranked_if_few() or []]
    rows = []
    for a in allocations:
        perfs = runs[allocation_key(a)]
        m, lo, hi, _ = mean_ci(perfs)
        rows.append(
            {
                "allocation": describe(model, a),
                "key": allocation_key(a),
                "model_rank": ranked.index(a) + 1 if ranked else None,
                "predicted": model.performance(a),
                "measured": m,
                "measured_low": lo,
                "measured_high": hi,
                "measured_over_predicted": m / model.performance(a),
                "runs": perfs,
            }
        )
    return rows


def check_report(rows: list[dict[str, Any]], settings: Settings) -> Report:
    """`check.{md,csv,json}`: predicted against measured, the measured best and the rank
    correlation."""
    measured_best = max(rows, key=lambda row: row["measured"])
    rank_corr = float(
        stats.spearmanr([r["predicted"] for r in rows], [r["measured"] for r in rows])[0]
    )
    table = markdown_table(
        ["allocation", "model rank", "predicted", "measured [95 % CI]", "measured / predicted"],
        [
            [
                r["allocation"],
                r["model_rank"] or "-",
                f"{r['predicted']:.4f}",
                f"{r['measured']:.4f} [{r['measured_low']:.4f}, {r['measured_high']:.4f}]",
                f"{r['measured_over_predicted']:.3f}",
            ]
            for r in rows
        ],
    )
    body = [
        "Each allocation run as a static allocation in the full arena "
        f"({settings.check_seeds} seeds x {settings.measured_h:g} h after "
        f"{settings.warmup_min:g} min); delivered value per robot per 10 s with a 95 % interval "
        "over seeds.",
        "",
        table,
        "",
        f"Measured best: {measured_best['allocation']} (model rank {measured_best['model_rank'] or '-'}). "
        f"Spearman rank correlation of predicted and measured: {rank_corr:.2f}.",
    ]
    return Report(
        "check",
        f"TAVC model of {settings.preset}: prediction checked in the full arena",
        "\n".join(body),
        rows,
        {"measured_best": measured_best["allocation"], "rank_correlation": rank_corr},
        fields=[k for k in rows[0] if k != "runs"],
    )


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
