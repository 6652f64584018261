"""Where does differentiation come from? Softmax temperature and arena regime, measured.

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

import argparse
import math
from collections.abc import Sequence
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
    write_results,
)
from table1 import TrialMeasures, measure

from agents.experiments.sweep import TrialSpec
from tavc_env.config import ARENA_REGIMES

REGIMES = ARENA_REGIMES  # also shipped as presets dahl2004, dahl2004_competence, ...
DEFAULT_TEMPERATURES = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05)


def _label(value: float) -> str:
    return f"{value:g}".replace(".", "p")


def specs_for(args: argparse.Namespace) -> list[TrialSpec]:
    specs = []
    for regime in args.regimes:
        env_kwargs = {"preset": "dahl2004", **dict(REGIMES[regime])}
        runs: list[tuple[str, str, dict[str, Any]]] = [
            (f"softmax_T{_label(t)}", "softmax_tavc", {"temperature": t, "init": args.init})
            for t in args.temperatures
        ]
        runs.append(("epsilon", "epsilon_tavc", {"epsilon": 0.1, "init": args.init}))
        runs.append(("random", "random", {}))
        for name, allocator, kwargs in runs:
            for k in range(args.trials):
                specs.append(
                    TrialSpec(
                        key=f"{regime}__{name}__seed{args.seed + k}",
                        allocator=allocator,
                        allocator_kwargs=kwargs,
                        seed=args.seed + k,
                        env_kwargs=env_kwargs,
                        convergence_s=args.convergence_h * 3600.0,
                        measured_s=args.measured_h * 3600.0,
                    )
                )
    return specs


def summarise(
    groups: dict[tuple[str, str], list[TrialMeasures]],
) -> tuple[list[dict[str, Any]], str]:
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
    table = markdown_table(
        [
            "regime",
            "condition",
            "trials",
            "fast on high",
            "slow on high",
            "fast - slow (95 % CI)",
            "time in 3:0 (%)",
            "performance (95 % CI)",
            "/ random (95 % CI)",
        ],
        [
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
        ],
    )
    return rows, table


PAIRED_NOTE = (
    "Per seed, (fast - slow) at a temperature minus (fast - slow) at the lowest temperature, "
    "mean and 95 % CI over seeds. Trials of one seed share their start and, with the `paper` "
    "initialisation, their initial Q noise; at the lowest temperature choices are greedy on that "
    "noise and blind to speed, so with the `paper` initialisation this is the part of the "
    "differentiation that speed adds through learning."
)


def paired_to_lowest_temperature(
    groups: dict[tuple[str, str], list[TrialMeasures]], temperatures: Sequence[float]
) -> str:
    """Per regime and temperature, the seed-paired difference of (fast - slow) between that
    temperature and the lowest one. Trials of one seed share their start and, with the `paper`
    initialisation, their initial Q noise; at the lowest temperature choices are greedy on that
    noise, blind to speed, so with the `paper` initialisation the paired difference is the part of
    the differentiation that speed (through learning) adds."""
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


def plot(rows: list[dict[str, Any]], temperatures: Sequence[float], out: Path) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for regime in dict.fromkeys(r["regime"] for r in rows):
        pts = [r for r in rows if r["regime"] == regime and r["condition"].startswith("softmax_T")]
        temps = [float(r["condition"][len("softmax_T") :].replace("p", ".")) for r in pts]
        for ax, key in ((axes[0], "fast_minus_slow"), (axes[1], "ratio_to_random")):
            lo_key = "fast_minus_slow_lo" if key == "fast_minus_slow" else "ratio_lo"
            hi_key = "fast_minus_slow_hi" if key == "fast_minus_slow" else "ratio_hi"
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
    fig.savefig(out / "differentiation.png", dpi=120)
    plt.close(fig)
    return "differentiation.png"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--regimes", default=",".join(REGIMES), help=f"subset of {list(REGIMES)}")
    ap.add_argument("--temperatures", default=",".join(str(t) for t in DEFAULT_TEMPERATURES))
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--convergence-h", type=float, default=15.0)
    ap.add_argument("--measured-h", type=float, default=5.0)
    ap.add_argument("--init", default="scaled", choices=["scaled", "paper"])
    ap.add_argument("--seed", type=int, default=0)
    add_sweep_options(ap)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument(
        "--quick", action="store_true", help="2 trials of 0.3 + 0.2 h, two temperatures"
    )
    args = ap.parse_args(argv)
    args.regimes = [r.strip() for r in args.regimes.split(",") if r.strip()]
    unknown = [r for r in args.regimes if r not in REGIMES]
    if unknown:
        ap.error(f"--regimes {unknown} unknown; allowed: {list(REGIMES)}")
    try:
        args.temperatures = [float(t) for t in args.temperatures.split(",") if t.strip()]
    except ValueError:
        ap.error(
            f"--temperatures {args.temperatures!r} is invalid; allowed: numbers, comma-separated"
        )
    if any(not (t > 0 and math.isfinite(t)) for t in args.temperatures):
        ap.error(f"--temperatures {args.temperatures} invalid; allowed: finite numbers > 0")
    if args.quick:
        args.trials, args.convergence_h, args.measured_h = 2, 0.3, 0.2
        args.temperatures = args.temperatures[:2]
    if args.trials < 1:
        ap.error(f"--trials {args.trials} is invalid; allowed: an integer >= 1")
    out = args.out or RESULTS_DIR / ("differentiation_quick" if args.quick else "differentiation")
    out.mkdir(parents=True, exist_ok=True)

    specs = specs_for(args)
    print(f"{len(specs)} trials; results in {out}", flush=True)
    results, meta = run_trials(
        specs,
        out / "trials",
        args.workers,
        {
            "regimes": args.regimes,
            "temperatures": args.temperatures,
            "trials": args.trials,
            "convergence_h": args.convergence_h,
            "measured_h": args.measured_h,
            "init": args.init,
            "seed": args.seed,
        },
        backend=args.backend,
    )
    wall = meta["wall_time_s"]
    groups: dict[tuple[str, str], list[TrialMeasures]] = {}
    for spec in specs:
        regime, name, _ = spec.key.split("__")
        groups.setdefault((regime, name), []).append(measure(results[spec.key]))
    rows, table = summarise(groups)
    body = (
        f"Softmax TAVC at several temperatures, epsilon-greedy TAVC and random allocation on "
        f"`dahl2004` in each regime; {args.trials} trials each, {args.convergence_h:g} h "
        f"convergence + {args.measured_h:g} h measured; Q-table initialisation `{args.init}`. "
        "Regimes: "
        + "; ".join(f"`{k}` = {REGIMES[k] or 'defaults'}" for k in args.regimes)
        + ".\n\n"
        + table
        + "\n\n"
        + paired_to_lowest_temperature(groups, args.temperatures)
    )
    write_results(out, "differentiation", rows, body, meta, "Where differentiation comes from")
    figure = plot(rows, args.temperatures, out) if have_matplotlib() else None
    print()
    print(table)
    print(
        f"wall time {wall:.0f} s; wrote {out / 'differentiation.md'}"
        + (f", {figure}" if figure else "")
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
