"""The TAVC model measured: completion frequencies, slot values, the predicted optimum, and a check.

For a preset, every group J of robots (a count per speed class) serves every circuit i alone, as a
fixed allocation, and its task-completion frequency c_{i,J} is measured (`--seeds` runs of
`--measured-h` hours after a `--warmup-min` warm-up). From those, Equation 1 gives the slot values
s_{i,J,j} = w_i (c_{i,J+j} - c_{i,J}) and exhaustive search the model-optimal allocation.

The check: the predicted optimum, its neighbours (one robot moved) and the next-best allocations
run as static allocations in the full arena (`--check-seeds` runs each); the measured delivered
value per robot per 10 s is set beside the model's prediction.

Outputs in `benchmarks/results/tavc_model/<preset>/`: `model.json` (the model, read by
`allocators.py` and `vacancy_chain.py`), `slot_values.{md,csv,json}`, `group_runs.csv` (every run's
rate), `check.{md,csv,json}`. Finished runs are kept in `cache/` (not committed), so an interrupted
run resumes.

    python benchmarks/tavc_model.py                                        # dahl2004
    python benchmarks/tavc_model.py --preset three_circuits_three_classes --seeds 2
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
from _common import (
    RESULTS_DIR,
    add_sweep_options,
    markdown_table,
    mean_ci,
    run_trials,
    write_csv,
    write_results,
)
from scipy import stats

from agents.experiments.estimation import group_of, group_specs, measured_rate
from agents.experiments.sweep import TrialSpec
from agents.model import (
    Allocation,
    CompletionModel,
    SpeedClasses,
    model_from_runs,
    robot_circuits,
)
from tavc_env import PRESETS, make_config, metrics


def model_dir(preset: str) -> Path:
    return RESULTS_DIR / "tavc_model" / preset


def load_model(preset: str, path: Path | None = None) -> CompletionModel:
    """The model at `path` (default: the committed model of `preset`), or an error naming the
    command that makes it."""
    path = path if path is not None else model_dir(preset) / "model.json"
    if not path.exists():
        raise SystemExit(
            f"{path} is missing; run `python benchmarks/tavc_model.py --preset {preset}` first"
        )
    return CompletionModel.load(path)


def check_allocations(model: CompletionModel, top: int) -> list[Allocation]:
    """The optimum, its neighbours and the `top` best allocations, without repeats, best first."""
    ranked = [a for _, a in model.ranked()]
    chosen = [ranked[0], *model.neighbours(ranked[0]), *ranked[1:top]]
    unique = list(dict.fromkeys(chosen))
    return sorted(unique, key=lambda a: -model.value_rate(a))


def allocation_key(allocation: Allocation) -> str:
    return "_".join("-".join(map(str, g)) for g in allocation)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--preset", default="dahl2004", choices=sorted(PRESETS))
    parser.add_argument("--seeds", type=int, default=3, help="runs per group and circuit")
    parser.add_argument("--warmup-min", type=float, default=10.0)
    parser.add_argument("--measured-h", type=float, default=2.0)
    parser.add_argument("--check-seeds", type=int, default=3, help="runs per checked allocation")
    parser.add_argument("--top", type=int, default=6, help="next-best allocations to check")
    add_sweep_options(parser)
    parser.add_argument(
        "--out", type=Path, default=None, help="default: results/tavc_model/<preset>"
    )
    args = parser.parse_args(argv)
    for name in ("seeds", "check_seeds", "top"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} = {getattr(args, name)}; allowed: >= 1")
    if args.warmup_min < 0 or args.measured_h <= 0:
        parser.error("allowed: --warmup-min >= 0 and --measured-h > 0")

    config = make_config(args.preset)
    classes = SpeedClasses.of(config)
    out = args.out if args.out is not None else model_dir(args.preset)
    warmup, measured = args.warmup_min * 60.0, args.measured_h * 3600.0
    settings = {k: str(v) for k, v in vars(args).items() if k not in ("workers", "out")}

    # 1. Completion frequencies of every group on every circuit.
    specs = group_specs(config, range(args.seeds), warmup, measured)
    print(f"measuring c for {len(specs)} group runs ({args.preset})")
    results, meta = run_trials(
        specs, out / "cache" / "groups", args.workers, settings, backend=args.backend
    )
    runs = []
    rows = []
    for spec in specs:
        circuit = int(spec.allocator_kwargs["circuit"])
        group_counts = group_of(spec)
        rate = measured_rate(results[spec.key])
        runs.append((circuit, group_counts, rate))
        rows.append(
            {
                "circuit": circuit,
                **{f"n_{label}": n for label, n in zip(classes.labels, group_counts)},
                "seed": spec.seed,
                "tasks_per_h": 3600 * rate,
                "escapes": results[spec.key].escapes,
            }
        )
    write_csv(out / "group_runs.csv", rows)
    model = model_from_runs(config, runs)
    (out / "model.json").write_text(json.dumps(model.to_dict(), indent=1) + "\n")

    ranked = model.ranked()
    best_value, best = ranked[0]
    slot_rows = model.slot_table()
    body = [
        f"Team: {model.describe(model.team)}; circuit values {list(model.values)}.",
        "",
        "## Task-completion frequency c of each group (tasks per hour, mean over runs, +- s.e.)",
        "",
        _rates_table(model),
        "",
        "## Slot values s = w_i (c_{i,J+j} - c_{i,J}) (Equation 1, value per hour)",
        "",
        markdown_table(
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
        ),
        "",
        "## Best allocations (model)",
        "",
        markdown_table(
            ["rank", "allocation (groups per circuit)", "value per h", "per robot per 10 s"],
            [
                [k + 1, _describe(model, a), f"{3600 * v:.0f}", f"{model.performance(a):.4f}"]
                for k, (v, a) in enumerate(ranked[:10])
            ],
        ),
        "",
        f"Predicted optimum: **{_describe(model, best)}**, {3600 * best_value:.0f} value per hour, "
        f"{model.performance(best):.4f} per robot per 10 s. Worst allocation: "
        f"{_describe(model, ranked[-1][1])} ({model.performance(ranked[-1][1]):.4f}).",
    ]
    summary = {
        "optimum": best,
        "optimum_performance": model.performance(best),
        "ranked_top10": [(a, model.performance(a)) for _, a in ranked[:10]],
    }
    write_results(
        out,
        "slot_values",
        slot_rows,
        "\n".join(body),
        meta,
        f"TAVC model of {args.preset}: completion frequencies and slot values",
        summary,
    )

    # 2. The check: chosen allocations as static allocations in the full arena.
    allocations = check_allocations(model, args.top)
    check_specs = [
        TrialSpec(
            key=f"{allocation_key(a)}_s{seed}",
            allocator="static",
            allocator_kwargs={"circuits": robot_circuits(a, classes)},
            seed=seed,
            env_kwargs={"preset": args.preset},
            convergence_s=warmup,
            measured_s=measured,
            snapshot_every_s=warmup + measured,
        )
        for a in allocations
        for seed in range(args.check_seeds)
    ]
    print(f"checking {len(allocations)} allocations in the full arena")
    checked, check_meta = run_trials(
        check_specs, out / "cache" / "check", args.workers, settings, backend=args.backend
    )
    check_rows: list[dict[str, Any]] = []
    for a in allocations:
        perfs = []
        for seed in range(args.check_seeds):
            r = checked[f"{allocation_key(a)}_s{seed}"]
            t0, t1 = r.measured_window
            perfs.append(
                metrics.value_rate(
                    r.delivery_time_s, r.delivery_circuit, r.values, len(r.agents), t0, t1
                )
            )
        m, lo, hi, _ = mean_ci(perfs)
        check_rows.append(
            {
                "allocation": _describe(model, a),
                "key": allocation_key(a),
                "model_rank": [x for _, x in ranked].index(a) + 1,
                "predicted": model.performance(a),
                "measured": m,
                "measured_low": lo,
                "measured_high": hi,
                "measured_over_predicted": m / model.performance(a),
                "runs": perfs,
            }
        )
    measured_best = max(check_rows, key=lambda row: row["measured"])
    rank_corr = float(
        stats.spearmanr([r["predicted"] for r in check_rows], [r["measured"] for r in check_rows])[
            0
        ]
    )
    check_body = [
        "Each allocation run as a static allocation in the full arena "
        f"({args.check_seeds} seeds x {args.measured_h:g} h after {args.warmup_min:g} min); "
        "delivered value per robot per 10 s with a 95 % interval over seeds.",
        "",
        markdown_table(
            ["allocation", "model rank", "predicted", "measured [95 % CI]", "measured / predicted"],
            [
                [
                    r["allocation"],
                    r["model_rank"],
                    f"{r['predicted']:.4f}",
                    f"{r['measured']:.4f} [{r['measured_low']:.4f}, {r['measured_high']:.4f}]",
                    f"{r['measured_over_predicted']:.3f}",
                ]
                for r in check_rows
            ],
        ),
        "",
        f"Measured best: {measured_best['allocation']} (model rank {measured_best['model_rank']}). "
        f"Spearman rank correlation of predicted and measured: {rank_corr:.2f}.",
    ]
    check_meta["model_wall_time_s"] = meta.get("wall_time_s")
    write_results(
        out,
        "check",
        check_rows,
        "\n".join(check_body),
        check_meta,
        f"TAVC model of {args.preset}: prediction checked in the full arena",
        {"measured_best": measured_best["allocation"], "rank_correlation": rank_corr},
        fields=[k for k in check_rows[0] if k != "runs"],
    )
    print((out / "slot_values.md").read_text().split("## Best allocations (model)")[1])
    print("\n".join(check_body))


def _describe(model: CompletionModel, allocation: Allocation) -> str:
    return " | ".join(f"c{i}: {model.describe(g)}" for i, g in enumerate(allocation))


def _rates_table(model: CompletionModel) -> str:
    import itertools

    groups = [g for g in itertools.product(*(range(n + 1) for n in model.team)) if sum(g)]
    se = model.rates_se if model.rates_se is not None else np.zeros_like(model.rates)
    rows = [
        [model.describe(g)]
        + [
            f"{3600 * model.rate(i, g):.1f} +- {3600 * se[(i, *g)]:.1f}"
            for i in range(model.n_circuits)
        ]
        for g in groups
    ]
    return markdown_table(["group", *(f"circuit {i}" for i in range(model.n_circuits))], rows)


if __name__ == "__main__":
    main()
