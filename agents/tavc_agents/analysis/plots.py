"""Plots from saved results, no rerun needed: allocation timelines, Q-value trajectories, deep
learners' learning curves, the interference curve and differentiation against crowding elasticity. matplotlib is an optional extra (`pip install 'tavc-env[plot]'`), imported
only when a plot is drawn.

    from tavc_agents.analysis.plots import allocation_timeline
    allocation_timeline({"softmax": TrialResult.load("trial.json")}, "timeline.png")
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tavc_agents.experiments.files import REPORT_MAX_BYTES, read_csv, read_text
from tavc_agents.experiments.runner import TrialResult
from tavc_env import metrics
from tavc_env.validation import require

CIRCUIT_COLOURS = ["tab:red", "tab:blue", "tab:green", "tab:purple", "tab:orange"]
CLASS_COLOURS = {"fast": "tab:red", "medium": "tab:green", "slow": "tab:blue"}


def subplots(nrows: int = 1, ncols: int = 1, **kwargs: Any) -> tuple[Any, Any]:
    """A figure and its axes as `pyplot.subplots` makes them, but without pyplot: no global state
    to leak, and the caller's backend (a notebook's, say) is left alone. `figsize` goes to the
    figure, everything else to `Figure.subplots`. Saved figures are drawn by matplotlib's Agg
    canvas, whatever backend is selected."""
    try:
        from matplotlib.figure import Figure
    except ImportError as error:
        raise ImportError("plots need matplotlib: pip install 'tavc-env[plot]'") from error
    fig = Figure(figsize=kwargs.pop("figsize", None))
    return fig, fig.subplots(nrows, ncols, **kwargs)


def allocation_timeline(
    trials: Mapping[str, TrialResult],
    path: str | Path,
    from_h: float | None = None,
    to_h: float | None = None,
) -> None:
    """Which circuit each robot served over time, one panel per trial (titled with its label);
    broken periods dark, recorded events (breakdown, repair, value change) dashed."""
    from matplotlib.patches import Rectangle

    fig, axes = subplots(len(trials), 1, figsize=(11, 1.4 + 1.1 * len(trials)), sharex=True)
    n_circuits = 1
    for ax, (label, r) in zip(np.atleast_1d(axes), trials.items()):
        t0 = 0.0 if from_h is None else from_h * 3600.0
        t1 = r.end_s if to_h is None else min(to_h * 3600.0, r.end_s)
        if t1 <= t0:
            raise ValueError(f"time window [{t0 / 3600:g}, {t1 / 3600:g}] h is empty for {label!r}")
        durations, states = metrics.allocation_segments(r.initial_circuits, r.changes, t0, t1)
        starts = (t0 + np.concatenate([[0.0], np.cumsum(durations)[:-1]])) / 3600.0
        n_circuits = max(n_circuits, len(r.values))
        for robot in range(states.shape[1]):
            for circuit in range(len(r.values)):
                bars = [
                    (s, d / 3600.0)
                    for s, d, c in zip(starts, durations, states[:, robot])
                    if c == circuit
                ]
                colour = CIRCUIT_COLOURS[circuit % len(CIRCUIT_COLOURS)]
                ax.broken_barh(bars, (robot - 0.4, 0.8), color=colour, lw=0)
        down: dict[int, float] = {}
        for t, kind, arg in r.events:
            if kind == "break_down":
                down[int(arg)] = t
            elif kind == "repair" and int(arg) in down:
                start = down.pop(int(arg))
                ax.broken_barh([(start / 3600, (t - start) / 3600)], (arg - 0.4, 0.8), color="0.2")
            ax.axvline(t / 3600.0, color="k", lw=0.8, ls="--")
        for robot, start in down.items():  # never repaired
            ax.broken_barh([(start / 3600, (t1 - start) / 3600)], (robot - 0.4, 0.8), color="0.2")
        ax.set_yticks(
            range(states.shape[1]),
            [f"{i} {c}" for i, c in enumerate(r.speed_classes)],
            fontsize=7,
        )
        ax.set_ylabel("robot", fontsize=8)  # the rows are robots; the trial names the panel
        ax.set_title(label, loc="left", fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("simulated hours (dashed: recorded events)")
    handles = [
        Rectangle((0, 0), 1, 1, color=CIRCUIT_COLOURS[c % len(CIRCUIT_COLOURS)])
        for c in range(n_circuits)
    ]
    handles.append(Rectangle((0, 0), 1, 1, color="0.2"))
    labels = [f"circuit {c}" for c in range(n_circuits)] + ["broken"]
    fig.legend(handles, labels, loc="upper center", ncol=n_circuits + 1, fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(path, dpi=120)


def count_ticks(axis: Any) -> None:
    """Ticks for a count of steps or decisions: 50k, 100k, ... (200,000 in full would run the
    labels into each other)."""
    from matplotlib.ticker import EngFormatter, MaxNLocator

    axis.set_major_locator(MaxNLocator(nbins=5, integer=True))
    axis.set_major_formatter(EngFormatter(sep=""))


def learning_curve(rows: Sequence[Mapping[str, Any]], title: str, path: str | Path) -> None:
    """A deep learner's learning curve (`tavc_agents.learning_runs.curve_rows`, or the rows of a
    saved `curve.csv`): the greedy network's value rate, and the time each speed class spends on
    the high-value circuit, at each checkpoint (all evaluated on one trial, its `seed`)."""
    fig, (ax1, ax2) = subplots(1, 2, figsize=(10, 3.6))  # names the plot extra if it is missing
    steps = [int(r["step"]) for r in rows]
    ax1.plot(steps, [float(r["performance"]) for r in rows], marker="o")
    ax1.set_ylabel("value / robot / 10 s (greedy)")
    ax1.set_ylim(bottom=0)
    ax2.plot(steps, [float(r["fast_share"]) for r in rows], marker="o", label="fast robots")
    ax2.plot(steps, [float(r["slow_share"]) for r in rows], marker="s", label="slow robots")
    ax2.set_ylabel("time on the high-value circuit")
    ax2.set_ylim(0, 1)
    ax2.set_title(f"the checkpoints' evaluation trial (seed {rows[0]['seed']})", fontsize=9)
    ax2.legend()
    for ax in (ax1, ax2):
        ax.set_xlabel("env steps of training")
        count_ticks(ax.xaxis)
    fig.suptitle(f"{title}: greedy evaluations during training")
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")


def redraw_learning_curve(folder: Path, path: str | Path) -> None:
    """Draw the learning curve of the run that `tavc_agents.learning_runs.write_learning_run`
    wrote into `folder`, from its `curve.csv` (titled with its report's heading), without
    training anything: needs only the plot extra."""
    rows = list(read_csv(folder / "curve.csv"))
    heading = read_text(folder / "evaluation.md", REPORT_MAX_BYTES, "report").partition("\n")[0]
    require(
        heading.startswith("# ") and bool(rows),
        "learning run folder",
        str(folder),
        "a folder with curve.csv and evaluation.md written by a learning run",
    )
    learning_curve(rows, heading[2:].strip(), path)


def q_gaps(result: TrialResult) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Snapshot times (h) and, per agent, the learned preference for the high-value circuit over
    time: the mean over states of Q(s, high) - max over the other circuits of Q(s, other)."""
    high = int(np.argmax(result.values))
    times = np.array([snap["time_s"] / 3600.0 for snap in result.q_snapshots])
    gaps: dict[str, list[float]] = {}
    for snap in result.q_snapshots:
        for agent, table in snap["q"].items():
            q = np.asarray(table)
            others = [c for c in range(q.shape[1]) if c != high]
            gaps.setdefault(agent, []).append(float(np.mean(q[:, high] - q[:, others].max(axis=1))))
    return times, {a: np.asarray(g) for a, g in gaps.items()}


def q_trajectories(result: TrialResult, path: str | Path) -> None:
    """Each learner's preference for the high-value circuit over the trial (thin lines), and the
    mean of each speed class (thick)."""
    if not result.q_snapshots:
        raise ValueError(
            f"trial {result.label or result.seed!r} has no Q snapshots; allowed: a trial of "
            "learning robots (softmax_tavc, epsilon_tavc)"
        )
    times, gaps = q_gaps(result)
    fig, ax = subplots(figsize=(9, 4.5))
    by_class: dict[str, list[np.ndarray]] = {}
    for i, agent in enumerate(result.agents):
        if agent not in gaps:
            continue
        cls = result.speed_classes[i]
        colour = CLASS_COLOURS.get(cls, "tab:gray")
        ax.plot(times, gaps[agent], color=colour, lw=0.7, alpha=0.5)
        by_class.setdefault(cls, []).append(gaps[agent])
    for cls, series in by_class.items():
        colour = CLASS_COLOURS.get(cls, "tab:gray")
        ax.plot(times, np.mean(series, axis=0), color=colour, lw=2.5, label=f"{cls} (mean)")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.axvline(result.convergence_s / 3600.0, color="grey", ls="--", lw=0.8)
    ax.set_xlabel("simulated hours (dashed: end of convergence)")
    ax.set_ylabel("Q(high) - Q(other), mean over states")
    ax.set_title(f"Learned preference for the high-value circuit ({result.label or 'trial'})")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def interference_curve(summary_csv: str | Path, path: str | Path) -> None:
    """t(n) per circuit with 95 % intervals, from `interference.csv` (benchmarks/interference.py)."""
    rows = [
        r
        for r in read_csv(summary_csv)
        if r.get("section") == "t_n" and r.get("quantity") == "mean task time (s)"
    ]
    if not rows:
        raise ValueError(
            f"{summary_csv} has no t(n) rows; allowed: the interference.csv written by "
            "benchmarks/interference.py"
        )
    fig, ax = subplots(figsize=(6.5, 4.5))
    for c in sorted({int(r["circuit"]) for r in rows}):
        mine = sorted(
            (r for r in rows if int(r["circuit"]) == c), key=lambda r: int(r["n_on_circuit"])
        )
        n = np.array([int(r["n_on_circuit"]) for r in mine]) + (c - 0.5) * 0.08
        mean = np.array([float(r["mean"]) for r in mine])
        low = np.array([_float(r["ci95_low"], m) for r, m in zip(mine, mean)])
        high = np.array([_float(r["ci95_high"], m) for r, m in zip(mine, mean)])
        colour = CIRCUIT_COLOURS[c % len(CIRCUIT_COLOURS)]
        ax.errorbar(
            n,
            mean,
            yerr=[mean - low, high - mean],
            marker="o",
            capsize=4,
            color=colour,
            label=f"circuit {c}",
        )
    ax.set_xlabel("robots on the circuit, n")
    ax.set_ylabel("mean task time t(n) (s)")
    ax.set_title("Interference curve, 95 % CI over seeds")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def _float(text: str, default: float) -> float:
    try:
        value = float(text)
    except ValueError:
        return default
    return value if math.isfinite(value) else default
