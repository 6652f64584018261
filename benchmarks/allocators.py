"""TAVC against the MRTA baselines the paper lacked, on `dahl2004` and a harder preset.

Random, epsilon-greedy and softmax TAVC, a response-threshold allocator, an auction, greedy on
the model's slot values and static at the model optimum: 10 trials each per preset of 15 h + 5 h
measured. Reports delivered value (also as a fraction of the model optimum), the model value of
the allocation held, switches per robot per hour and time to settle, with 95 % intervals. Writes
allocators.{md,csv,json}, trials.csv and allocators.png into benchmarks/results/allocators/ (or
--out); trials are kept in cache/ so `--resume RUN_DIR` continues an interrupted run. Needs the models of the tavc_model study.

    python benchmarks/allocators.py
    python benchmarks/allocators.py --quick       # a smoke run
    python benchmarks/allocators.py --update-reference --figure-only   # redraw the PNG, run nothing

TAVC against the MRTA baselines the paper lacked, on `dahl2004` and a harder preset.

Every allocator -- random, `stay` (keep the circuit the start gave), epsilon-greedy TAVC, softmax
TAVC (the paper's three), static at the model optimum, greedy on the model's slot values, a
MURDOCH / TraderBots-style auction, a Bonabeau-style response-threshold allocator, and every
trained deep MARL network found for the preset (`--networks`: learning runs of `docs/examples`,
in `--network-dir` (`benchmarks/results/marl/`) `<run>_<preset>/network.npz`, run greedily), and
your own allocators by name (`--plugins NAME ...`: registered, or a `tavc.allocators` entry
point) -- runs `--trials` trials per preset (default 10 x
(15 h + 5 h measured), the paper's periods). Reported per allocator, with 95 % intervals over
trials:

* delivered value per robot per 10 s in the measured period (the paper's performance measure),
  and as a fraction of the model optimum's predicted value (the tavc_model study);
* the model value of the allocation itself (time-weighted over the measured period; the gap to the
  delivered value is what switching and transients cost);
* circuit switches per robot per hour;
* the model value of the start's allocation (the reset's even spread, drawn from the seed, the same
  for every allocator): how much of any allocator's score the reset hands it;
* time to settle: the start of the first 2-hour window in which the mean model value of the current
  allocation is within 3 % of its measured-period mean (never: `inf`).

Outputs in `benchmarks/results/allocators/` (the committed reference; a run writes into a new `runs/` folder unless `--update-reference` or `--out`): `allocators.{md,csv,json}` (summary),
`trials.csv` (every trial's measures, with the preset, allocator and seed that rebuild it),
`allocators.png` (bar plot). Trials are kept under `cache/` as they finish (not committed), so an
interrupted run resumes; `reproduce_rows` re-runs a sample of them against `trials.csv`.
`--figure-only` redraws `allocators.png` from a finished run's `allocators.csv` without running
a trial or writing anything else.

    python benchmarks/allocators.py
    python benchmarks/allocators.py --quick       # a smoke run
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

from tavc_agents.analysis import allocation
from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, fmt_ci_of, markdown_table, write_csv
from tavc_agents.analysis.row_check import compare_rows, read_rows, run_fresh, sample_rows
from tavc_agents.analysis.stats import mean_ci, ratio_ci
from tavc_agents.evaluation import Allocator, allocators
from tavc_agents.experiments.registry import allocator_names
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.study import (
    RESULTS_DIR,
    Outcome,
    StudySettings,
    at_least,
    positive,
    redraw,
    redraw_source,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import TagValue, TrialSpec
from tavc_agents.model import CompletionModel, SpeedClasses, load_model, missing_model
from tavc_env import make_config
from tavc_env.validation import is_number

PresetName = Literal["dahl2004", "three_circuits_three_classes"]
PRESETS: tuple[PresetName, ...] = ("dahl2004", "three_circuits_three_classes")
FIGURE = "allocators.png"
NETWORK_RUNS = ("sb3_maskable_ppo", "torchrl_mappo", "rllib_ppo")
SETTLE_BAND = 0.03
SETTLE_WINDOW_H = 2
TRIAL_MEASURES = (
    "performance",
    "fraction_of_optimum",
    "allocation_value_fraction",
    "start_value_fraction",
    "switches_per_robot_h",
)


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The allocator comparison's settings (its command line)."""

    reference: ClassVar = "allocators"
    quick_sizes: ClassVar = {"trials": 2, "convergence_h": 1.0, "measured_h": 1.0}
    recorded_as_text: ClassVar = True
    recorded_fields: ClassVar = (
        "presets trials convergence_h measured_h backend out=out_text quick model networks "
        "network_dir"
    )

    presets: tuple[PresetName, ...] = PRESETS
    """arena presets to compare on"""
    trials: int = 10
    """trials per allocator and preset (>= 2, for confidence intervals)"""
    convergence_h: float = 15.0
    """convergence period, simulated hours"""
    measured_h: float = 5.0
    """measured period, simulated hours"""
    quick: bool = False
    """smoke run: 2 trials of 1 h + 1 h"""
    model: tuple[Path, ...] | None = None
    """model.json per preset (default: the committed ones)"""
    networks: tuple[str, ...] = NETWORK_RUNS
    """learning runs whose trained network joins the comparison where one exists for the preset"""
    network_dir: Path = RESULTS_DIR / "marl"
    """where the learning runs are (`<run>_<preset>/network.npz`)"""
    plugins: tuple[str, ...] = ()
    """more allocators by name, with their default parameters (and the preset's model if they
    take `model`): your own, from a `tavc.allocators` entry point or registered at run time"""
    figure_only: bool = False
    """run nothing: redraw allocators.png from the allocators.csv already in the output folder"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            ("presets", bool(self.presets) and set(self.presets) <= set(PRESETS), str(PRESETS)),
            ("trials", at_least(self.trials, 2), "an integer >= 2"),
            ("convergence_h", is_number(self.convergence_h) and self.convergence_h >= 0, ">= 0"),
            ("measured_h", positive(self.measured_h), "> 0"),
        ]
        refuse_invalid(self, checks)
        known = allocator_names()
        unknown = [name for name in self.plugins if name not in known]
        if unknown or len(set(self.plugins)) != len(self.plugins):
            raise ValueError(
                f"plugins = {self.plugins!r} is invalid; allowed: distinct allocator names from "
                f"{known}"
            )
        if self.model is not None and len(self.model) != len(self.presets):
            raise ValueError(
                f"model = {self.model!r} is invalid; allowed: one path per preset {self.presets}"
            )
        for preset, path in zip(self.presets, self.model_paths()):
            problem = missing_model(preset, path)
            if problem is not None:
                raise ValueError(f"model = {path!r} is invalid; allowed: a model.json ({problem})")

    def model_paths(self) -> list[Path | None]:
        return list(self.model) if self.model is not None else [None] * len(self.presets)

    def recorded(self) -> dict[str, Any]:
        # plugins only when given, so the reports of runs without them record what they always did
        plugins = {"plugins": str(list(self.plugins))} if self.plugins else {}
        return {**super().recorded(), **plugins}

    def compared(self, preset: str, model: CompletionModel) -> list[Allocator]:
        """The allocators compared on `preset`, in report order."""
        return allocators(model, self.network_paths(preset), self.plugins)

    def network_paths(self, preset: str) -> dict[str, Path]:
        """The trained networks found for `preset`, by learning run."""
        found = {run: self.network_dir / f"{run}_{preset}" / "network.npz" for run in self.networks}
        return {run: path for run, path in found.items() if path.is_file()}


def models(settings: Settings) -> dict[str, CompletionModel]:
    """The model of each preset."""
    return {p: load_model(p, path) for p, path in zip(settings.presets, settings.model_paths())}


def trial_key(tags: Mapping[str, TagValue]) -> str:
    return f"{tags['preset']}__{tags['allocator']}_s{tags['seed']}"


def trial_spec(
    settings: Settings, model: CompletionModel, preset: str, name: str, seed: int
) -> TrialSpec:
    """The trial of allocator `name` on `preset` with `seed` (tagged with the three)."""
    s = settings.sized()
    chosen = next(a for a in settings.compared(preset, model) if a.name == name)
    tags: dict[str, TagValue] = {"preset": preset, "allocator": name, "seed": seed}
    return TrialSpec(
        key=trial_key(tags),
        allocator=chosen.allocator,
        allocator_kwargs=chosen.kwargs,
        seed=seed,
        env_kwargs={"preset": preset},
        convergence_s=s.convergence_h * 3600.0,
        measured_s=s.measured_h * 3600.0,
        tags=tags,
    )


def specs(settings: Settings, by_preset: Mapping[str, CompletionModel]) -> list[TrialSpec]:
    """Every trial: preset by preset, allocator by allocator, seed 0 .. trials - 1."""
    trials = settings.sized().trials
    return [
        trial_spec(settings, by_preset[p], p, a.name, seed)
        for p in settings.presets
        for a in settings.compared(p, by_preset[p])
        for seed in range(trials)
    ]


def run(settings: Settings) -> Outcome:
    """Run (or resume) every trial, then write the summary, the per-trial table and the plot;
    with `figure_only`, only redraw the plot from the summary in the output folder."""
    out = settings.out_dir()
    if settings.figure_only:
        saved = read_rows(redraw_source(out / "allocators.csv"))
        return redraw(out, FIGURE, lambda path: plot(saved, path))
    by_preset = models(settings)
    trial_specs = specs(settings, by_preset)
    results, provenance = settings.run_trials(trial_specs, "cache")
    per_trial = trial_rows(trial_specs, results, by_preset)
    summary: list[dict[str, Any]] = []
    sections = []
    for preset in settings.presets:
        compared = settings.compared(preset, by_preset[preset])
        rows = summarise([r for r in per_trial if r["preset"] == preset], compared)
        summary += rows
        sections.append(preset_section(rows, by_preset[preset], preset))
    s = settings.sized()
    body = (
        f"{s.trials} trials per allocator and preset, {s.convergence_h:g} h convergence + "
        f"{s.measured_h:g} h measured; mean [95 % CI] over trials.\n\n" + "\n\n".join(sections)
    )
    write_csv(out / "trials.csv", per_trial)
    report = Report(
        "allocators",
        "Allocators compared",
        body,
        summary,
        {"rows": summary},
        figures=[(FIGURE, lambda path: plot(summary, path))],
    )
    written = [out / "trials.csv", *report.write(out, provenance)]
    return Outcome(out, written, body)


# -- measures ------------------------------------------------------------------------------------
def measure(
    result: TrialResult, model: CompletionModel, classes: SpeedClasses, optimum: float
) -> dict[str, float]:
    """One trial's measures; `optimum` is the model optimum's performance."""
    t0, t1 = result.measured_window
    perf = allocation.delivered_performance(result, t0, t1)
    held = allocation.held_performance(result, model, classes, t0, t1)
    return {
        "performance": perf,
        "fraction_of_optimum": perf / optimum,
        "allocation_value_fraction": held / optimum,
        "start_value_fraction": model.mean_performance(
            result.initial_circuits, [], classes, 0.0, 1.0
        )
        / optimum,
        "switches_per_robot_h": allocation.switches_per_robot_h(result, t0, t1),
        "settle_h": allocation.settle_time_h(
            result, model, classes, held, SETTLE_BAND, SETTLE_WINDOW_H
        ),
        "escapes": result.escapes,
    }


def trial_row(spec: TrialSpec, result: TrialResult, model: CompletionModel) -> dict[str, Any]:
    """A trial's row of `trials.csv`: its preset, allocator and seed, then its measures."""
    preset = str(spec.tags["preset"])
    classes = SpeedClasses.of(make_config(preset))
    optimum = model.performance(model.optimum())
    head = {"preset": preset, "allocator": spec.tags["allocator"], "seed": spec.tags["seed"]}
    return {**head, **measure(result, model, classes, optimum)}


def trial_rows(
    trial_specs: Sequence[TrialSpec],
    results: Mapping[str, TrialResult],
    by_preset: Mapping[str, CompletionModel],
) -> list[dict[str, Any]]:
    return [
        trial_row(spec, results[spec.key], by_preset[str(spec.tags["preset"])])
        for spec in trial_specs
    ]


def summarise(
    rows: Sequence[Mapping[str, Any]], compared: Sequence[Allocator]
) -> list[dict[str, Any]]:
    """Per allocator (of one preset's trial rows): every measure's mean and 95 % interval, the
    ratio to random, and the median settle time."""
    preset = rows[0]["preset"]
    by: dict[str, list[Mapping[str, Any]]] = {a.name: [] for a in compared}
    for trial in rows:
        by[trial["allocator"]].append(trial)
    random_perf = [r["performance"] for r in by["random"]]
    summary = []
    for a in compared:
        mine = by[a.name]
        settle = np.array([r["settle_h"] for r in mine])
        row: dict[str, Any] = {"preset": preset, "allocator": a.name, "label": a.label}
        for key in TRIAL_MEASURES:
            m, lo, hi, _ = mean_ci([r[key] for r in mine])
            row.update({key: m, f"{key}_low": lo, f"{key}_high": hi})
        ratio = ratio_ci([r["performance"] for r in mine], random_perf)
        row.update(vs_random=ratio[0], vs_random_low=ratio[1], vs_random_high=ratio[2])
        row.update(
            settle_h_median=float(np.median(settle)),
            settle_never=int(np.isinf(settle).sum()),
            trials=len(mine),
        )
        summary.append(row)
    return summary


# -- the report ----------------------------------------------------------------------------------
def preset_section(
    summary: Sequence[Mapping[str, Any]], model: CompletionModel, preset: str
) -> str:
    optimum = model.optimum()
    header = [
        "allocator",
        "value / robot / 10 s",
        "fraction of optimum",
        "allocation's model value",
        "vs random",
        "switches / robot / h",
        "settle (h, median)",
    ]
    rows = [
        [
            r["label"],
            fmt_ci_of(r, "performance", 4),
            fmt_ci_of(r, "fraction_of_optimum", 3),
            fmt_ci_of(r, "allocation_value_fraction", 3),
            fmt_ci_of(r, "vs_random", 3),
            f"{r['switches_per_robot_h']:.2f}",
            settle_text(r),
        ]
        for r in summary
    ]
    described = " | ".join(f"c{i}: {model.describe(g)}" for i, g in enumerate(optimum))
    start = summary[0]  # the same starts for every allocator (the same seeds)
    return "\n".join(
        [
            f"### {preset}",
            "",
            f"Model optimum: {described} = {model.performance(optimum):.4f} per robot per 10 s.",
            "The start's allocation (the reset spreads the robots evenly over the circuits, in an "
            f"order drawn from the seed) is worth {fmt_ci_of(start, 'start_value_fraction', 3)} of the "
            "optimum by the model: that much of every allocator's score the reset hands it.",
            "",
            markdown_table(header, rows),
        ]
    )


def settle_text(row: Mapping[str, Any]) -> str:
    text = "never" if math.isinf(row["settle_h_median"]) else f"{row['settle_h_median']:.0f}"
    if row["settle_never"]:
        text += f" ({row['settle_never']}/{row['trials']} never)"
    return text


def plot(summary: Sequence[Mapping[str, Any]], path: Path) -> None:
    """Delivered value and the allocation's model value, as fractions of the optimum, one panel
    per preset. The rows' numbers may be text (a written `allocators.csv`, for `--figure-only`)."""

    def number(row: Mapping[str, Any], key: str) -> float:
        return float(row[key])

    presets = list(dict.fromkeys(r["preset"] for r in summary))
    fig, axes = subplots(1, len(presets), figsize=(6 * len(presets), 5.0), sharey=True)
    for ax, preset in zip(np.atleast_1d(axes), presets):
        rows = [r for r in summary if r["preset"] == preset]
        x = np.arange(len(rows))
        mean = np.array([number(r, "fraction_of_optimum") for r in rows])
        err = np.array(
            [
                [
                    m - number(r, "fraction_of_optimum_low"),
                    number(r, "fraction_of_optimum_high") - m,
                ]
                for m, r in zip(mean, rows)
            ]
        ).T
        ax.bar(x, mean, yerr=err, capsize=3, color="tab:blue", alpha=0.8, label="delivered")
        ax.plot(
            x,
            [number(r, "allocation_value_fraction") for r in rows],
            "k_",
            markersize=18,
            label="model value of the allocation",
        )
        ax.set_xticks(x, [r["label"] for r in rows], rotation=35, ha="right")
        ax.axhline(1.0, color="grey", lw=0.8, ls="--")
        ax.set_title(preset)
        ax.set_ylim(0.0, 1.05)
    # two short lines: one long line was longer than the axis and was cut off at both ends
    np.atleast_1d(axes)[0].set_ylabel("fraction of the model optimum\n(value per robot per 10 s)")
    handles, labels = np.atleast_1d(axes)[0].get_legend_handles_labels()
    # above the panels, where it hides no bar
    fig.legend(handles, labels, loc="upper center", ncol=len(labels), fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.94))
    fig.savefig(path, dpi=120, format="png")


# -- reproduction ----------------------------------------------------------------------------------
def reproduce_rows(settings: Settings, sample: int, seed: int) -> list[tuple[str, bool]]:
    """Re-run `sample` trials drawn at random (with `seed`) from the `trials.csv` in the settings'
    output folder, from scratch, and compare each one's fresh row with the saved row, cell by
    cell as written: (trial key, identical) per trial."""
    saved = sample_rows(settings.out_dir() / "trials.csv", sample, seed)
    by_preset = models(settings)
    chosen = [
        trial_spec(settings, by_preset[r["preset"]], r["preset"], r["allocator"], int(r["seed"]))
        for r in saved
    ]
    fresh = run_fresh(chosen, settings.workers)
    rows = [trial_row(s, fresh[s.key], by_preset[str(s.tags["preset"])]) for s in chosen]
    return [(s.key, same) for s, same in zip(chosen, compare_rows(rows, saved))]


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
