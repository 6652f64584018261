"""What several studies share of the analysis of fixed-allocation runs, beside them (the studies
import this module, `arena_runs` and the package, never each other):

- interference: task time against crowding, the cost of a switch and the cross-interference of
  fast and slow robots, from the runs' group rows;
- elasticity: the crowding elasticity e of an arena and the cross runs that measure it;
- synthetic twin tables of a chosen crowding elasticity (the twin curve's arenas).

Interference, from runs with fixed allocations (`tavc_env.measurement.run_fixed`):
each run's mean task time per group of robots, the curve t(n) of task time against the robots on
a circuit with its ratios t(n+1)/t(n), the cost of a circuit switch, the cross-interference
matrices of fast and slow robots, and the figure of them.

Runs of six robots on two circuits; one value per run (seed) and quantity, summarised over seeds
with `tavc_agents.analysis.stats`. A summary row is a dict: section, quantity, what it is about
(preset, circuit, robots on it, class), then mean, ci95_low, ci95_high, n_seeds.

Elasticity of the arena: how crowding's cost splits between fast and slow robots.

With fixed allocations, T_c(f, s) is the mean task time of a robot of class c (fast 0.30 m/s, slow
0.20 m/s) when f fast and s slow robots serve the same circuit (circuit 0 of the interference
study's "cross" runs; `cross_allocation` below makes them for any arena). Then

    e = mean_{f,s in 1..3} ln(T_fast(f, s) / T_fast(1, 0))
        / mean_{f,s in 1..3} ln(T_slow(f, s) / T_slow(0, 1))

e = 1: crowding costs every robot the same fraction of its time (pure multiplicative crowding);
e > 1: fast robots lose more (an additive wait is a larger share of a shorter task); e < 1: slow
robots lose more. The means run over the nine cells where both classes share the circuit; each
class is compared with itself alone on it.

Beside e, the pace in company

    rho = T_slow(1, 1) / T_fast(1, 1)

says whether a fast robot keeps its speed advantage when it shares the circuit with one slow robot:
rho = 1 means it is held to the slow robot's pace (behind it at a one-robot dock, or braking
behind it on a leg it cannot pass on), and rho = T_slow(0, 1) / T_fast(1, 0), the ratio alone, is
its ceiling. Its interval is the same seed bootstrap, drawn after e's.

Over seeds: the point estimate is e of the tables averaged cell by cell over seeds; its interval
is a percentile bootstrap that resamples whole seeds (each seed's runs together) and recomputes
that estimate (`scipy.stats.bootstrap`, method "percentile"). With few seeds the bootstrap cannot
see beyond the observed spread and its interval is too narrow. Everything here is a pure
function of its arguments (the random draws come from the Generator passed in).

The runs: each cell's run is the interference study's cross-interference run, made for any
`ArenaConfig`: its arena (geometry, stations, physics) with the team replaced by `PER_CLASS` fast
robots (0-2) and `PER_CLASS` slow ones (3-5), scheduled breakdowns removed. With two or more
circuits, f fast and s slow robots serve circuit 0 and the rest circuit 1, as in the study (for
the dahl2004 presets the runs are the study's own); an arena of one circuit holds only the f + s
robots.

    alloc = cross_allocation(tavc_env.preset("dahl2004"), 2, 1, seed=0, hours=3.0,
                             warmup_s=600.0, skip_first=2)
    run_fixed(alloc)  # tavc_env.measurement

Synthetic interference tables with a chosen crowding elasticity e, for the model twin.

A family of arenas for the paper's team (3 fast robots at 0.30 m/s, 3 slow at 0.20 m/s, two
circuits alike but for their values): a robot of class c with f fast and s slow robots on its
circuit (n = f + s, itself included) takes on average

    T_c(f, s) = H + b_c(f, s) k(n) + W (k(n) - 1),    k(n) = 1 + step * max(0, n - 3)

* b_c: the robot's free task time, 60 s fast and 90 s slow (the speed ratio 0.30 / 0.20);
* k(n): crowding. A circuit carries three robots without interference (a station that serves
  three at once); each robot beyond the third stretches every robot's travel by `step` (0.5) of
  its free time. t(4) / t(3) = 1.5 with H = W = 0: the knee that makes 3 + 3 the homogeneous
  equilibrium of circuits worth 2200 and 2000;
* H: a fixed handling time every robot spends alike, untouched by crowding. It dilutes the
  crowding of the slow robots (whose longer travel is stretched more) less than the fast ones':
  e < 1, down to b_fast / b_slow = 2/3 as H grows;
* W: an additive wait, the same for every robot, that grows with the crowd. It is a larger
  share of a shorter task: e > 1, but only to about 1.17 (with large W every task is mostly wait
  and e returns to 1);
* pace p in [0, 1]: a fast robot sharing its circuit with a slow one drives at the slow robot's
  pace for a fraction p of its travel, b_fast(f, s >= 1) = b_fast + p (b_slow - b_fast). p = 1 is
  what every physical arena of the package measured (rho = T_slow(1, 1) / T_fast(1, 1) = 1, the
  fast robot held behind the slow one), and what gives them e of 1.1 to 3.4: here e reaches 2.04.

H = W = p = 0 is pure multiplicative crowding, e = 1. Cell standard deviations are `cv` (0.1) of
the means; the switch cost (1.13) is what `dahl2004`'s switch tasks cost under random allocation
in the physics (benchmarks/results/twin_audit/twin_audit.md: 1.133 [1.129, 1.137] of their cell).

`with_elasticity(e)` solves for H (e < 1) or p (or W, `above="wait"`) by bisection on
`elasticity_of` (circuit 0's tables), and refuses an e the family cannot reach: below about 0.744
the H it needs would flatten the knee under t(4) / t(3) = 1.1 (at a homogeneous team of the mean
speed 0.25 m/s, free time 72 s), above about 2.04 even p = 1 is not enough.
"""

from __future__ import annotations

import inspect
import math
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence

# -- the runs elasticity needs ---------------------------------------------------------------------
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
from scipy import stats

import tavc_env
from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.stats import bootstrap_ratio_ci, mean_ci, mean_sd, ratio_ci
from tavc_agents.experiments.files import read_csv
from tavc_env.config import ArenaConfig, Robot, preset_overrides
from tavc_env.measurement import FixedAllocation, FixedRun, Mode, two_circuit_allocation
from tavc_env.twin import InterferenceTables, team_classes
from tavc_env.validation import is_number, require

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
    for (f, s), cell in mat.items():
        grid[f, s] = cell[0]
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


FAST = Robot(0.30, "fast")
SLOW = Robot(0.20, "slow")
PER_CLASS = 3
"""robots of each class in a run (with two or more circuits)"""
BASE_PRESET = "dahl2004"
"""the preset a run's arena is given relative to (`FixedAllocation.arena`)"""

Cell = tuple[int, int]
"""(fast, slow robots on circuit 0)"""
ALONE: dict[str, Cell] = {"fast": (1, 0), "slow": (0, 1)}
"""the cell in which a robot of the class is alone on circuit 0"""
CROWDED: tuple[Cell, ...] = tuple(
    (f, s) for f in range(1, PER_CLASS + 1) for s in range(1, PER_CLASS + 1)
)
"""the cells with both classes on circuit 0 (f, s in 1..3), over which elasticity averages"""
CELLS: tuple[Cell, ...] = (ALONE["fast"], ALONE["slow"], *CROWDED)
"""the runs elasticity needs (11 of the 16 cells f, s in 0..3)"""


def _check_cell(fast: int, slow: int) -> None:
    for name, n in (("fast", fast), ("slow", slow)):
        ok = isinstance(n, int) and not isinstance(n, bool) and 0 <= n <= PER_CLASS
        if not ok:
            raise ValueError(f"{name} = {n!r} is invalid; allowed: an integer in 0..{PER_CLASS}")
    if fast + slow == 0:
        raise ValueError("fast = slow = 0 is invalid; allowed: at least one robot on circuit 0")


def cross_circuits(fast: int, slow: int, n_circuits: int) -> tuple[int, ...]:
    """Each robot's circuit in the run of cell (fast, slow): with two or more circuits, fast robots
    0..fast-1 and slow robots 3..3+slow-1 on circuit 0, the others on circuit 1; with one circuit
    the fast + slow robots, all on it."""
    _check_cell(fast, slow)
    if n_circuits >= 2:
        return two_circuit_allocation(fast, PER_CLASS) + two_circuit_allocation(slow, PER_CLASS)
    return (0,) * (fast + slow)


def cross_arena(config: ArenaConfig, fast: int, slow: int) -> ArenaConfig:
    """`config`'s arena with the team of the run of cell (fast, slow) (see `cross_circuits`) and no
    scheduled breakdowns."""
    if not isinstance(config, ArenaConfig):
        raise ValueError(f"config = {config!r} is invalid; allowed: a tavc_env.ArenaConfig")
    _check_cell(fast, slow)
    if config.n_circuits >= 2:
        robots = (FAST,) * PER_CLASS + (SLOW,) * PER_CLASS
    else:
        robots = (FAST,) * fast + (SLOW,) * slow
    return config.replace(robots=robots, breakdowns=())


def arena_overrides(config: ArenaConfig, preset: str = BASE_PRESET) -> tuple[tuple[str, Any], ...]:
    """The fields in which `config` differs from `preset` (`tavc_env.config.preset_overrides`,
    from the study's base preset by default)."""
    return preset_overrides(config, preset)


def cross_allocation(
    config: ArenaConfig,
    fast: int,
    slow: int,
    *,
    seed: int,
    hours: float,
    warmup_s: float,
    skip_first: int,
) -> FixedAllocation:
    """The fixed-allocation run of cell (fast, slow) in `config`'s arena (see the module)."""
    arena = cross_arena(config, fast, slow)
    return FixedAllocation(
        preset=BASE_PRESET,
        circuit_of=cross_circuits(fast, slow, arena.n_circuits),
        seed=seed,
        hours=hours,
        warmup_s=warmup_s,
        skip_first=skip_first,
        arena=arena_overrides(arena),
    )


# -- elasticity from the runs ------------------------------------------------------------------

CLASSES = ("fast", "slow")


class Tables(NamedTuple):
    """T_fast(f, s) and T_slow(f, s), mean task times (s) by (fast, slow robots on the circuit)."""

    fast: Mapping[Cell, float]
    slow: Mapping[Cell, float]


@dataclass(frozen=True)
class Elasticity:
    """e with its percentile-bootstrap interval over seeds, and the two mean log-ratios it is the
    quotient of (both averaged over the cells f, s in 1..3)."""

    e: float
    low: float
    high: float
    n_seeds: int
    fast_mean_log_ratio: float
    """mean ln(T_fast(f, s) / T_fast(1, 0))"""
    slow_mean_log_ratio: float
    """mean ln(T_slow(f, s) / T_slow(0, 1))"""
    confidence: float = 0.95
    rho: float = math.nan
    """pace in company, T_slow(1, 1) / T_fast(1, 1), of the tables averaged over seeds"""
    rho_low: float = math.nan
    rho_high: float = math.nan
    rho_alone: float = math.nan
    """T_slow(0, 1) / T_fast(1, 0): rho's ceiling, the two classes' ratio alone on the circuit"""

    def text(self, digits: int = 3) -> str:
        """The text "e [low, high]" (the interval left out where there is none)."""
        return _with_interval(self.e, self.low, self.high, digits)

    def rho_text(self, digits: int = 3) -> str:
        """The text "rho [low, high]" (the interval left out where there is none)."""
        return _with_interval(self.rho, self.rho_low, self.rho_high, digits)


def _with_interval(value: float, low: float, high: float, digits: int) -> str:
    text = f"{value:.{digits}f}"
    if math.isfinite(low) and math.isfinite(high):
        return f"{text} [{low:.{digits}f}, {high:.{digits}f}]"
    return text


def seed_tables(rows: Sequence[Row], seeds: Iterable[int] | None = None) -> dict[int, Tables]:
    """Per seed, the tables T_fast and T_slow on circuit 0 from the group rows of "cross" runs
    (`tavc_agents.analysis.interference.group_rows`, experiment "cross", labelled f:s): every cell
    f, s in 0..3 in which the class is present and the rows have a value. `seeds`: those to take
    (default: every seed with a cross row). Missing cells are left out (`elasticity` names them)."""
    if seeds is None:
        seeds = sorted({r["seed"] for r in rows if r["experiment"] == "cross"})
        if not seeds:
            raise ValueError("rows has no row of a 'cross' run; allowed: the rows of cross runs")
    wanted = list(seeds)
    found: dict[tuple[int, str], dict[Cell, float]] = {
        (seed, cls): {} for seed in wanted for cls in CLASSES
    }
    for f in range(PER_CLASS + 1):
        for s in range(PER_CLASS + 1):
            for cls in CLASSES:
                if (f if cls == "fast" else s) == 0:
                    continue  # the class is not on the circuit
                sel = cross_cell(rows, f, s, 0, cls)
                for seed in wanted:
                    if seed in sel:
                        found[(seed, cls)][(f, s)] = float(sel[seed]["mean_task_time_s"])
    return {seed: Tables(found[(seed, "fast")], found[(seed, "slow")]) for seed in wanted}


def _cells(cls: str) -> tuple[Cell, ...]:
    return (ALONE[cls], *CROWDED)


def _column(tables: Tables, cls: str, where: str) -> list[float]:
    """The class's times in the cells e uses (alone first), refusing a missing cell or a time that
    is not a finite number > 0."""
    table = tables.fast if cls == "fast" else tables.slow
    values = []
    for cell in _cells(cls):
        if cell not in table:
            raise ValueError(
                f"T_{cls}{cell} is missing{where}; allowed: tables with every cell "
                f"{list(_cells(cls))}"
            )
        v = table[cell]
        ok = isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v > 0
        if not ok:
            raise ValueError(
                f"T_{cls}{cell} = {v!r}{where} is invalid; allowed: a finite task time > 0 s"
            )
        values.append(float(v))
    return values


def log_ratios(tables: Tables) -> tuple[float, float]:
    """The mean over f, s in 1..3 of ln(T_fast(f, s) / T_fast(1, 0)) and of
    ln(T_slow(f, s) / T_slow(0, 1)). A ValueError names a missing cell or a bad time."""
    fast = np.asarray(_column(tables, "fast", ""))
    slow = np.asarray(_column(tables, "slow", ""))
    return _mean_log_ratio(fast), _mean_log_ratio(slow)


def _mean_log_ratio(times: np.ndarray) -> Any:
    """Along the last axis: the cell times, the alone cell first."""
    return np.log(times[..., 1:] / times[..., :1]).mean(axis=-1)


def _quotient(num: Any, den: Any) -> Any:
    """num / den, nan where den is 0 (crowding costs the slow robots nothing: e is undefined)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den != 0, num / np.where(den != 0, den, 1.0), np.nan)


def elasticity_of(tables: Tables) -> float:
    """e of one set of tables (nan if the slow robots' mean log-ratio is 0)."""
    fast, slow = log_ratios(tables)
    return float(_quotient(fast, slow))


def _arrays(per_seed: Mapping[int, Tables] | Sequence[Tables]) -> tuple[np.ndarray, np.ndarray]:
    """(seeds, cells) arrays of the fast and slow times, checked seed by seed."""
    items = list(per_seed.items()) if isinstance(per_seed, Mapping) else list(enumerate(per_seed))
    if not items:
        raise ValueError("no seeds; allowed: the tables of one or more seeds")
    fast, slow = [], []
    for key, tables in items:
        where = f" in seed {key}" if isinstance(per_seed, Mapping) else f" in tables[{key}]"
        fast.append(_column(tables, "fast", where))
        slow.append(_column(tables, "slow", where))
    return np.asarray(fast), np.asarray(slow)


def _e_of_seeds(fast: np.ndarray, slow: np.ndarray) -> Any:
    """e of the tables averaged over seeds; arrays (..., seeds, cells)."""
    return _quotient(_mean_log_ratio(fast.mean(axis=-2)), _mean_log_ratio(slow.mean(axis=-2)))


_PAIR = 1 + CROWDED.index((1, 1))  # the column of cell (1, 1) in `_column`'s order (alone first)


def _rho_of_seeds(fast: np.ndarray, slow: np.ndarray) -> Any:
    """rho of the tables averaged over seeds; arrays (..., seeds, cells)."""
    return slow.mean(axis=-2)[..., _PAIR] / fast.mean(axis=-2)[..., _PAIR]


def _bootstrap(
    of_seeds: Callable[[np.ndarray, np.ndarray], Any],
    fast: np.ndarray,
    slow: np.ndarray,
    rng: np.random.Generator,
    confidence: float,
    n_resamples: int,
) -> tuple[float, float]:
    """Percentile bootstrap of `of_seeds` (`_e_of_seeds` or `_rho_of_seeds`), resampling seeds
    with replacement (a seed's cells stay together: the resampled objects are seed indices)."""

    def statistic(index: np.ndarray, axis: int = -1) -> Any:
        return of_seeds(fast[index], slow[index])  # index: (..., seeds)

    kwargs: dict[str, Any] = (
        {"rng": rng}
        if "rng" in inspect.signature(stats.bootstrap).parameters
        else {"random_state": rng}  # scipy < 1.15
    )
    res = stats.bootstrap(
        (np.arange(len(fast)),),
        statistic,
        n_resamples=n_resamples,
        batch=1000,
        vectorized=True,
        confidence_level=confidence,
        method="percentile",
        **kwargs,
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def elasticity(
    per_seed: Mapping[int, Tables] | Sequence[Tables],
    rng: np.random.Generator,
    confidence: float = 0.95,
    n_resamples: int = 10_000,
) -> Elasticity:
    """e over seeds (one `Tables` per seed): the point estimate from the tables averaged over
    seeds, a percentile bootstrap interval resampling seeds with draws from `rng` (nan with one
    seed). A ValueError names a missing cell or a bad time and its seed."""
    if not (isinstance(confidence, float) and 0 < confidence < 1):
        raise ValueError(f"confidence = {confidence!r} is invalid; allowed: a float in (0, 1)")
    if not (isinstance(n_resamples, int) and n_resamples >= 1):
        raise ValueError(f"n_resamples = {n_resamples!r} is invalid; allowed: an integer >= 1")
    fast, slow = _arrays(per_seed)
    n = len(fast)
    no_interval = (math.nan, math.nan)
    # e's interval first: the draws for rho come after, so e's interval does not depend on them
    low, high = (
        _bootstrap(_e_of_seeds, fast, slow, rng, confidence, n_resamples) if n >= 2 else no_interval
    )
    rho_low, rho_high = (
        _bootstrap(_rho_of_seeds, fast, slow, rng, confidence, n_resamples)
        if n >= 2
        else no_interval
    )
    return Elasticity(
        e=float(_e_of_seeds(fast, slow)),
        low=low,
        high=high,
        n_seeds=n,
        fast_mean_log_ratio=float(_mean_log_ratio(fast.mean(axis=0))),
        slow_mean_log_ratio=float(_mean_log_ratio(slow.mean(axis=0))),
        confidence=confidence,
        rho=float(_rho_of_seeds(fast, slow)),
        rho_low=rho_low,
        rho_high=rho_high,
        rho_alone=float(slow[:, 0].mean() / fast[:, 0].mean()),
    )


KNEE_MIN = 2200.0 / 2000.0
"""t(4) / t(3) above the circuits' value ratio: a fourth robot earns less on the high-value
circuit than the third on the other, so 3 + 3 is the homogeneous equilibrium"""
CAPACITY = 3
"""robots a circuit carries without interference"""
_BISECTIONS = 200
_TOLERANCE = 1e-12


@dataclass(frozen=True)
class Family:
    """One member of the family (see the module's docstring); times in seconds."""

    handling_s: float = 0.0
    """H, the fixed handling time every robot spends alike (e < 1)"""
    wait_s: float = 0.0
    """W, the additive wait equal for every robot, times k(n) - 1 (e > 1, up to about 1.17)"""
    pace: float = 0.0
    """p, the fraction of a fast robot's travel at the slow robots' pace in their company (e > 1)"""
    b_fast_s: float = 60.0
    """free task time of a fast robot"""
    b_slow_s: float = 90.0
    """free task time of a slow robot"""
    step: float = 0.5
    """k(n) = 1 + step * max(0, n - 3)"""
    cv: float = 0.1
    """every cell's standard deviation over its mean"""
    switch_cost: float = 1.13
    """factor on a task that starts on the other circuit (dahl2004's as paid, twin audit)"""

    def __post_init__(self) -> None:
        for name in ("handling_s", "wait_s", "cv"):
            value = getattr(self, name)
            require(is_number(value) and value >= 0, name, value, "a finite number >= 0")
        for name in ("b_fast_s", "b_slow_s", "step", "switch_cost"):
            value = getattr(self, name)
            require(is_number(value) and value > 0, name, value, "a finite number > 0")
        require(
            is_number(self.pace) and 0 <= self.pace <= 1, "pace", self.pace, "a number in [0, 1]"
        )
        require(
            self.b_fast_s < self.b_slow_s,
            "b_fast_s",
            self.b_fast_s,
            f"a free task time shorter than b_slow_s = {self.b_slow_s!r} (fast robots are faster)",
        )

    def k(self, n: int) -> float:
        """The crowding factor of `n` robots on a circuit."""
        return 1.0 + self.step * max(0, n - CAPACITY)

    def _time(self, free_s: float, n: int) -> float:
        k = self.k(n)
        return self.handling_s + free_s * k + self.wait_s * (k - 1.0)

    def mean_s(self, robot_class: str, fast: int, slow: int) -> float:
        """T_c(f, s): the mean task time of a `robot_class` robot with `fast` fast and `slow` slow
        robots on its circuit (itself included)."""
        require(robot_class in ("fast", "slow"), "robot_class", robot_class, "'fast' or 'slow'")
        mine = fast if robot_class == "fast" else slow
        require(
            isinstance(fast, int) and isinstance(slow, int) and mine >= 1 and min(fast, slow) >= 0,
            "counts",
            (fast, slow),
            f"robots >= 0 of each class, at least one {robot_class} robot (the robot itself)",
        )
        if robot_class == "slow":
            free = self.b_slow_s
        else:
            free = self.b_fast_s + (self.pace * (self.b_slow_s - self.b_fast_s) if slow else 0.0)
        return self._time(free, fast + slow)

    def knee(self) -> float:
        """t(4) / t(3) of a homogeneous team of the mean speed (free time the harmonic mean of
        b_fast and b_slow: 72 s for 60 and 90), as the interference study measures it at
        0.25 m/s."""
        free = 2.0 * self.b_fast_s * self.b_slow_s / (self.b_fast_s + self.b_slow_s)
        return self._time(free, 4) / self._time(free, 3)

    def elasticity_tables(self) -> Tables:
        """T_fast and T_slow on one circuit in the cells e uses."""
        cells = (ALONE["fast"], ALONE["slow"], *CROWDED)
        return Tables(
            fast={(f, s): self.mean_s("fast", f, s) for f, s in cells if f},
            slow={(f, s): self.mean_s("slow", f, s) for f, s in cells if s},
        )

    def elasticity(self) -> float:
        """e of these tables (`tavc_agents.analysis.elasticity.elasticity_of`)."""
        return elasticity_of(self.elasticity_tables())

    def describe(self) -> str:
        return (
            f"H = {self.handling_s:.4g} s, W = {self.wait_s:.4g} s, pace {self.pace:.4g}, "
            f"b = {self.b_fast_s:g} / {self.b_slow_s:g} s, k(n) = 1 + {self.step:g} "
            f"max(0, n - {CAPACITY}), cv {self.cv:g}, switch cost {self.switch_cost:g}"
        )

    def tables(self, config: ArenaConfig | None = None) -> InterferenceTables:
        """The twin's tables for `config` (default: `dahl2004`, the paper's team and circuits):
        every circuit alike, each cell's mean `mean_s` and standard deviation `cv` of it."""
        config = tavc_env.make_config("dahl2004") if config is None else config
        classes, _ = team_classes(config)
        require(
            sorted(classes) == ["fast", "slow"],
            "config",
            f"speed classes {list(classes)}",
            "an arena whose robots are of the classes 'fast' and 'slow'",
        )
        i_fast, i_slow = classes.index("fast"), classes.index("slow")

        def mean(_: int, counts: tuple[int, ...], cls: str) -> float:
            return self.mean_s(cls, counts[i_fast], counts[i_slow])

        return InterferenceTables.from_function(
            config,
            mean,
            lambda k, counts, cls: self.cv * mean(k, counts, cls),
            self.switch_cost,
            source=f"synthetic, e = {self.elasticity():.4f}: {self.describe()}",
        )


def max_handling_s(base: Family) -> float:
    """The largest H that keeps the knee at `KNEE_MIN` (the knee falls linearly as H grows)."""
    zero = replace(base, handling_s=0.0)
    free = 2.0 * base.b_fast_s * base.b_slow_s / (base.b_fast_s + base.b_slow_s)
    t3, t4 = zero._time(free, 3), zero._time(free, 4)
    # (H + t4) / (H + t3) = KNEE_MIN
    return max(0.0, (t4 - KNEE_MIN * t3) / (KNEE_MIN - 1.0))


def _peak_wait_s(base: Family) -> float:
    """The W of the largest e the wait reaches (e rises with W, then falls back towards 1)."""
    grid = np.geomspace(1e-3, 1e5, 801) * base.b_slow_s
    e = [replace(base, wait_s=float(w)).elasticity() for w in grid]
    return float(grid[int(np.argmax(e))])


def reach(base: Family = Family(), above: Literal["pace", "wait"] = "pace") -> tuple[float, float]:
    """The lowest and highest e `with_elasticity` reaches from `base`'s other parameters."""
    low = replace(base, handling_s=max_handling_s(base), wait_s=0.0, pace=0.0).elasticity()
    if above == "pace":
        high = replace(base, handling_s=0.0, wait_s=0.0, pace=1.0).elasticity()
    else:
        high = replace(base, handling_s=0.0, wait_s=_peak_wait_s(base), pace=0.0).elasticity()
    return low, high


def with_elasticity(
    e: float, base: Family = Family(), above: Literal["pace", "wait"] = "pace"
) -> Family:
    """`base` with H (e < 1), the pace p or the wait W (e > 1, by `above`) set so that its
    elasticity is `e` (to 1e-9), the other two at 0. A ValueError names an e the family cannot
    reach from `base` (see `reach`)."""
    require(above in ("pace", "wait"), "above", above, "'pace' or 'wait'")
    require(is_number(e) and e > 0, "e", e, "a finite elasticity > 0")
    plain = replace(base, handling_s=0.0, wait_s=0.0, pace=0.0)
    if e == 1.0:
        return plain
    if e < 1.0:
        name, hi = "handling_s", max_handling_s(base)
    elif above == "pace":
        name, hi = "pace", 1.0
    else:
        name, hi = "wait_s", _peak_wait_s(base)
    low_e, high_e = reach(base, above)
    if not (low_e <= e <= high_e) or hi == 0.0:
        raise ValueError(
            f"e = {e!r} is invalid; allowed: an elasticity in [{low_e:.4f}, {high_e:.4f}], what "
            f"H (e < 1, kept at t(4) / t(3) >= {KNEE_MIN:g}) and the "
            f"{'pace p <= 1' if above == 'pace' else 'additive wait W'} (e > 1) reach from "
            f"{base.describe()}"
        )

    def gap(x: float) -> float:
        return replace(plain, **{name: x}).elasticity() - e

    lo, lo_gap = 0.0, gap(0.0)
    for _ in range(_BISECTIONS):  # e moves monotonically with x on [0, hi]
        mid = (lo + hi) / 2
        mid_gap = gap(mid)
        if (mid_gap < 0) == (lo_gap < 0):
            lo, lo_gap = mid, mid_gap
        else:
            hi = mid
        if hi - lo <= _TOLERANCE * max(1.0, hi):
            break
    best = min((lo, hi), key=lambda x: abs(gap(x)))
    found = replace(plain, **{name: best})
    if not math.isclose(found.elasticity(), e, abs_tol=1e-9):
        raise ValueError(f"e = {e!r} is invalid: no {name} gives it to 1e-9 (e is flat there)")
    return found
