"""Interference, from runs with fixed allocations (`tavc_env.measurement.run_fixed`):
each run's mean task time per group of robots, the curve t(n) of task time against the robots on
a circuit with its ratios t(n+1)/t(n), the cost of a circuit switch, the cross-interference
matrices of fast and slow robots, and the figure of them.

Runs of six robots on two circuits; one value per run (seed) and quantity, summarised over seeds
with `tavc_agents.analysis.stats`. A summary row is a dict: section, quantity, what it is about
(preset, circuit, robots on it, class), then mean, ci95_low, ci95_high, n_seeds.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.stats import bootstrap_ratio_ci, mean_ci, mean_sd, ratio_ci
from tavc_agents.experiments.files import read_csv
from tavc_env.measurement import FixedRun, Mode

Row = dict[str, Any]
Stats = tuple[float, float, float, int]
Matrix = dict[tuple[int, int], Stats]
"""(fast, slow robots on the circuit) -> the statistics of a quantity"""

ROBOTS = 6
RUN_FIELDS = [
    "experiment",
    "preset",
    "label",
    "seed",
    "circuit",
    "robot_class",
    "task_kind",
    "n_on_circuit",
    "n_fast_on_circuit",
    "n_slow_on_circuit",
    "n_tasks",
    "mean_task_time_s",
    "sd_task_time_s",
    "queued_s_per_task",
    "travel_s_per_task",
    "run_wall_s",
]
"""The columns of a run's group rows (`group_rows`)."""


# -- the labels of runs -------------------------------------------------------------------------
def t_n_label(on_first: int) -> str:
    """An allocation of `on_first` robots on circuit 0, the rest on circuit 1."""
    return f"{on_first}+{ROBOTS - on_first}"


def switch_label(others_first: int) -> str:
    """The five robots besides the switcher: `others_first` on circuit 0, the rest on 1."""
    return f"others {others_first}+{ROBOTS - 1 - others_first}"


def cross_label(fast: int, slow: int) -> str:
    """`fast` fast and `slow` slow robots on circuit 0, the rest on circuit 1."""
    return f"{fast}:{slow}"


# -- one run ------------------------------------------------------------------------------------
def _groups(run: FixedRun) -> dict[tuple[int, str, str], list[float]]:
    """Task times by (circuit, class, kind); the switcher is its own class, the others count
    also in class "all"."""
    groups: dict[tuple[int, str, str], list[float]] = defaultdict(list)
    for task in run.tasks:
        c, t, kind = task.circuit, task.task_time_s, task.kind
        if task.robot == run.allocation.switcher:
            groups[(c, "switcher", kind)].append(t)
        else:
            groups[(c, task.robot_class, kind)].append(t)
            groups[(c, "all", kind)].append(t)
    return groups


def _time_shares(run: FixedRun, members: list[int], mean_task_s: float) -> Row:
    """Seconds per task spent queued and travelling: each mode's share of the members' ticks
    times their mean task time (nothing if they have no ticks)."""
    ticks = run.mode_ticks[members].sum(axis=0)
    if ticks.sum() <= 0:
        return {}
    frac = ticks / ticks.sum()
    return {
        "queued_s_per_task": float(frac[Mode.QUEUED] * mean_task_s),
        "travel_s_per_task": float(frac[Mode.TRAVEL] * mean_task_s),
    }


def group_rows(run: FixedRun, experiment: str, label: str) -> list[Row]:
    """One row per (circuit, class, kind) group of the run's counted tasks: how many robots were
    on the circuit (the switcher included), the task count, mean and sd of the task time, and for
    own tasks of a run without a switcher the seconds per task queued and travelling."""
    alloc = run.allocation
    rows = []
    for (c, cls, kind), times in sorted(_groups(run).items()):
        on_c = [i for i, ci in enumerate(alloc.circuit_of) if ci == c and i != alloc.switcher]
        mean, sd = mean_sd(times)
        row: Row = {
            "experiment": experiment,
            "preset": alloc.preset,
            "label": label,
            "seed": alloc.seed,
            "circuit": c,
            "robot_class": cls,
            "task_kind": kind,
            "n_on_circuit": len(on_c) + (1 if alloc.switcher >= 0 else 0),
            "n_fast_on_circuit": sum(1 for i in on_c if run.classes[i] == "fast"),
            "n_slow_on_circuit": sum(1 for i in on_c if run.classes[i] == "slow"),
            "n_tasks": len(times),
            "mean_task_time_s": mean,
            "sd_task_time_s": sd,
            "run_wall_s": round(run.wall_s, 2),
        }
        if alloc.switcher < 0 and kind == "own":
            members = [i for i in on_c if cls == "all" or run.classes[i] == cls]
            row.update(_time_shares(run, members, mean))
        rows.append(row)
    return rows


_INT_FIELDS = (
    "seed",
    "circuit",
    "n_on_circuit",
    "n_fast_on_circuit",
    "n_slow_on_circuit",
    "n_tasks",
)


def read_group_rows(path: Path) -> list[Row]:
    """The group rows saved in a runs CSV (`interference_runs.csv`), typed as `group_rows` made
    them: counts as int, times as float, and an empty cell (no time shares) left out."""
    rows = []
    reader = read_csv(path)
    if reader.fieldnames != RUN_FIELDS:
        raise ValueError(f"{path} has columns {reader.fieldnames}; allowed: {RUN_FIELDS}")
    for raw in reader:
        row: Row = {}
        for key, text in raw.items():
            if text == "":
                continue
            if key in _INT_FIELDS:
                row[key] = int(text)
            elif key.endswith("_s") or key.endswith("_s_per_task"):
                row[key] = float(text)
            else:
                row[key] = text
        rows.append(row)
    return rows


# -- over seeds ---------------------------------------------------------------------------------
def per_seed(rows: Sequence[Row], **match: Any) -> dict[int, Row]:
    """The rows with every field in `match`, by seed (one per seed)."""
    out: dict[int, Row] = {}
    for r in rows:
        if all(r[k] == v for k, v in match.items()):
            if r["seed"] in out:
                raise ValueError(f"two rows of seed {r['seed']} match {match}")
            out[r["seed"]] = r
    return out


def summary_row(section: str, quantity: str, stats: Stats, **about: Any) -> Row:
    m, lo, hi, n = stats
    return {
        "section": section,
        "quantity": quantity,
        **about,
        "mean": m,
        "ci95_low": lo,
        "ci95_high": hi,
        "n_seeds": n,
    }


def _t_n_rows(
    rows: Sequence[Row], seeds: Sequence[int], preset: str, c: int, n: int
) -> tuple[list[Row], list[float]]:
    """Summary rows of t(n), the time queued per task and n/t(n) on circuit `c`, and the per-seed
    t(n)."""
    sel = per_seed(
        rows, experiment="t_n", circuit=c, n_on_circuit=n, robot_class="all", task_kind="own"
    )
    vals = [sel[s]["mean_task_time_s"] for s in seeds if s in sel]
    queued = [sel[s].get("queued_s_per_task", math.nan) for s in seeds if s in sel]
    about = {"preset": preset, "circuit": c, "n_on_circuit": n, "robot_class": "medium"}
    n_tasks = sum(sel[s]["n_tasks"] for s in sel)
    out = [
        summary_row("t_n", "mean task time (s)", mean_ci(vals), **about, n_tasks=n_tasks),
        summary_row("t_n", "time queued per task (s)", mean_ci(queued), **about),
        # circuit throughput c(n) = n / t(n) (tasks per hour), the TAVC model's c_{i,J}
        summary_row(
            "t_n",
            "circuit throughput n/t(n) (tasks/h)",
            mean_ci([3600.0 * n / v for v in vals]),
            **about,
        ),
    ]
    return out, vals


def t_n_curve(
    rows: Sequence[Row], seeds: Sequence[int], preset: str, boot_rng: np.random.Generator
) -> tuple[list[Row], dict[int, dict[int, list[float]]]]:
    """Summary rows of t(n), the time queued per task and n/t(n) for n = 1..6 robots on each
    circuit, and of t(n+1)/t(n) (delta-method interval, and a bootstrap over seeds drawn from
    `boot_rng`); and the per-seed t(n) values by circuit and n."""
    out: list[Row] = []
    tn: dict[int, dict[int, list[float]]] = {0: {}, 1: {}}
    for c in (0, 1):
        for n in range(1, ROBOTS + 1):
            rows_n, tn[c][n] = _t_n_rows(rows, seeds, preset, c, n)
            out += rows_n
        for n in range(1, ROBOTS):
            r, lo, hi = ratio_ci(tn[c][n + 1], tn[c][n])
            blo, bhi = bootstrap_ratio_ci(tn[c][n + 1], tn[c][n], boot_rng)
            stats = (r, lo, hi, min(len(tn[c][n + 1]), len(tn[c][n])))
            about = {"preset": preset, "circuit": c, "n_on_circuit": n + 1}
            row = summary_row("t_ratio", f"t({n + 1})/t({n})", stats, **about)
            row.update(robot_class="medium", bootstrap_low=blo, bootstrap_high=bhi)
            out.append(row)
    return out, tn


class SwitchCase(NamedTuple):
    """The switcher's tasks into `circuit` in the runs of `experiment` labelled `label`, with
    `n_on_circuit` robots on that circuit (the switcher included)."""

    experiment: str
    label: str
    circuit: int
    n_on_circuit: int

    @property
    def name(self) -> str:
        return f"{self.label} into c{self.circuit}"


def switch_cost(
    rows: Sequence[Row], seeds: Sequence[int], preset: str, case: SwitchCase
) -> tuple[list[Row], dict[str, Any]]:
    """Summary rows of the switcher's own-circuit and switch task times into `case.circuit`, the
    extra time of a switch task (paired within each run) and that relative to the own-task mean;
    and the same as a dict (with the per-seed relative values and the task counts)."""
    match = {
        "experiment": case.experiment,
        "label": case.label,
        "circuit": case.circuit,
        "robot_class": "switcher",
    }
    sw = per_seed(rows, task_kind="switch", **match)
    own = per_seed(rows, task_kind="own", **match)
    both = [s for s in seeds if s in sw and s in own]
    t_sw = [sw[s]["mean_task_time_s"] for s in both]
    t_own = [own[s]["mean_task_time_s"] for s in both]
    extra = [a - b for a, b in zip(t_sw, t_own)]
    rel = [(a - b) / b for a, b in zip(t_sw, t_own)]
    about = {
        "preset": preset,
        "circuit": case.circuit,
        "n_on_circuit": case.n_on_circuit,
        "robot_class": "switcher",
    }
    out = [
        summary_row("switch", f"{case.name}: own-circuit task time (s)", mean_ci(t_own), **about),
        summary_row("switch", f"{case.name}: switch task time (s)", mean_ci(t_sw), **about),
        summary_row("switch", f"{case.name}: extra time (s)", mean_ci(extra), **about),
        summary_row("switch", f"{case.name}: relative extra", mean_ci(rel), **about),
    ]
    info = {
        "label": case.label,
        "circuit": case.circuit,
        "n_on_circuit": case.n_on_circuit,
        **dict(zip(("own", "switch", "extra", "relative"), out)),
        "rel_values": rel,
        "n_switch_tasks": sum(sw[s]["n_tasks"] for s in both),
        "n_own_tasks": sum(own[s]["n_tasks"] for s in both),
    }
    return out, info


def cross_cell(rows: Sequence[Row], fast: int, slow: int, circuit: int, cls: str) -> dict[int, Row]:
    """By seed, the row of the own-circuit tasks of class `cls` on `circuit` in the "cross" run
    with `fast` fast and `slow` slow robots on circuit 0 (the rest on circuit 1)."""
    return per_seed(
        rows,
        experiment="cross",
        label=cross_label(fast, slow),
        circuit=circuit,
        robot_class=cls,
        task_kind="own",
    )


def cross_matrices(
    rows: Sequence[Row], seeds: Sequence[int], preset: str
) -> tuple[list[Row], dict[tuple[int, str], Matrix], dict[tuple[int, str], Matrix]]:
    """From the "cross" runs (f fast, s slow robots on circuit 0, the rest on circuit 1): summary
    rows, and by (circuit, class) the matrices of the mean task time and of the time queued per
    task, indexed by the fast and slow robots on that circuit."""
    out: list[Row] = []
    times: dict[tuple[int, str], Matrix] = {}
    queued: dict[tuple[int, str], Matrix] = {}
    for c in (0, 1):
        for cls in ("fast", "slow", "all"):
            times[(c, cls)], queued[(c, cls)] = {}, {}
            for f in range(4):
                for s in range(4):
                    nf, ns = (f, s) if c == 0 else (3 - f, 3 - s)
                    sel = cross_cell(rows, f, s, c, cls)
                    vals = [sel[k]["mean_task_time_s"] for k in seeds if k in sel]
                    t = times[(c, cls)][(nf, ns)] = mean_ci(vals)
                    q = queued[(c, cls)][(nf, ns)] = mean_ci(
                        [sel[k].get("queued_s_per_task", math.nan) for k in seeds if k in sel]
                    )
                    if not vals:
                        continue
                    about = {
                        "preset": preset,
                        "circuit": c,
                        "n_on_circuit": nf + ns,
                        "n_fast_on_circuit": nf,
                        "n_slow_on_circuit": ns,
                        "robot_class": cls,
                    }
                    n_tasks = sum(sel[k]["n_tasks"] for k in sel)
                    out.append(summary_row("cross", "time queued per task (s)", q, **about))
                    out.append(
                        summary_row("cross", "mean task time (s)", t, **about, n_tasks=n_tasks)
                    )
    return out, times, queued


# -- figure -------------------------------------------------------------------------------------
def _errorbars(rows: Sequence[Row], c: int) -> tuple[list[float], ...]:
    xs, ms, lo, hi = [], [], [], []
    for r in rows:
        xs.append(r["n_on_circuit"] + (c - 0.5) * 0.08)
        ms.append(r["mean"])
        lo.append(r["mean"] - r["ci95_low"] if math.isfinite(r["ci95_low"]) else 0)
        hi.append(r["ci95_high"] - r["mean"] if math.isfinite(r["ci95_high"]) else 0)
    return xs, ms, lo, hi


def _curve_panel(ax: Any, summary_rows: Sequence[Row], section: str, quantity: str | None) -> None:
    for c, color in ((0, "tab:red"), (1, "tab:blue")):
        mine = [
            r
            for r in summary_rows
            if r["section"] == section
            and r["circuit"] == c
            and (quantity is None or r["quantity"] == quantity)
        ]
        xs, ms, lo, hi = _errorbars(mine, c)
        marker = "o" if section == "t_n" else "s"
        ax.errorbar(
            xs, ms, yerr=[lo, hi], marker=marker, capsize=4, color=color, label=f"circuit {c}"
        )
    ax.grid(alpha=0.3)


def _matrix_panel(
    ax: Any, fig: Any, mat: Matrix, cls: str, vmin: float, vmax: float, preset: str
) -> None:
    grid = np.full((4, 4), np.nan)
    for (f, s), stats in mat.items():
        grid[f, s] = stats[0]
    im = ax.imshow(grid, origin="lower", cmap="viridis", vmin=vmin, vmax=vmax)
    for f in range(4):
        for s in range(4):
            st = mat.get((f, s))
            if st and math.isfinite(st[0]):
                half = (st[2] - st[0]) if math.isfinite(st[2]) else math.nan
                txt = f"{st[0]:.1f}" + (f"\n±{half:.1f}" if math.isfinite(half) else "")
                ax.text(s, f, txt, ha="center", va="center", color="w", fontsize=9)
    ax.set_xticks(range(4))
    ax.set_yticks(range(4))
    ax.set_xlabel("slow robots on circuit 0, s")
    ax.set_ylabel("fast robots on circuit 0, f")
    ax.set_title(f"{cls.capitalize()} robot's task time on circuit 0 (s)\n{preset}")
    fig.colorbar(im, ax=ax, shrink=0.8, label="mean task time (s)")


def plot_interference(
    path: Path,
    summary_rows: Sequence[Row],
    cross: dict[tuple[int, str], Matrix],
    ratio_line: float,
    preset: str = "dahl2004",
    homog: str = "dahl2004_homogeneous",
) -> None:
    """Four panels: t(n) and t(n)/t(n-1) per circuit with 95 % intervals (a dashed line at
    `ratio_line`), and a fast and a slow robot's task time on circuit 0 against the fast and slow
    robots there (matplotlib needed). `preset` and `homog` name the arenas in the titles."""

    fig, axes = subplots(2, 2, figsize=(12, 9.5))
    ax = axes[0, 0]
    _curve_panel(ax, summary_rows, "t_n", "mean task time (s)")
    ax.set_xlabel("robots on the circuit, n")
    ax.set_ylabel("mean task time t(n) (s)")
    ax.set_ylim(bottom=0)  # zero-based: heights compare as ratios
    ax.set_title(f"Interference curve, 95% CI over seeds\n{homog}")
    ax.legend()
    ax = axes[0, 1]
    _curve_panel(ax, summary_rows, "t_ratio", None)
    ax.axhline(ratio_line, color="k", ls="--", lw=1, label=f"{ratio_line} (t(4)/t(3) req.)")
    # A ratio's natural baseline is 1 (no slow-down), drawn and labelled rather than 0.
    ax.axhline(1.0, color="gray", lw=0.8, label="1: no slow-down")
    ax.set_xlabel("n")
    ax.set_ylabel("t(n) / t(n-1)")
    ax.set_title("Marginal slow-down, 95% CI (log delta method)")
    ax.legend()
    means = [st[0] for cls in ("fast", "slow") for st in cross[(0, cls)].values()]
    vmin, vmax = float(np.nanmin(means)), float(np.nanmax(means))
    for ax, cls in ((axes[1, 0], "fast"), (axes[1, 1], "slow")):
        _matrix_panel(ax, fig, cross[(0, cls)], cls, vmin, vmax, preset)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
