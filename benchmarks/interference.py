"""Interference in the arena: task time against crowding, the cost of a circuit switch, and the
cross-interference between fast and slow robots.

Every measurement drives the bare engine (`tavc_env.engine.simulation.Simulation`) with fixed
allocations: each robot serves the circuit it is given, task after task (a designated "switcher"
alternates).

1. **t(n)** (preset `dahl2004_homogeneous`, six robots at 0.25 m/s): allocation k on circuit 0 and
   6 - k on circuit 1 for k = 0..6; one run gives t_0(k) and t_1(6 - k), so seven allocations give
   t(n) for n = 1..6 on both circuits. Also t(n+1)/t(n) with a 95% interval.
2. **Switch cost** (homogeneous): one robot alternates circuits every `--switch-every` tasks while
   the five others stay (three on one circuit, two on the other, both ways round, so every switch
   into a circuit is measured with 3 robots there, i.e. in the 3 + 3 state, and with 4); and a lone
   robot alone in the arena, alternating. A *switch task* starts at the other circuit's sink; its
   time is compared with the same robot's *own-circuit* tasks on the same circuit in the same run
   (same crowding).
3. **Cross-interference** (preset `dahl2004`: robots 0-2 fast 0.30 m/s, 3-5 slow 0.20 m/s): f fast
   and s slow robots on circuit 0 (f, s = 0..3), the rest on circuit 1; the mean task time of a fast
   and of a slow robot on circuit 0 (and, from the same runs, on circuit 1 with 3-f fast, 3-s slow).
4. **Elasticity** e (`tavc_agents.analysis.elasticity`), from the circuit-0 tables T_c(f, s) of 3.:
   mean over f, s in 1..3 of ln(T_fast(f, s) / T_fast(1, 0)) divided by that of
   ln(T_slow(f, s) / T_slow(0, 1)); 1: crowding costs every robot the same fraction of its time,
   > 1: fast robots lose more. Its 95% interval is a percentile bootstrap resampling seeds.
   `benchmarks/elasticity.py.measure_elasticity` measures e alone, for any arena.

`--preset` (default dahl2004; also dahl2004_competence, dahl2004_light_stations,
dahl2004_congestion, dahl2004_bays) is the arena of the cross runs; t(n) and the switch runs use
its arena with six robots at 0.25 m/s (for dahl2004: the preset dahl2004_homogeneous).

Warm-up: in every run a task counts only if it was *decided* at or after `--warmup-min` (default
10 simulated minutes) and it is not among the robot's first `--skip-first` (default 2) tasks (the
first task can start at the other circuit's sink, since reset spreads robots 3 + 3 in random
order). Tasks decided up to the end of the run (`--hours`) count, and the run goes on until they
are all complete, so long tasks are not censored at the end. The time each robot spends queued or
travelling is counted tick by tick by an observer of the engine (it changes nothing).

Statistics: each run (seed) gives one number per quantity: the mean over its counted tasks
(task-weighted over the robots of that group). Reported: mean over seeds with a Student-t 95%
interval (n_seeds - 1 df). Ratios t(n+1)/t(n) are ratios of the seed means of two separate sets of
runs; the 95% interval is a delta-method interval on the log scale with Welch-Satterthwaite degrees
of freedom (`tavc_agents.analysis.stats.ratio_ci`); a percentile bootstrap over seeds is given as a
cross-check (too narrow with few seeds). The switch cost is paired within a run: per seed,
mean(switch tasks into c) - mean(own tasks on c), absolute and relative to the own-task mean; mean
over seeds with a Student-t interval.

Writes `interference.{csv,md,json}`, `interference_runs.csv` (one row per run and group) and
`interference.png` (if matplotlib is installed) into a new run folder under runs/ (git ignores it),
`--out`, or with `--update-reference` benchmarks/results/. Runs go through the package's sweep
runner (`--workers`, `--backend local|ray`) and are kept in the output folder's cache/interference/
as they finish, so an interrupted benchmark resumes.

    python benchmarks/interference.py             # 130 runs: 5 seeds x 3 simulated h, ~3-5 min
    python benchmarks/interference.py --quick
    python benchmarks/interference.py --preset dahl2004_competence --out /tmp/competence

Interference in the arena: task time against crowding t(n), the cost of a circuit switch, the
cross-interference between fast and slow robots and the elasticity e drawn from it, from runs of
the bare engine with fixed allocations (`tavc_env.measurement.run_fixed`; the analysis is
`tavc_agents.analysis.interference` and `tavc_agents.analysis.elasticity`). The script is
`benchmarks/interference.py`.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

import arena_analysis as ea
import arena_analysis as ia
import tavc_env
from arena_analysis import FAST, PER_CLASS, SLOW
from arena_runs import ELASTICITY_BOOT_SEED, RUNS, Job, job_key
from tavc_agents.analysis.reports import Report, fmt_ci, have_matplotlib, markdown_table, write_csv
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.study import (
    Outcome,
    Overrides,
    StudySettings,
    arena_overrides,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_env.measurement import two_circuit_allocation
from tavc_env.validation import is_number

HOMOG = "dahl2004_homogeneous"
HETERO = "dahl2004"
RATIO_REQUIREMENT = 1.15  # t(4)/t(3) on the high-value circuit
SWITCH_REQUIREMENT = 0.20  # extra time of a switch task relative to an own-circuit task
EXPERIMENTS = ("t_n", "switch", "switch_lone", "cross")
SWITCHER = 5  # the robot that alternates in the "switch" runs
MEDIUM_SPEED = 0.25  # the robots of the t(n) and switch runs
# Fast and slow robots "share one pace" on a circuit when their task times there differ by at most
# this fraction of the gap between them alone.
SHARED_PACE_FRACTION = 0.25
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The interference benchmark's settings (its command line)."""

    quick_sizes: ClassVar = {"seeds": 2, "hours": 0.12, "warmup_min": 0.5, "skip_first": 1}
    recorded_fields: ClassVar = (
        "seeds=seed_list hours warmup_min skip_first switch_every workers "
        "arena_overrides=sorted_overrides"
    )

    preset: str = HETERO
    """the arena: a preset with three fast (0.30 m/s) and three slow (0.20 m/s) robots, whose team
    runs the cross-interference; t(n) and the switch runs use its arena with six robots at 0.25
    m/s (for dahl2004: the preset dahl2004_homogeneous)"""
    seeds: int = 5
    """seeds per configuration"""
    hours: float = 3.0
    """simulated hours per run"""
    warmup_min: float = 10.0
    """warm-up, simulated minutes: a task counts if decided at or after it"""
    skip_first: int = 2
    """tasks discarded per robot at the start of a run"""
    switch_every: int = 3
    """the switcher's block length (tasks)"""
    quick: bool = False
    """smoke run: 2 seeds x 0.12 h (warm-up 0.5 min, one task skipped)"""
    set: Overrides = ()
    """arena override KEY=VALUE for every run, e.g. --set source_service_s=15 or --set
    service_scales_with_speed=true"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            ("seeds", at_least(self.seeds, 1), "an integer >= 1"),
            ("hours", positive(self.hours), "> 0"),
            ("warmup_min", is_number(self.warmup_min) and self.warmup_min >= 0, ">= 0"),
            ("skip_first", at_least(self.skip_first, 0), ">= 0"),
            (
                "switch_every",
                at_least(self.switch_every, 2),
                "an integer >= 2 (a block needs own-circuit tasks to compare with)",
            ),
        ]
        refuse_invalid(self, checks)
        team = (FAST,) * PER_CLASS + (SLOW,) * PER_CLASS
        presets = sorted(
            name
            for name in tavc_env.PRESETS
            if tavc_env.preset(name).robots == team and tavc_env.preset(name).n_circuits >= 2
        )
        if self.preset not in presets:
            raise ValueError(f"preset = {self.preset!r} is invalid; allowed: one of {presets}")
        # a bad arena is refused before any run
        tavc_env.make_config(self.preset, **self.overrides)
        tavc_env.make_config(self.homog_preset, **{**self.overrides, **self.homog_overrides})

    @property
    def homog_preset(self) -> str:
        """The preset of the t(n) and switch runs."""
        return HOMOG if self.preset == HETERO else self.preset

    @property
    def homog_overrides(self) -> dict[str, Any]:
        """What turns `homog_preset` into the arena of the t(n) and switch runs."""
        return {} if self.preset == HETERO else {"speeds": [MEDIUM_SPEED] * 2 * PER_CLASS}

    @property
    def homog_title(self) -> str:
        """The arena of the t(n) and switch runs, as the report's headings name it."""
        return HOMOG if self.preset == HETERO else f"{self.preset} arena, six robots at 0.25 m/s"

    @property
    def overrides(self) -> dict[str, Any]:
        return arena_overrides(self.set)

    @property
    def arena(self) -> tuple[tuple[str, Any], ...]:
        return tuple(sorted(self.overrides.items()))

    @property
    def seed_list(self) -> list[int]:
        return list(range(self.seeds))

    @property
    def sorted_overrides(self) -> dict[str, Any]:
        return dict(self.arena)

    def recorded(self) -> dict[str, Any]:
        # the preset only when it is not the default: earlier reports did not record it
        preset = {} if self.preset == HETERO else {"preset": self.preset}
        return {**preset, **super().recorded()}


def seed_jobs(s: Settings, seed: int) -> list[Job]:
    """The 7 + 2 + 1 + 16 runs of one seed (see the script's docstring)."""
    medium = None if s.preset == HETERO else (MEDIUM_SPEED,) * 2 * PER_CLASS
    base = Job(
        "t_n",
        s.homog_preset,
        (),
        seed,
        s.hours,
        s.warmup_min * 60.0,
        s.skip_first,
        speeds=medium,
        arena=s.arena,
    )
    new = dataclasses.replace
    jobs = [
        new(base, circuit_of=two_circuit_allocation(n0), label=ia.t_n_label(n0)) for n0 in range(7)
    ]
    switching = new(base, experiment="switch", switcher=SWITCHER, switch_every=s.switch_every)
    for others0 in (3, 2):  # the five others: `others0` on circuit 0, the rest on circuit 1
        alloc = (*two_circuit_allocation(others0, 5), 1)  # the switcher (5) starts on 1
        jobs.append(new(switching, circuit_of=alloc, label=ia.switch_label(others0)))
    lone = new(
        switching, experiment="switch_lone", circuit_of=(0,), switcher=0, speeds=(MEDIUM_SPEED,)
    )
    jobs.append(new(lone, label="lone"))
    for f in range(4):
        for sl in range(4):
            alloc = two_circuit_allocation(f, 3) + two_circuit_allocation(sl, 3)
            label = ia.cross_label(f, sl)
            cross = new(base, experiment="cross", preset=s.preset, speeds=None)
            jobs.append(new(cross, circuit_of=alloc, label=label))
    return jobs


def make_jobs(s: Settings) -> list[Job]:
    """Every run, longest first (so the pool does not end on a lone straggler)."""
    jobs = [j for seed in s.seed_list for j in seed_jobs(s, seed)]
    jobs.sort(key=lambda j: (j.experiment == "switch_lone", j.seed))
    return jobs


# -- analysis -----------------------------------------------------------------------------------
def switch_cases() -> list[ia.SwitchCase]:
    """The switcher into each circuit with 3 robots there (the 3 + 3 state), with 4, and alone."""
    cases = []
    for others0, c in ((2, 0), (3, 1), (3, 0), (2, 1)):
        n_on = (others0 if c == 0 else 5 - others0) + 1
        cases.append(ia.SwitchCase("switch", ia.switch_label(others0), c, n_on))
    cases += [ia.SwitchCase("switch_lone", "lone", c, 1) for c in (0, 1)]
    return cases


@dataclass
class Findings:
    """The analysis: summary rows (the CSV) and the pieces the report is made of."""

    rows: list[Row]
    t_n: dict[int, dict[int, list[float]]]
    switch: dict[str, dict[str, Any]]
    pooled: Row
    cross: dict[tuple[int, str], ia.Matrix]
    queued: dict[tuple[int, str], ia.Matrix]
    elasticity: ea.Elasticity | None = None
    elasticity_error: str = ""
    """why e could not be measured (a cell without tasks, say), if it could not"""
    preset: str = HETERO
    homog_name: str = HOMOG

    def row(self, section: str, circuit: int, quantity: str) -> Row:
        return next(
            r
            for r in self.rows
            if r["section"] == section and r.get("circuit") == circuit and r["quantity"] == quantity
        )


def elasticity_rows(el: ea.Elasticity, preset: str) -> list[Row]:
    """Summary rows of e (with its bootstrap interval) and of the two mean log-ratios."""
    about = {"preset": preset, "circuit": 0}
    n = el.n_seeds
    return [
        ia.summary_row(
            "elasticity",
            "elasticity e (percentile bootstrap 95% interval over seeds)",
            (el.e, el.low, el.high, n),
            **about,
        ),
        ia.summary_row(
            "elasticity",
            "mean ln(T_fast(f,s)/T_fast(1,0)), f,s in 1..3",
            (el.fast_mean_log_ratio, math.nan, math.nan, n),
            **about,
            robot_class="fast",
        ),
        ia.summary_row(
            "elasticity",
            "mean ln(T_slow(f,s)/T_slow(0,1)), f,s in 1..3",
            (el.slow_mean_log_ratio, math.nan, math.nan, n),
            **about,
            robot_class="slow",
        ),
        ia.summary_row(
            "elasticity",
            "pace in company rho = T_slow(1,1)/T_fast(1,1) (percentile bootstrap 95% interval "
            "over seeds)",
            (el.rho, el.rho_low, el.rho_high, n),
            **about,
        ),
        ia.summary_row(
            "elasticity",
            "rho's ceiling T_slow(0,1)/T_fast(1,0), the ratio alone",
            (el.rho_alone, math.nan, math.nan, n),
            **about,
        ),
    ]


def analyse(
    rows: Sequence[Row], seeds: Sequence[int], preset: str = HETERO, homog: str = HOMOG
) -> Findings:
    """The analysis of the runs' group rows; `preset` and `homog` name the arenas of the cross
    runs and of the t(n) and switch runs in the summary rows."""
    summary, tn = ia.t_n_curve(rows, seeds, homog, np.random.default_rng(12345))
    switch: dict[str, dict[str, Any]] = {}
    for case in switch_cases():
        case_rows, switch[case.name] = ia.switch_cost(rows, seeds, homog, case)
        summary += case_rows
    # headline: the two 3 + 3 cases pooled (one value per run)
    pooled_values = [v for case in switch_cases()[:2] for v in switch[case.name]["rel_values"]]
    pooled = ia.summary_row(
        "switch",
        "3+3 pooled over both circuits: relative extra",
        mean_ci(pooled_values),
        preset=homog,
        n_on_circuit=3,
        robot_class="switcher",
    )
    summary.append(pooled)
    cross_rows, cross, queued = ia.cross_matrices(rows, seeds, preset)
    el, error = None, ""
    try:
        el = ea.elasticity(ea.seed_tables(rows, seeds), np.random.default_rng(ELASTICITY_BOOT_SEED))
    except ValueError as e:  # a cell without counted tasks (a very short run)
        error = str(e)
    el_rows = elasticity_rows(el, preset) if el is not None else []
    return Findings(
        summary + cross_rows + el_rows, tn, switch, pooled, cross, queued, el, error, preset, homog
    )


# -- report -------------------------------------------------------------------------------------
def _ci(row: Row) -> tuple[float, float, float]:
    return (row["mean"], row["ci95_low"], row["ci95_high"])


def _ci_pct(row: Row) -> str:
    m, lo, hi = _ci(row)
    return fmt_ci(100 * m, 100 * lo, 100 * hi)


def _verdict(ok: bool, low: float, requirement: float) -> str:
    if not ok and not math.isfinite(low):
        return "NOT MEASURED (too few tasks or seeds for an estimate)"
    word = "PASS" if ok else "FAIL"
    if ok and math.isfinite(low):
        word += (
            " (the whole 95% interval is above the requirement)"
            if low >= requirement
            else " (but the 95% interval reaches below the requirement)"
        )
    return word


def verdict_lines(f: Findings) -> list[str]:
    """The two requirements (t(4)/t(3), switch cost) and the TAVC equilibrium check."""
    r43 = f.row("t_ratio", 0, "t(4)/t(3)")
    r43_1 = f.row("t_ratio", 1, "t(4)/t(3)")
    pooled, sw = f.pooled, f.switch
    ok_ratio = r43["mean"] >= RATIO_REQUIREMENT
    ok_switch = pooled["mean"] >= SWITCH_REQUIREMENT
    lines = [
        "## Verdict",
        "",
        f"- **t(4)/t(3) on the high-value circuit (circuit 0) = "
        f"{fmt_ci(*_ci(r43), 3)}**; requirement >= "
        f"{RATIO_REQUIREMENT}: **{_verdict(ok_ratio, r43['ci95_low'], RATIO_REQUIREMENT)}**. "
        f"(Circuit 1: {fmt_ci(*_ci(r43_1), 3)}.)",
        f"- **Switch cost relative to an own-circuit task, 3 + 3 state, pooled over both circuits "
        f"= {_ci_pct(pooled)} %**; requirement >= {100 * SWITCH_REQUIREMENT:.0f} %: "
        f"**{_verdict(ok_switch, pooled['ci95_low'], SWITCH_REQUIREMENT)}**. Into circuit 0: "
        f"{_ci_pct(sw['others 2+3 into c0']['relative'])} %, into "
        f"circuit 1: {_ci_pct(sw['others 3+2 into c1']['relative'])} %; "
        f"lone robot: {_ci_pct(sw['lone into c0']['relative'])} % / "
        f"{_ci_pct(sw['lone into c1']['relative'])} %.",
    ]
    # TAVC equilibrium check in reward terms: 4th on c0 vs 3rd on c1
    w0, w1 = (c.value for c in tavc_env.make_config(f.homog_name).circuits)
    t0_4, t1_3 = np.mean(f.t_n[0][4]), np.mean(f.t_n[1][3])
    lines.append(
        f"- TAVC equilibrium (DESIGN.md section 3): the 4th robot on circuit 0 earns w0/t0(4) = "
        f"{w0 / t0_4:.2f}/s, the 3rd on circuit 1 w1/t1(3) = {w1 / t1_3:.2f}/s, so 3 + 3 is "
        f"{'an' if w1 / t1_3 > w0 / t0_4 else 'NOT an'} equilibrium of the homogeneous arena "
        f"(needs t0(4)/t1(3) > w0/w1 = {w0 / w1:.2f}; measured {t0_4 / t1_3:.3f})."
    )
    return lines


def arena_text(s: Settings) -> str:
    """The arena's stations, governor and robots in a sentence."""
    c = tavc_env.make_config(s.preset, **s.overrides)
    pace = (
        f" at a {c.service_reference_speed:g} m/s robot's pace, scaled by each robot's speed"
        if c.service_scales_with_speed
        else ""
    )
    serving = (
        "Stations serve one robot at a time"
        if c.station_bays == 1
        else f"Stations have {c.station_bays} bays, each serving one robot at a time"
    )
    governor = (
        f" Clearance governor: a robot drives at min(1, clearance / {c.clearance_governor_m:g} m) "
        f"of its own top speed (sensing range {c.sensing_range_m:g} m)."
        if c.clearance_governor_m > 0
        else ""
    )
    return (
        f"{serving} (source loading {c.source_service_s:g} s, sink "
        f"unloading {c.sink_service_s:g} s{pace}); robots are discs of radius "
        f"{c.robot_radius:g} m.{governor}"
    )


def method_lines(s: Settings) -> list[str]:
    return [
        "",
        "## Method",
        "",
        f"Simulated {s.hours:g} h per run, seeds {s.seed_list}; a task counts if decided at "
        f"or after {s.warmup_min:g} simulated minutes and not among the robot's first "
        f"{s.skip_first} tasks; tasks decided before the end are run to completion. Each run "
        "gives one mean per group (task-weighted over the group's robots); tables show the mean "
        "over seeds and a Student-t 95% interval [low, high]. Ratios: ratio of seed means with a "
        "log-scale delta-method interval (Welch-Satterthwaite df); the bootstrap column resamples "
        "seeds (10,000 reps) and is too narrow with few seeds. Switch cost: per run, mean switch "
        "task time minus mean own-circuit task time of the same robot on the same circuit "
        f"(switching every {s.switch_every} tasks: one switch task and "
        f"{s.switch_every - 1} own tasks per block); relative = that / own-task mean; mean "
        f"over runs with a Student-t interval. {arena_text(s)}",
        "",
        f"## 1. Task time t(n) with n robots on a circuit ({s.homog_title}"
        + (", 0.25 m/s)" if s.preset == HETERO else ")"),
        "",
    ]


def t_n_table(f: Findings) -> str:
    get = {
        (r["section"], r["quantity"], r.get("circuit"), r.get("n_on_circuit")): r for r in f.rows
    }
    trows = []
    for n in range(1, 7):
        cells = [str(n)]
        for c in (0, 1):
            for quantity in (
                "mean task time (s)",
                "time queued per task (s)",
                "circuit throughput n/t(n) (tasks/h)",
            ):
                cells.append(fmt_ci(*_ci(get[("t_n", quantity, c, n)])))
            if n >= 2:
                q = get[("t_ratio", f"t({n})/t({n - 1})", c, n)]
                cells.append(
                    f"{fmt_ci(*_ci(q), 3)} "
                    f"(boot [{q['bootstrap_low']:.3f}, {q['bootstrap_high']:.3f}])"
                )
            else:
                cells.append("")
        trows.append(cells)
    header = ["n"] + [
        f"c{c} {h}"
        for c in (0, 1)
        for h in ("t(n) s", "queued s/task", "tasks/h n/t", "t(n)/t(n-1)")
    ]
    return markdown_table(header, trows)


def switch_table(f: Findings) -> str:
    srows = [
        (
            key,
            info["n_on_circuit"],
            fmt_ci(*_ci(info["own"])),
            fmt_ci(*_ci(info["switch"])),
            fmt_ci(*_ci(info["extra"])),
            _ci_pct(info["relative"]),
            f"{info['n_switch_tasks']} / {info['n_own_tasks']}",
        )
        for key, info in f.switch.items()
    ]
    header = [
        "case (switcher into circuit)",
        "robots on that circuit",
        "own task (s)",
        "switch task (s)",
        "extra (s)",
        "extra (%)",
        "tasks switch / own",
    ]
    return markdown_table(header, srows)


def _matrix_table(mat: ia.Matrix) -> str:
    def cell(st: ia.Stats | None) -> str:
        return fmt_ci(*(st[:3] if st is not None else (math.nan,) * 3))

    rows = [[f"f={f}"] + [cell(mat.get((f, s))) for s in range(4)] for f in range(4)]
    return markdown_table(["", "s=0", "s=1", "s=2", "s=3"], rows)


def cross_lines(f: Findings) -> list[str]:
    """The cross-interference matrices: task times on both circuits, time queued on circuit 0."""
    lines = []
    for c in (0, 1):
        for cls in ("fast", "slow"):
            lines += [f"**{cls.capitalize()} robot on circuit {c}** (rows f, columns s):", ""]
            lines += [_matrix_table(f.cross[(c, cls)]), ""]
        if c == 0:
            for cls in ("fast", "slow"):
                lines += [
                    f"**{cls.capitalize()} robot on circuit 0: seconds per task spent waiting in "
                    "a station's line** (rows f, columns s):",
                    "",
                    _matrix_table(f.queued[(0, cls)]),
                    "",
                ]
            lines += ["Circuit 1 from the same runs (f fast and s slow robots on circuit 1):", ""]
    return lines


def arena_label(name: str, s: Settings) -> str:
    """An arena's name with the run's overrides, e.g. 'dahl2004 + source_service_s=6', as the
    figure's titles name it."""
    return " + ".join([name, *(f"{key}={value}" for key, value in sorted(s.overrides.items()))])


def speed_classes_text(s: Settings) -> str:
    """The cross-interference arena's speed classes, e.g. 'fast 0.3 m/s, slow 0.2 m/s'."""
    config = tavc_env.make_config(s.preset, **s.overrides)
    speeds: dict[str, float] = {}
    for robot in config.robots:
        speeds.setdefault(robot.speed_class or f"{robot.speed:g} m/s", robot.speed)
    return ", ".join(f"{label} {speed:g} m/s" for label, speed in speeds.items())


def cross_notes(f: Findings, s: Settings) -> list[str]:
    """Plain-language reading of the circuit-0 matrices: who slows whom."""

    def t(cls: str, fast: int, slow: int) -> float:
        st = f.cross[(0, cls)].get((fast, slow))
        return st[0] if st is not None and math.isfinite(st[0]) else math.nan

    def q(cls: str, fast: int, slow: int) -> float:
        st = f.queued[(0, cls)].get((fast, slow))
        return st[0] if st is not None and math.isfinite(st[0]) else math.nan

    out = ["### Reading the matrices", ""]
    out.append(
        f"- Alone on circuit 0: fast {t('fast', 1, 0):.1f} s, slow {t('slow', 0, 1):.1f} s "
        f"(slow/fast = {t('slow', 0, 1) / t('fast', 1, 0):.3f}; travel alone would give 1.5)."
    )
    out.append(
        f"- First companion: a fast robot with one more fast robot {t('fast', 1, 0):.1f} -> "
        f"{t('fast', 2, 0):.1f} s ({t('fast', 2, 0) - t('fast', 1, 0):+.1f} s), with one slow "
        f"robot -> {t('fast', 1, 1):.1f} s ({t('fast', 1, 1) - t('fast', 1, 0):+.1f} s; queued "
        f"{q('fast', 1, 1):.1f} s per task against {q('fast', 2, 0):.1f} s with a fast "
        f"companion). A slow robot with one more slow robot {t('slow', 0, 1):.1f} -> "
        f"{t('slow', 0, 2):.1f} s ({t('slow', 0, 2) - t('slow', 0, 1):+.1f} s), with one fast "
        f"robot -> {t('slow', 1, 1):.1f} s ({t('slow', 1, 1) - t('slow', 0, 1):+.1f} s)."
    )
    same = [
        abs(t("fast", a, b) - t("slow", a, b))
        for a in range(1, 4)
        for b in range(1, 4)
        if math.isfinite(t("fast", a, b)) and math.isfinite(t("slow", a, b))
    ]
    if same:
        # The catch-up story holds only where the classes really share one pace; say so only then.
        lone_gap = t("slow", 0, 1) - t("fast", 1, 0)
        widest = max(same)
        head = (
            f"- Wherever fast and slow robots share circuit 0 (f, s >= 1), their task times "
            f"differ by at most {widest:.1f} s (alone, by {lone_gap:.1f} s)"
        )
        if widest <= SHARED_PACE_FRACTION * lone_gap:
            config = tavc_env.make_config(s.preset, **s.overrides)
            loading = f"{config.source_service_s:g} s loading" + (
                f" at a {config.service_reference_speed:g} m/s robot's pace"
                if config.service_scales_with_speed
                else ""
            )
            out.append(
                f"{head}: a fast robot that shares a station with a slow one ends up at the slow "
                f"one's pace (it catches up during the {loading} and then waits "
                "behind it in the line, lap after lap), so speed pays only among robots of the "
                "same class."
            )
        else:
            out.append(f"{head}: sharing a circuit does not put the two classes on one pace.")
    out.append(
        f"- Three of a kind on circuit 0: 3 fast {t('fast', 3, 0):.1f} s per fast task, 3 slow "
        f"{t('slow', 0, 3):.1f} s per slow task."
    )
    return out


def report_body(f: Findings, s: Settings) -> str:
    lines = verdict_lines(f) + method_lines(s)
    lines += [
        t_n_table(f),
        "",
        "t(n) on circuit 0 and t(6-n) on circuit 1 come from the same runs (allocation n + 6-n). "
        "'queued s/task': time a robot spends waiting in a station's line per task (its share "
        "of ticks in the queued mode times its mean task time). 'tasks/h': the circuit's "
        "delivery rate n / t(n) (the TAVC model's c); it saturates where the source station "
        "(its loading plus the changeover between robots) is busy all the time.",
        "",
        f"## 2. Extra time of a circuit switch ({s.homog_title})",
        "",
        switch_table(f),
        "",
        "'others a+b': the five non-switching robots, a on circuit 0 and b on circuit 1; the "
        "switcher (robot 5) alternates. 'robots on that circuit' counts the switcher.",
        "",
        f"## 3. Cross-interference ({s.preset}: {speed_classes_text(s)})",
        "",
        "Mean task time (s) of a fast and of a slow robot on the high-value circuit 0, with f fast "
        "(rows) and s slow (columns) robots on circuit 0 (the robot itself included) and the rest "
        "on circuit 1.",
        "",
    ]
    lines += cross_lines(f) + cross_notes(f, s) + elasticity_lines(f)
    return "\n".join(lines)


def elasticity_lines(f: Findings) -> list[str]:
    """e with its interval, what it is made of, and how to read it."""
    out = ["", "### Elasticity", ""]
    el = f.elasticity
    if el is None:
        return [*out, f"e: NOT MEASURED ({f.elasticity_error})"]
    fast, slow = el.fast_mean_log_ratio, el.slow_mean_log_ratio
    if not math.isfinite(el.e):
        reading = "undefined, as crowding costs the slow robots nothing"
    elif el.e != 1:
        who = "fast" if el.e > 1 else "slow"
        reading = f"{who} robots lose the larger share of their time to crowding"
    else:
        reading = "crowding costs both classes the same share of their time"
    return [
        *out,
        f"**e = {el.text()}** (95% percentile bootstrap over {el.n_seeds} seeds, resampling "
        f"whole seeds; too narrow with few seeds): {reading}.",
        "",
        "e = mean over f, s in 1..3 of ln(T_fast(f,s) / T_fast(1,0)), divided by the same mean of "
        "ln(T_slow(f,s) / T_slow(0,1)), from the tables of circuit 0 above averaged over seeds: "
        f"{fast:.3f} for a fast robot (its task time x{math.exp(fast):.2f} on average over the "
        f"shared cells) and {slow:.3f} for a slow one (x{math.exp(slow):.2f}). e = 1: crowding "
        "costs every robot the same fraction of its time; e > 1: fast robots lose more.",
        "",
        f"**Pace in company rho = {el.rho_text()}** (same bootstrap): T_slow(1,1) / T_fast(1,1), "
        "a slow robot's task time over a fast one's when one of each serves circuit 0. Alone the "
        f"ratio is {el.rho_alone:.3f}, rho's ceiling; rho = 1 means the fast robot works at the "
        f"slow robot's pace. Here the fast robot keeps {_kept(el):.0%} of its advantage.",
    ]


def _kept(el: ea.Elasticity) -> float:
    """How much of its speed advantage alone a fast robot keeps in company: (rho - 1) / (rho
    alone - 1)."""
    return (el.rho - 1.0) / (el.rho_alone - 1.0)


def summary(f: Findings, jobs: Sequence[Job]) -> dict[str, Any]:
    """The JSON summary: the two requirements and what was run."""
    r43 = f.row("t_ratio", 0, "t(4)/t(3)")
    pooled = f.pooled
    return {
        "t4_over_t3_circuit0": {k: r43[k] for k in ("mean", "ci95_low", "ci95_high")},
        "t4_over_t3_requirement": RATIO_REQUIREMENT,
        "t4_over_t3_pass": r43["mean"] >= RATIO_REQUIREMENT,
        "switch_relative_3p3_pooled": {k: pooled[k] for k in ("mean", "ci95_low", "ci95_high")},
        "switch_requirement": SWITCH_REQUIREMENT,
        "switch_pass": pooled["mean"] >= SWITCH_REQUIREMENT,
        **elasticity_summary(f),
        "runs": len(jobs),
        "runs_per_experiment": {e: sum(1 for j in jobs if j.experiment == e) for e in EXPERIMENTS},
        "example_run": asdict(jobs[0]),
    }


def elasticity_summary(f: Findings) -> dict[str, Any]:
    el = f.elasticity
    if el is None:
        return {"elasticity": {"error": f.elasticity_error}}
    return {
        "elasticity": {
            "e": el.e,
            "ci95_low": el.low,
            "ci95_high": el.high,
            "interval": "percentile bootstrap over seeds",
            "n_seeds": el.n_seeds,
            "fast_mean_log_ratio": el.fast_mean_log_ratio,
            "slow_mean_log_ratio": el.slow_mean_log_ratio,
        },
        "pace_in_company": {
            "rho": el.rho,
            "ci95_low": el.rho_low,
            "ci95_high": el.rho_high,
            "interval": "percentile bootstrap over seeds, drawn after e's",
            "alone": el.rho_alone,
        },
    }


SUMMARY_FIELDS = [
    "section",
    "quantity",
    "preset",
    "circuit",
    "n_on_circuit",
    "n_fast_on_circuit",
    "n_slow_on_circuit",
    "robot_class",
    "mean",
    "ci95_low",
    "ci95_high",
    "n_seeds",
    "n_tasks",
    "bootstrap_low",
    "bootstrap_high",
]


def build_report(f: Findings, s: Settings, jobs: Sequence[Job]) -> Report:
    body = report_body(f, s)
    figures: list[tuple[str, Any]] = []
    if have_matplotlib():
        body += "\n\n![interference](interference.png)\n"
        figures.append(
            (
                "interference.png",
                lambda path: ia.plot_interference(
                    path,
                    f.rows,
                    f.cross,
                    RATIO_REQUIREMENT,
                    arena_label(s.preset, s),
                    arena_label(s.homog_title, s),
                ),
            )
        )
    return Report(
        "interference",
        "Interference benchmark",
        body,
        f.rows,
        summary(f, jobs),
        SUMMARY_FIELDS,
        figures,
    )


def _run_wall(result: dict[str, Any]) -> float:
    rows = result["rows"]
    return float(rows[0]["run_wall_s"]) if rows else 0.0


def run(settings: Settings) -> Outcome:
    """Run (or resume) every run, then write the runs' rows, the report and the figure."""
    out = settings.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    s = settings.sized()
    jobs = make_jobs(s)
    jobs_dir = Path("cache", "interference")  # its provenance with it (`out` may be shared)
    results, provenance = settings.run_jobs(
        jobs, RUNS, jobs_dir, provenance_in=jobs_dir, wall_of=_run_wall
    )
    rows = [r for job in jobs for r in results[job_key(job)]["rows"]]
    runs_csv = out / "interference_runs.csv"
    write_csv(runs_csv, rows, ia.RUN_FIELDS)
    findings = analyse(rows, s.seed_list, s.preset, s.homog_preset)
    report = build_report(findings, s, jobs)
    written = [runs_csv, *report.write(out, provenance)]
    text = (
        report.body.split("## Method")[0]
        + f"\nwrote {out / 'interference.md'} ({provenance['wall_time_s']:.0f} s wall)"
    )
    return Outcome(out, written, text)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
