"""TAVC against the MRTA baselines the paper lacked, on `dahl2004` and a harder preset.

Every allocator -- random, epsilon-greedy TAVC, softmax TAVC (the paper's three), static at the
model optimum, greedy on the model's slot values, a MURDOCH / TraderBots-style auction and a
Bonabeau-style response-threshold allocator -- runs `--trials` trials per preset (default 10 x
(15 h + 5 h measured), the paper's periods). Reported per allocator, with 95 % intervals over
trials:

* delivered value per robot per 10 s in the measured period (the paper's performance measure),
  and as a fraction of the model optimum's predicted value (`benchmarks/tavc_model.py`);
* the model value of the allocation itself (time-weighted over the measured period; the gap to the
  delivered value is what switching and transients cost);
* circuit switches per robot per hour;
* time to settle: the start of the first 2-hour window in which the mean model value of the current
  allocation is within 3 % of its measured-period mean (never: `inf`).

Outputs in `benchmarks/results/allocators/`: `allocators.{md,csv,json}` (summary),
`trials.csv` (every trial's measures), `allocators.png` (bar plot). Trials are kept under
`cache/` as they finish (not committed), so an interrupted run resumes.

    python benchmarks/allocators.py
    python benchmarks/allocators.py --quick       # a smoke run
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from _common import (
    RESULTS_DIR,
    add_sweep_options,
    fmt_ci,
    have_matplotlib,
    markdown_table,
    mean_ci,
    ratio_ci,
    run_trials,
    write_csv,
    write_results,
)
from tavc_model import load_model

from agents.experiments.runner import TrialResult
from agents.experiments.sweep import TrialSpec
from agents.model import CompletionModel, SpeedClasses
from tavc_env import make_config, metrics

PRESETS = ("dahl2004", "three_circuits_three_classes")
SETTLE_BAND = 0.03
SETTLE_WINDOW_H = 2


@dataclass(frozen=True)
class Allocator:
    name: str  # registry name
    label: str
    kwargs: Mapping[str, Any]


def allocators(model: CompletionModel) -> list[Allocator]:
    m = model.to_dict()
    return [
        Allocator("random", "random", {}),
        Allocator("epsilon_tavc", "epsilon TAVC", {"epsilon": 0.1, "init": "scaled"}),
        Allocator("softmax_tavc", "softmax TAVC", {"temperature": 0.005, "init": "scaled"}),
        Allocator("response_threshold", "response threshold", {}),
        Allocator("auction", "auction", {"model": m}),
        Allocator("greedy", "greedy (model)", {"model": m}),
        Allocator("static", "static (model optimum)", {"model": m}),
    ]


def settle_time_h(
    result: TrialResult, model: CompletionModel, classes: SpeedClasses, target: float
) -> float:
    """Hours until the allocation first comes within SETTLE_BAND of its long-run quality
    `target`: the start of the first SETTLE_WINDOW_H-hour window whose mean model value is within
    SETTLE_BAND of it (inf if none is). A sliding window and a first entry, rather than "stays
    inside", so that the hour-to-hour noise of stochastic allocators does not count as
    drifting."""
    hours = int(result.measured_window[1] // 3600)
    for h in range(hours - SETTLE_WINDOW_H + 1):
        window = (h * 3600.0, (h + SETTLE_WINDOW_H) * 3600.0)
        value = model.mean_performance(result.initial_circuits, result.changes, classes, *window)
        if abs(value - target) <= SETTLE_BAND * target:
            return float(h)
    return math.inf


def measure(
    result: TrialResult, model: CompletionModel, classes: SpeedClasses, optimum: float
) -> dict[str, float]:
    """One trial's measures; `optimum` is the model optimum's performance."""
    t0, t1 = result.measured_window
    perf = metrics.value_rate(
        result.delivery_time_s, result.delivery_circuit, result.values, len(result.agents), t0, t1
    )
    held = model.mean_performance(result.initial_circuits, result.changes, classes, t0, t1)
    switches = sum(1 for t, _, _ in result.changes if t0 <= t < t1)
    return {
        "performance": perf,
        "fraction_of_optimum": perf / optimum,
        "allocation_value_fraction": held / optimum,
        "switches_per_robot_h": switches / len(result.agents) / ((t1 - t0) / 3600.0),
        "settle_h": settle_time_h(result, model, classes, held),
        "escapes": result.escapes,
    }


def specs_for(preset: str, model: CompletionModel, args: argparse.Namespace) -> list[TrialSpec]:
    return [
        TrialSpec(
            key=f"{preset}__{a.name}_s{seed}",
            allocator=a.name,
            allocator_kwargs=a.kwargs,
            seed=seed,
            env_kwargs={"preset": preset},
            convergence_s=args.convergence_h * 3600.0,
            measured_s=args.measured_h * 3600.0,
        )
        for a in allocators(model)
        for seed in range(args.trials)
    ]


def summarise(
    preset: str,
    model: CompletionModel,
    results: Mapping[str, TrialResult],
    trials: int,
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Per-allocator summary rows and per-trial rows."""
    summary, per_trial = [], []
    measures: dict[str, list[dict[str, float]]] = {}
    classes = SpeedClasses.of(make_config(preset))
    optimum = model.performance(model.optimum())
    for a in allocators(model):
        rows = [
            measure(results[f"{preset}__{a.name}_s{s}"], model, classes, optimum)
            for s in range(trials)
        ]
        measures[a.name] = rows
        per_trial += [
            {"preset": preset, "allocator": a.name, "seed": s, **r} for s, r in enumerate(rows)
        ]
    random_perf = [r["performance"] for r in measures["random"]]
    for a in allocators(model):
        rows = measures[a.name]
        perf = [r["performance"] for r in rows]
        settle = np.array([r["settle_h"] for r in rows])
        row: dict[str, Any] = {"preset": preset, "allocator": a.name, "label": a.label}
        for key in (
            "performance",
            "fraction_of_optimum",
            "allocation_value_fraction",
            "switches_per_robot_h",
        ):
            m, lo, hi, _ = mean_ci([r[key] for r in rows])
            row.update({key: m, f"{key}_low": lo, f"{key}_high": hi})
        ratio = ratio_ci(perf, random_perf)
        row.update(vs_random=ratio[0], vs_random_low=ratio[1], vs_random_high=ratio[2])
        row.update(
            settle_h_median=float(np.median(settle)),
            settle_never=int(np.isinf(settle).sum()),
            trials=len(rows),
        )
        summary.append(row)
    return summary, per_trial


def report(summary: Sequence[Mapping[str, Any]], model: CompletionModel, preset: str) -> str:
    optimum = model.optimum()
    lines = [
        f"### {preset}",
        "",
        f"Model optimum: {' | '.join(f'c{i}: {model.describe(g)}' for i, g in enumerate(optimum))}"
        f" = {model.performance(optimum):.4f} per robot per 10 s.",
        "",
        markdown_table(
            [
                "allocator",
                "value / robot / 10 s",
                "fraction of optimum",
                "allocation's model value",
                "vs random",
                "switches / robot / h",
                "settle (h, median)",
            ],
            [
                [
                    r["label"],
                    fmt_ci(r["performance"], r["performance_low"], r["performance_high"], 4),
                    fmt_ci(
                        r["fraction_of_optimum"],
                        r["fraction_of_optimum_low"],
                        r["fraction_of_optimum_high"],
                        3,
                    ),
                    fmt_ci(
                        r["allocation_value_fraction"],
                        r["allocation_value_fraction_low"],
                        r["allocation_value_fraction_high"],
                        3,
                    ),
                    fmt_ci(r["vs_random"], r["vs_random_low"], r["vs_random_high"], 3),
                    f"{r['switches_per_robot_h']:.2f}",
                    _settle(r),
                ]
                for r in summary
            ],
        ),
    ]
    return "\n".join(lines)


def _settle(row: Mapping[str, Any]) -> str:
    text = "never" if math.isinf(row["settle_h_median"]) else f"{row['settle_h_median']:.0f}"
    if row["settle_never"]:
        text += f" ({row['settle_never']}/{row['trials']} never)"
    return text


def plot(summary: Sequence[Mapping[str, Any]], path: Path) -> None:
    import matplotlib.pyplot as plt

    presets = list(dict.fromkeys(r["preset"] for r in summary))
    fig, axes = plt.subplots(1, len(presets), figsize=(6 * len(presets), 4.2), sharey=True)
    for ax, preset in zip(np.atleast_1d(axes), presets):
        rows = [r for r in summary if r["preset"] == preset]
        x = np.arange(len(rows))
        mean = np.array([r["fraction_of_optimum"] for r in rows])
        err = np.array(
            [
                [m - r["fraction_of_optimum_low"], r["fraction_of_optimum_high"] - m]
                for m, r in zip(mean, rows)
            ]
        ).T
        ax.bar(x, mean, yerr=err, capsize=3, color="tab:blue", alpha=0.8, label="delivered")
        ax.plot(
            x,
            [r["allocation_value_fraction"] for r in rows],
            "k_",
            markersize=18,
            label="model value of the allocation",
        )
        ax.set_xticks(x, [r["label"] for r in rows], rotation=35, ha="right")
        ax.axhline(1.0, color="grey", lw=0.8, ls="--")
        ax.set_title(preset)
        ax.set_ylim(0.6, 1.05)
    np.atleast_1d(axes)[0].set_ylabel("value per robot per 10 s / model optimum")
    np.atleast_1d(axes)[0].legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--presets", nargs="+", default=list(PRESETS), choices=PRESETS)
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--convergence-h", type=float, default=15.0)
    parser.add_argument("--measured-h", type=float, default=5.0)
    add_sweep_options(parser)
    parser.add_argument("--out", type=Path, default=RESULTS_DIR / "allocators")
    parser.add_argument("--quick", action="store_true", help="2 trials of 1 h + 1 h (smoke run)")
    parser.add_argument(
        "--model",
        type=Path,
        nargs="+",
        default=None,
        help="model.json per preset (default: the committed ones)",
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.trials, args.convergence_h, args.measured_h = 2, 1.0, 1.0
        if args.out == RESULTS_DIR / "allocators":
            args.out = RESULTS_DIR / "allocators_quick"
    if args.trials < 2:
        parser.error(f"--trials = {args.trials}; allowed: >= 2 (for confidence intervals)")
    if args.convergence_h < 0 or args.measured_h <= 0:
        parser.error("allowed: --convergence-h >= 0 and --measured-h > 0")
    if args.model is not None and len(args.model) != len(args.presets):
        parser.error(f"--model: {len(args.model)} paths; allowed: one per preset {args.presets}")

    paths = args.model or [None] * len(args.presets)
    models = {p: load_model(p, path) for p, path in zip(args.presets, paths)}
    specs = [s for p in args.presets for s in specs_for(p, models[p], args)]
    settings = {k: str(v) for k, v in vars(args).items() if k != "workers"}
    results, meta = run_trials(
        specs, args.out / "cache", args.workers, settings, backend=args.backend
    )

    summary: list[dict[str, Any]] = []
    per_trial: list[dict[str, Any]] = []
    sections = []
    for preset in args.presets:
        s, t = summarise(preset, models[preset], results, args.trials)
        summary += s
        per_trial += t
        sections.append(report(s, models[preset], preset))
    body = (
        f"{args.trials} trials per allocator and preset, {args.convergence_h:g} h convergence + "
        f"{args.measured_h:g} h measured; mean [95 % CI] over trials.\n\n" + "\n\n".join(sections)
    )
    write_csv(args.out / "trials.csv", per_trial)
    write_results(
        args.out, "allocators", summary, body, meta, "Allocators compared", {"rows": summary}
    )
    if have_matplotlib():
        plot(summary, args.out / "allocators.png")
    print(body)


if __name__ == "__main__":
    main()
