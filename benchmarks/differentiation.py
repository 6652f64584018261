"""Where does differentiation come from? Softmax temperature and arena regime, measured.

Softmax TAVC at several temperatures, epsilon-greedy TAVC and random allocation in the arena
regimes stations, competence and light_stations; reports, with 95 % confidence intervals over
trials, the time fast and slow robots spend on the high-value circuit, their difference (the
paper's effect: > 0) and performance against random. Trials are saved as they finish and reused
by a rerun.

    python benchmarks/differentiation.py                       # all regimes, default temperatures
    python benchmarks/differentiation.py --regimes stations --temperatures 0.002,0.005,0.02
    python benchmarks/differentiation.py --quick

Where does differentiation come from? Softmax temperature and arena regime, measured.

For each arena regime and each softmax temperature, `--trials` trials of softmax TAVC (plus the
random and epsilon-greedy baselines once per regime) on `dahl2004`-style teams; reports, with 95 %
confidence intervals over trials, the fraction of the measured period fast and slow robots spend on
the high-value circuit, their difference (the paper's effect: > 0), the performance (delivered value
per robot per 10 s) and its ratio to random allocation.

Regimes (arena overrides; each a physical hypothesis about who yields to whom):

* `stations`: the default arena (one-robot docks, 20 s loading, 4 s unloading). Fast robots catch up
  with slow ones at the docks and queue behind them (see the cross-interference matrix).
* `competence`: as `stations`, but loading and unloading take longer for slower robots
  (`service_scales_with_speed`): speed as task-processing speed, as the paper frames it.
* `light_stations`: 6 s loading, 2 s unloading: interference mostly from traffic, much weaker, so
  3 + 3 is no longer the homogeneous equilibrium.

    python benchmarks/differentiation.py                       # all regimes, default temperatures
    python benchmarks/differentiation.py --regimes stations --temperatures 0.002,0.005,0.02
    python benchmarks/differentiation.py --quick

Trials are saved as they finish under `<out>/trials/` and reused by a rerun.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

from tavc_agents.analysis.measures import TrialMeasures, measure
from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci, ratio_ci
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    choices,
    positive,
    refuse_invalid,
    replace,
    run_study,
)
from tavc_agents.experiments.sweep import TagValue, TrialSpec
from tavc_env.config import ARENA_REGIMES
from tavc_env.validation import is_number

REGIMES = ARENA_REGIMES  # also shipped as presets dahl2004, dahl2004_competence, ...
DEFAULT_TEMPERATURES = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05)
Group = tuple[str, str]  # (regime, condition)


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The differentiation study's settings (its command line)."""

    reference: ClassVar = "differentiation"
    quick_sizes: ClassVar = {"trials": 2, "convergence_h": 0.3, "measured_h": 0.2}
    recorded_fields: ClassVar = (
        "regimes=regime_list temperatures=temperature_list trials convergence_h measured_h "
        "init seed"
    )

    regimes: str = ",".join(REGIMES)
    """comma-separated subset of the arena regimes stations, competence, light_stations"""
    temperatures: str = ",".join(str(t) for t in DEFAULT_TEMPERATURES)
    """softmax temperatures, comma-separated"""
    trials: int = 8
    """trials per regime and condition"""
    convergence_h: float = 15.0
    """convergence period, simulated hours"""
    measured_h: float = 5.0
    """measured period, simulated hours"""
    init: Literal["scaled", "paper"] = "scaled"
    """Q-table initialisation"""
    seed: int = 0
    """trial k uses seed + k in every cell"""
    quick: bool = False
    """2 trials of 0.3 + 0.2 h, two temperatures"""

    def __post_init__(self) -> None:
        super().__post_init__()
        choices(self, "regimes", REGIMES)  # an unknown regime is refused
        try:
            temperatures = self.temperature_list
        except ValueError:
            temperatures = []
        refuse_invalid(
            self,
            [
                (
                    "temperatures",
                    bool(temperatures) and all(positive(t) for t in temperatures),
                    "finite numbers > 0, comma-separated",
                ),
                ("trials", at_least(self.trials, 1), "an integer >= 1"),
                (
                    "convergence_h",
                    is_number(self.convergence_h) and self.convergence_h >= 0,
                    "a finite number >= 0",
                ),
                ("measured_h", positive(self.measured_h), "a finite number > 0"),
            ],
        )

    @property
    def regime_list(self) -> list[str]:
        return choices(self, "regimes", REGIMES)

    @property
    def temperature_list(self) -> list[float]:
        return [float(t) for t in self.temperatures.split(",") if t.strip()]

    def sized(self) -> Settings:
        """These settings with `--quick`'s sizes applied: also only the first two temperatures."""
        if not self.quick:
            return self
        first_two = ",".join(str(t) for t in self.temperature_list[:2])
        return replace(super().sized(), temperatures=first_two)


def _label(value: float) -> str:
    return f"{value:g}".replace(".", "p")


def conditions(settings: Settings) -> list[tuple[str, str, dict[str, Any], float | None]]:
    """(condition name, allocator, its parameters, softmax temperature or None) per condition."""
    runs: list[tuple[str, str, dict[str, Any], float | None]] = [
        (f"softmax_T{_label(t)}", "softmax_tavc", {"temperature": t, "init": settings.init}, t)
        for t in settings.temperature_list
    ]
    runs.append(("epsilon", "epsilon_tavc", {"epsilon": 0.1, "init": settings.init}, None))
    runs.append(("random", "random", {}, None))
    return runs


def trial_key(tags: Mapping[str, TagValue]) -> str:
    return f"{tags['regime']}__{tags['condition']}__seed{tags['seed']}"


def specs(settings: Settings) -> list[TrialSpec]:
    """Every trial, tagged with its regime, condition, temperature (softmax only) and seed."""
    s = settings.sized()
    out = []
    for regime in s.regime_list:
        env_kwargs = {"preset": "dahl2004", **dict(REGIMES[regime])}
        for name, allocator, kwargs, temperature in conditions(s):
            for k in range(s.trials):
                tags: dict[str, TagValue] = {
                    "regime": regime,
                    "condition": name,
                    "seed": s.seed + k,
                }
                if temperature is not None:
                    tags["temperature"] = temperature
                out.append(
                    TrialSpec(
                        key=trial_key(tags),
                        allocator=allocator,
                        allocator_kwargs=kwargs,
                        seed=s.seed + k,
                        env_kwargs=env_kwargs,
                        convergence_s=s.convergence_h * 3600.0,
                        measured_s=s.measured_h * 3600.0,
                        tags=tags,
                    )
                )
    return out


def run(settings: Settings) -> Outcome:
    """Run (or resume) the trials, then write the report and the figure."""
    out = settings.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    trial_specs = specs(settings)
    print(f"{len(trial_specs)} trials; results in {out}", flush=True)
    results, provenance = settings.run_trials(trial_specs)
    groups: dict[Group, list[TrialMeasures]] = {}
    for spec in trial_specs:
        group = (str(spec.tags["regime"]), str(spec.tags["condition"]))
        groups.setdefault(group, []).append(measure(results[spec.key]))
    s = settings.sized()
    temperature_of = {name: t for name, _, _, t in conditions(s) if t is not None}
    rows, table = summarise(groups)
    body = (
        f"Softmax TAVC at several temperatures, epsilon-greedy TAVC and random allocation on "
        f"`dahl2004` in each regime; {s.trials} trials each, {s.convergence_h:g} h "
        f"convergence + {s.measured_h:g} h measured; Q-table initialisation `{s.init}`. "
        "Regimes: "
        + "; ".join(f"`{k}` = {REGIMES[k] or 'defaults'}" for k in s.regime_list)
        + ".\n\n"
        + table
        + "\n\n"
        + paired_to_lowest_temperature(groups, s.temperature_list)
    )
    report = Report(
        "differentiation",
        "Where differentiation comes from",
        body,
        rows,
        figures=[("differentiation.png", lambda path: plot(rows, temperature_of, path))],
    )
    written = report.write(out, provenance)
    figure = ", differentiation.png" if len(written) > 3 else ""
    text = (
        f"\n{table}\nwall time {provenance['wall_time_s']:.0f} s; "
        f"wrote {out / 'differentiation.md'}{figure}"
    )
    return Outcome(out, written, text)


def summarise(groups: dict[Group, list[TrialMeasures]]) -> tuple[list[dict[str, Any]], str]:
    """One row per (regime, condition) and the Markdown table of them."""
    rows: list[dict[str, Any]] = []
    for (regime, name), ms in groups.items():
        diff = mean_ci([m.fast_share - m.slow_share for m in ms])
        perf = mean_ci([m.performance for m in ms])
        random = groups.get((regime, "random"), [])
        ratio = (
            ratio_ci([m.performance for m in ms], [m.performance for m in random])
            if random
            else (math.nan,) * 3
        )
        rows.append(
            {
                "regime": regime,
                "condition": name,
                "trials": len(ms),
                "fast_share": float(np.mean([m.fast_share for m in ms])),
                "slow_share": float(np.mean([m.slow_share for m in ms])),
                "fast_minus_slow": diff[0],
                "fast_minus_slow_lo": diff[1],
                "fast_minus_slow_hi": diff[2],
                "time_3_0": float(np.mean([m.states[(3, 0)] for m in ms])),
                "performance": perf[0],
                "performance_lo": perf[1],
                "performance_hi": perf[2],
                "ratio_to_random": ratio[0],
                "ratio_lo": ratio[1],
                "ratio_hi": ratio[2],
            }
        )
    header = [
        "regime",
        "condition",
        "trials",
        "fast on high",
        "slow on high",
        "fast - slow (95 % CI)",
        "time in 3:0 (%)",
        "performance (95 % CI)",
        "/ random (95 % CI)",
    ]
    body = [
        [
            r["regime"],
            r["condition"],
            r["trials"],
            f"{r['fast_share']:.3f}",
            f"{r['slow_share']:.3f}",
            fmt_ci(r["fast_minus_slow"], r["fast_minus_slow_lo"], r["fast_minus_slow_hi"], 3),
            f"{r['time_3_0']:.1f}",
            fmt_ci(r["performance"], r["performance_lo"], r["performance_hi"], 4),
            fmt_ci(r["ratio_to_random"], r["ratio_lo"], r["ratio_hi"], 3),
        ]
        for r in rows
    ]
    return rows, markdown_table(header, body)


PAIRED_NOTE = (
    "Per seed, (fast - slow) at a temperature minus (fast - slow) at the lowest temperature, "
    "mean and 95 % CI over seeds. Trials of one seed share their start and, with the `paper` "
    "initialisation, their initial Q noise; at the lowest temperature choices are greedy on that "
    "noise and blind to speed, so with the `paper` initialisation this is the part of the "
    "differentiation that speed adds through learning."
)


def paired_to_lowest_temperature(
    groups: dict[Group, list[TrialMeasures]], temperatures: Sequence[float]
) -> str:
    """Per regime and temperature, the seed-paired difference of (fast - slow) between that
    temperature and the lowest one (see `PAIRED_NOTE`)."""
    lowest = min(temperatures)
    rows = []
    regimes = dict.fromkeys(regime for regime, _ in groups)
    for regime in regimes:
        base = groups.get((regime, f"softmax_T{_label(lowest)}"))
        if not base:
            continue
        for t in sorted(temperatures):
            if t == lowest:
                continue
            cell = groups.get((regime, f"softmax_T{_label(t)}"), [])
            diffs = [
                (a.fast_share - a.slow_share) - (b.fast_share - b.slow_share)
                for a, b in zip(cell, base)
            ]
            m, lo, hi, n = mean_ci(diffs)
            rows.append([regime, f"{t:g} vs {lowest:g}", n, fmt_ci(m, lo, hi, 3)])
    if not rows:
        return ""
    header = ["regime", "temperature", "seeds", "(fast - slow) minus its value at the lowest T"]
    return f"## Paired against the lowest temperature\n\n{PAIRED_NOTE}\n\n" + (
        markdown_table(header, rows) + "\n"
    )


def plot(rows: list[dict[str, Any]], temperature_of: Mapping[str, float], path: Path) -> None:
    """Fast - slow and performance / random against the softmax temperature, per regime."""

    fig, axes = subplots(1, 2, figsize=(11, 4))
    for regime in dict.fromkeys(r["regime"] for r in rows):
        pts = [r for r in rows if r["regime"] == regime and r["condition"] in temperature_of]
        temps = [temperature_of[r["condition"]] for r in pts]
        for ax, key, lo_key, hi_key in (
            (axes[0], "fast_minus_slow", "fast_minus_slow_lo", "fast_minus_slow_hi"),
            (axes[1], "ratio_to_random", "ratio_lo", "ratio_hi"),
        ):
            y = np.array([r[key] for r in pts])
            lo = np.array([r[lo_key] for r in pts])
            hi = np.array([r[hi_key] for r in pts])
            err = np.vstack([np.nan_to_num(y - lo), np.nan_to_num(hi - y)])
            ax.errorbar(temps, y, yerr=err, marker="o", capsize=4, label=regime)
    axes[0].axhline(0, color="black", linewidth=0.8)
    axes[0].set_ylabel("fast - slow share of time on the high-value circuit")
    axes[1].axhline(1, color="black", linewidth=0.8)
    axes[1].set_ylabel("performance / random allocation")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xlabel("softmax temperature")
        ax.legend()
    axes[0].set_title("Differentiation (paper's effect > 0), 95 % CI")
    axes[1].set_title("Performance relative to random, 95 % CI")
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
