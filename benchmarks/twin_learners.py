"""The model twin measured among moving learners, audited mechanism by mechanism, and tested out
of sample (issue 40). Stages, whose order the git history shows:

    python benchmarks/twin_learners.py --stage logs --workers 2      # physics learner task logs
    python benchmarks/twin_learners.py --stage audit                 # learner tables, audit
    python benchmarks/twin_learners.py --stage predict               # pre-registered predictions
    python benchmarks/twin_learners.py --stage test --workers 2      # their physics (resumable)
    python benchmarks/twin_learners.py --stage family                # the search's arenas
    python benchmarks/twin_learners.py --stage search --workers 2    # the search's map
    python benchmarks/twin_learners.py --stage gap --workers 2       # why dahl2004 is missed

Writes, with `--update-reference`, benchmarks/results/twin_learners/ (logs and audit: every logged
trial in `logs/`, the learner tables in `tables/`, `twin_learners.{md,csv,json}`),
benchmarks/results/twin_learners_prediction/ (predict) or benchmarks/results/twin_learners_test/
(test); otherwise a new run folder under runs/; `--resume RUN_DIR` continues.

1. `logs`: physics trials of softmax TAVC (the package's learner, run by the package's trial
   runner, exactly as `benchmarks/passing.py` and the regime map run them: same seeds, same
   trajectories) that keep every task: when it was decided, its circuit, its time, the start
   allocation, every change of circuit and the Q tables hourly. `LOG_CELLS` says which.
2. `audit`: from those logs the learner tables (`tavc_env.twin.learner_tables`: first tasks,
   task times by composition among learners, switch costs by class), then the batched twin with
   the old tables (fixed allocations) and the new ones on the same cells, set against the physics
   per mechanism: first-task times, task times by composition, switch costs, Q levels and
   fast - slow, with 95 % intervals and N.
3. `predict`: the new twin's fast - slow in `OUT_OF_SAMPLE` cells, none of whose physics has run,
   with the physics trials a cell needs for 80 % power (`benchmarks/passing.py`'s rule).
4. `test`: those physics trials (logged too), and agreement cell by cell.
5. `family` and `search`: the search for the paper's condition (section 5 below).
6. `gap`: why the twin misses dahl2004. Physics trials on fresh seeds, each paired with the same
   seed on `tavc_env.twin.TwinPaidArenaEnv` (the physics, its learners paid the twin's task
   times), and the physics
   task times among learners over the twin's cells by class, kind of task and period
   (`run_gap`; writes benchmarks/results/twin_gap/).

The script is `benchmarks/twin_learners.py`.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

import arena_runs
import tavc_env
from tavc_agents.analysis.measures import measure
from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, fmt, fmt_ci, markdown_table, write_csv
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.files import read_csv, read_record, read_report, write_record
from tavc_agents.experiments.packs import is_saved, load_trials, read_saved
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.runner import TrialResult, env_arguments, run_trial
from tavc_agents.experiments.study import (
    RESULTS_DIR,
    Outcome,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import json_jobs
from tavc_agents.learners.selection import Softmax
from tavc_agents.learners.tavc import TavcLearner, TavcParams
from tavc_agents.policy import Policy
from tavc_env import Simulation
from tavc_env.twin import (
    InterferenceTables,
    ObservedTask,
    TwinPaidArenaEnv,
    TwinPaidSimulation,
    first_tasks,
    learner_tables,
    logged_tasks,
    switch_cost,
    twin_paid_parallel_env,
)

Row = dict[str, Any]
Stage = Literal["logs", "audit", "predict", "test", "family", "search", "gap"]


# -- the learners ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class SoftmaxCell:
    """A softmax TAVC learner: temperature and initialisation (`TavcParams.init`; `init_range` 0
    with the paper's initialisation: every Q entry starts at the same fixed level, 0)."""

    temperature: float
    init: str = "scaled"
    init_range: float = 0.1

    @property
    def params(self) -> TavcParams:
        return TavcParams(init=self.init, init_range=self.init_range)

    def policy(self, agent: str) -> Policy:
        return TavcLearner(Softmax(self.temperature), self.params)

    @property
    def batch(self) -> arena_runs.Learner:
        """The same learner in the batched twin (`arena_runs.run_batch`)."""
        return arena_runs.Learner("softmax", self.temperature, self.params)


LEARNERS: Mapping[str, SoftmaxCell] = {
    "softmax_T0.002": SoftmaxCell(0.002),
    "softmax_T0.005": SoftmaxCell(0.005),
    "softmax_T0.003": SoftmaxCell(0.003),
    "softmax_T0.005_paper": SoftmaxCell(0.005, "paper"),
    "softmax_T0.005_equal": SoftmaxCell(0.005, "paper", 0.0),
}
"""Condition name -> learner. `softmax_T<T>` are `arena_runs.CONDITIONS`' cells (the scaled
initialisation); `_paper` is the paper's literal U(-0.1, 0.1); `_equal` every entry at 0."""

LOG_CELLS: Mapping[tuple[str, str], int] = {
    ("dahl2004_passing", "softmax_T0.005"): 50,
    ("dahl2004_passing", "softmax_T0.002"): 50,
    ("dahl2004", "softmax_T0.005"): 30,
    ("dahl2004_congestion", "softmax_T0.005"): 30,
}
"""(arena, condition) -> logged physics trials (seeds 0, 1, ...: the committed trials' seeds) that
the learner tables are measured from."""


# -- jobs -------------------------------------------------------------------------------------------
Engine = Literal[
    "physics", "twin_fixed", "twin_learners", "physics_twin_paid", "physics_corrected_pay"
]
ENGINES: tuple[Engine, ...] = (
    "physics",
    "twin_fixed",
    "twin_learners",
    "physics_twin_paid",
    "physics_corrected_pay",
)
"""the physics, the twin with the fixed-allocation tables (`tavc_twin_v0`'s, the committed
predictions'), the twin with the tables measured among learners, and the physics paying its
learners with the twin's task times (`tavc_env.twin.TwinPaidArenaEnv`: stage `gap`), and the
same with those times corrected by the measured pay factors (`CorrectedPayEnv`: stage `gap`)"""


@dataclass(frozen=True)
class LogTrial:
    """One learner trial of `condition` on `arena`, every task kept: on the physics, or on the
    twin with `tables` (recorded by their digest)."""

    arena: str
    condition: str
    seed: int
    convergence_h: float
    measured_h: float
    arena_sha: str = ""
    engine: Engine = "physics"
    tables_sha256: str = ""
    keep_log: bool = True
    pay_factors: tuple[tuple[str, str, int, float], ...] = ()
    """physics_corrected_pay: (class, kind of task, period index, factor) (`CorrectedPayEnv`)"""
    tables: Mapping[str, Any] | None = field(default=None, compare=False, repr=False)


def log_key(job: LogTrial) -> str:
    twin = "" if job.engine == "physics" else f"__{job.engine}"
    return f"{job.arena}__{job.condition}{twin}__seed{job.seed}"


def _rounded(values: Sequence[float], digits: int) -> list[float]:
    return [round(float(v), digits) for v in values]


def task_log(result: TrialResult) -> dict[str, Any]:
    """The raw record of a trial: start allocation, changes of circuit, deliveries (time, robot,
    circuit, task time) and the Q tables at each snapshot."""
    return {
        "initial_circuits": list(result.initial_circuits),
        "changes": [[round(t, 6), r, c] for t, r, c in result.changes],
        "delivery_time_s": _rounded(result.delivery_time_s, 6),
        "delivery_robot": list(result.delivery_robot),
        "delivery_circuit": list(result.delivery_circuit),
        "delivery_task_time_s": _rounded(result.delivery_task_time_s, 6),
        "q": [
            [round(snap["time_s"], 3), [np.round(q, 8).tolist() for q in snap["q"].values()]]
            for snap in result.q_snapshots
        ],
    }


def run_log_trial(job: LogTrial) -> dict[str, Any]:
    """Run `job` on the physics: its measures (as `arena_runs.run_map_trial` reports them) and
    its task log."""
    started = time.perf_counter()
    factory: Any = None
    if job.engine != "physics":
        assert job.tables is not None, "a twin trial needs its tables"
        tables = InterferenceTables.from_dict(job.tables)
        if job.engine == "physics_corrected_pay":
            factory = functools.partial(CorrectedPayEnv, tables, job.pay_factors)
        elif job.engine == "physics_twin_paid":
            factory = functools.partial(twin_paid_parallel_env, tables=tables)
        else:
            factory = functools.partial(tavc_env.twin_parallel_env, tables=tables)
    result = run_trial(
        LEARNERS[job.condition].policy,
        seed=job.seed,
        convergence_s=job.convergence_h * 3600.0,
        measured_s=job.measured_h * 3600.0,
        snapshot_every_s=3600.0,
        env_factory=factory,
        **env_arguments(arena_runs.ARENAS[job.arena]),
    )
    return {
        **arena_runs.measures_record(measure(result)),
        "speed_classes": list(result.speed_classes),
        "values": list(result.values),
        **({"log": task_log(result)} if job.keep_log else {}),
        "wall_s": round(time.perf_counter() - started, 2),
    }


LOGS = json_jobs(
    run_log_trial,
    log_key,
    unit="trial",
    omit=("tables",),
    added={"engine": "physics", "tables_sha256": "", "keep_log": True, "pay_factors": []},
)


class CorrectedPaySimulation(TwinPaidSimulation):
    """The physics paid as the twin pays, each draw times the measured factor of its class, kind
    of task (`task_kind`) and period (`GAP_PERIODS_H`, by the time it was decided): the physics'
    task time over the twin's mean for such tasks (`cell_residuals`). A robot's first task is paid
    the draw itself (the factors leave first tasks out)."""

    def __init__(
        self,
        config: tavc_env.ArenaConfig,
        tables: InterferenceTables,
        jam_window_s: float,
        factors: Sequence[tuple[str, str, int, float]],
    ) -> None:
        super().__init__(config, tables, jam_window_s)
        self.factors = {(c, kind, period): f for c, kind, period, f in factors}
        self.high = int(np.argmax([c.value for c in config.circuits]))
        self.robot_classes = [r.speed_class for r in config.robots]

    def pay(self, robot: int, circuit: int, switch: bool, first: bool, drawn_s: float) -> float:
        if first:
            return drawn_s
        key = (
            self.robot_classes[robot],
            task_kind(circuit, switch, self.high),
            period_of(self.time_s),
        )
        return drawn_s * self.factors.get(key, 1.0)


class CorrectedPayEnv(TwinPaidArenaEnv):
    """`TwinPaidArenaEnv` on `CorrectedPaySimulation`."""

    def __init__(
        self,
        tables: InterferenceTables,
        factors: Sequence[tuple[str, str, int, float]],
        **env_kwargs: Any,
    ) -> None:
        self.factors = factors
        super().__init__(tables, **env_kwargs)

    def _new_engine(self) -> Simulation:
        return CorrectedPaySimulation(
            self.config, self.tables, self.options.jam_window_s, self.factors
        )


# -- what a log says ------------------------------------------------------------------------------
FIXED_TABLES: Mapping[str, Path] = {
    "dahl2004_passing": RESULTS_DIR / "passing_prediction" / "twin_tables",
    "dahl2004": RESULTS_DIR / "regime_map" / "twin_tables",
    "dahl2004_congestion": RESULTS_DIR / "regime_map" / "twin_tables",
}
"""Where each arena's fixed-allocation tables are committed: the tables of the committed twin
predictions (`benchmarks/passing.py`, the regime map)."""
COMMITTED_PHYSICS: Mapping[str, Path] = {
    "dahl2004_passing": RESULTS_DIR / "passing" / "trials",
    "dahl2004": RESULTS_DIR / "regime_map" / "trials",
    "dahl2004_congestion": RESULTS_DIR / "regime_map" / "trials",
}
"""Each arena's committed physics trials (`arena_runs.MapTrial` records)."""
TESTED_PHYSICS = RESULTS_DIR / "twin_learners_test" / "trials"
"""The out-of-sample cells' committed physics trials (`LogTrial` records, stage `test`)."""


def fixed_tables(arena: str) -> dict[str, Any]:
    """The arena's committed fixed-allocation tables (as `to_dict`)."""
    data: dict[str, Any] = read_saved(FIXED_TABLES[arena] / f"tables_{arena}.json")["result"]
    return data


def committed_physics(arena: str, condition: str) -> dict[int, float]:
    """Per seed, fast - slow of the arena's committed physics trials of `condition` (the
    studies' and the out-of-sample test's)."""
    out = {}
    records = [*load_trials(COMMITTED_PHYSICS[arena]), *load_trials(TESTED_PHYSICS)]
    for record in records:
        job, result = record["record"], record["result"]
        key = (job["arena"], job["condition"], job.get("engine", "physics"))
        if key == (arena, condition, "physics"):
            out[int(job["seed"])] = float(result["fast_share"]) - float(result["slow_share"])
    return out


def trial_tasks(arena: str, result: Mapping[str, Any]) -> tuple[ObservedTask, ...]:
    log = result["log"]
    return logged_tasks(
        arena_runs.arena_config(arena),
        log["initial_circuits"],
        log["changes"],
        log["delivery_time_s"],
        log["delivery_robot"],
        log["delivery_circuit"],
        log["delivery_task_time_s"],
    )


def time_ratios(tasks: Sequence[ObservedTask], high: int) -> dict[str, float]:
    """Per class R = mean task time on the high-value circuit / on the other(s), own-circuit
    tasks after the first (nan where a class has none on one side)."""
    out = {}
    for cls in sorted({t.robot_class for t in tasks}):
        on = [t.task_time_s for t in tasks if _own(t, cls) and t.circuit == high]
        off = [t.task_time_s for t in tasks if _own(t, cls) and t.circuit != high]
        out[cls] = float(np.mean(on) / np.mean(off)) if on and off else math.nan
    return out


def _own(task: ObservedTask, cls: str) -> bool:
    return task.robot_class == cls and not (task.first or task.switch)


def switch_costs(tasks: Sequence[ObservedTask], tables: InterferenceTables) -> dict[str, float]:
    """Per class what switching costs (`tavc_env.twin.switch_cost` against `tables`)."""
    return {cls: switch_cost(tasks, tables, cls)[0] for cls in tables.classes}


def serial_correlation(
    tasks: Sequence[ObservedTask], robots: Sequence[int], tables: InterferenceTables
) -> float:
    """The lag-1 correlation of a robot's successive own-circuit task times (log of time over
    its cell's mean, consecutive pairs of own tasks after the first), averaged over robots;
    `robots[i]` is task i's robot."""
    by_robot: dict[int, list[float]] = {}
    for robot, t in zip(robots, tasks):
        own = not (t.first or t.switch)
        cell = tables.cell(t.circuit, t.counts, t.robot_class).mean_s
        by_robot.setdefault(robot, []).append(math.log(t.task_time_s / cell) if own else math.nan)
    out = []
    for values in by_robot.values():
        v = np.asarray(values)
        a, b = v[:-1], v[1:]
        ok = np.isfinite(a) & np.isfinite(b)
        if ok.sum() >= 3:
            out.append(float(np.corrcoef(a[ok], b[ok])[0, 1]))
    return float(np.mean(out)) if out else math.nan


def q_levels(
    result: Mapping[str, Any], params: TavcParams, at_h: float
) -> dict[str, tuple[float, float]]:
    """Per class the mean Q level the scaled initialisation gives (from each robot's first
    reward, `TavcLearner.update`) and the mean of a robot's Q entries at `at_h` hours (the last
    snapshot at or before it)."""
    classes, values, log = result["speed_classes"], result["values"], result["log"]
    start = {}
    for robot, circuit, t in zip(
        log["delivery_robot"], log["delivery_circuit"], log["delivery_task_time_s"]
    ):  # in time order: each robot's first delivery first
        if robot not in start:
            reward = values[circuit] / (t * arena_runs.REWARD_UNIT)
            start[robot] = params.scaled_level(reward)
    late = [q for t, q in log["q"] if t <= at_h * 3600.0 + 1e-6][-1]
    out = {}
    for cls in sorted(set(classes)):
        robots = [i for i, c in enumerate(classes) if c == cls]
        out[cls] = (
            float(np.mean([start[i] for i in robots if i in start])),
            float(np.mean([np.mean(late[i]) for i in robots])),
        )
    return out


# -- stage 2: the learner tables and the audit -------------------------------------------------------
@dataclass(frozen=True)
class StartRun:
    """A physics run of `arena` from its start allocation that measures every robot's first task
    (`tavc_env.twin.first_tasks`)."""

    arena: str
    seed: int
    hours: float
    arena_sha: str = ""


def run_start(job: StartRun) -> dict[str, Any]:
    tasks = first_tasks(arena_runs.arena_config(job.arena), [job.seed], job.hours)
    return {"tasks": [dataclasses.asdict(t) for t in tasks]}


STARTS = json_jobs(run_start, lambda job: f"{job.arena}__start{job.seed}", unit="run")
START_HOURS = 0.25
"""long enough for every robot's first task in these arenas (the slowest take about 300 s)"""


def start_tasks(s: Settings, arenas: Sequence[str]) -> dict[str, list[ObservedTask]]:
    """Per arena, every robot's first task over `s.start_runs` physics runs from the start
    allocation (run, or resumed, in the output folder's starts/)."""
    jobs = [
        StartRun(a, k, START_HOURS, arena_runs.digest(a))
        for a in arenas
        for k in range(s.start_runs)
    ]
    started, _ = s.run_jobs(jobs, STARTS, "starts/runs", provenance_in="starts")
    return {
        a: [
            ObservedTask(**{**t, "counts": tuple(t["counts"])})
            for job in jobs
            if job.arena == a
            for t in started[STARTS.key(job)]["tasks"]
        ]
        for a in arenas
    }


VARIANTS: Mapping[str, str] = {
    "fixed": "fixed-allocation tables (the committed twin)",
    "first": "fixed + first tasks from the start (A)",
    "cells": "fixed + cells among learners (B)",
    "cells_switch": "cells among learners + class switch costs (B, C)",
    "learners": "all: first tasks, cells among learners, class switch costs (A, B, C)",
}
"""The batched twin's tables in the audit: the committed ones, each mechanism alone, and all."""
TWIN_ENGINES: tuple[tuple[Engine, str], ...] = (
    ("twin_fixed", "fixed"),
    ("twin_learners", "learners"),
)
"""the logged twin trials' engines and their tables (`VARIANTS`)"""


def variant_tables(
    name: str, fixed: InterferenceTables, learned: InterferenceTables
) -> InterferenceTables:
    """The tables of audit variant `name` (`VARIANTS`)."""
    if name == "fixed":
        return fixed
    if name == "first":
        return dataclasses.replace(
            fixed,
            first_own_cells=learned.first_own_cells,
            first_switch_cells=learned.first_switch_cells,
        )
    if name in ("cells", "cells_switch"):
        costs = learned.class_switch_costs if name == "cells_switch" else ()
        return dataclasses.replace(
            learned, class_switch_costs=costs, first_own_cells=(), first_switch_cells=()
        )
    return learned


def batch_effect(
    arena: str,
    tables: InterferenceTables,
    condition: str,
    trials: int,
    rng: np.random.Generator,
    s: Settings,
) -> np.ndarray:
    """Per batched twin trial, fast - slow."""
    out = arena_runs.run_batch(
        arena_runs.arena_config(arena),
        tables,
        LEARNERS[condition].batch,
        trials,
        rng,
        s.convergence_h * 3600.0,
        s.measured_h * 3600.0,
    )
    return np.asarray(out.fast_share - out.slow_share)


def _ci_row(values: Sequence[float], **labels: Any) -> Row:
    m, lo, hi, n = mean_ci([v for v in values if math.isfinite(v)])
    return {**labels, "mean": m, "low": lo, "high": hi, "n": n}


def trial_measures(
    arena: str, results: Sequence[Mapping[str, Any]], learned: InterferenceTables, at_h: float
) -> dict[str, list[float]]:
    """Per measure name, one value per trial (per task for first tasks and cells)."""
    config = arena_runs.arena_config(arena)
    high = int(np.argmax([c.value for c in config.circuits]))
    params = TavcParams()
    out: dict[str, list[float]] = {}
    for r in results:
        tasks = trial_tasks(arena, r)
        out.setdefault("fast - slow", []).append(float(r["fast_share"]) - float(r["slow_share"]))
        for t in tasks:
            if t.first:
                kind = "leaving" if t.switch else "staying"
                out.setdefault(f"first task s: {t.robot_class}, {kind}", []).append(t.task_time_s)
            elif not t.switch and t.circuit == high:
                f, sl = t.counts
                name = f"task s on high, ({f} fast, {sl} slow): {t.robot_class}"
                out.setdefault(name, []).append(t.task_time_s)
        log = r["log"]
        robots = [robot for _, robot in sorted(zip(log["delivery_time_s"], log["delivery_robot"]))]
        out.setdefault("lag-1 correlation of task times", []).append(
            serial_correlation(tasks, robots, learned)
        )
        for cls, ratio in time_ratios(tasks, high).items():
            out.setdefault(f"R {cls} (high / low)", []).append(ratio)
        for cls, cost in switch_costs(tasks, learned).items():
            out.setdefault(f"switch cost {cls}", []).append(cost)
        for cls, (start, late) in q_levels(r, params, at_h).items():
            out.setdefault(f"Q level {cls}, start", []).append(start)
            out.setdefault(f"Q level {cls}, {at_h:g} h", []).append(late)
    return out


def physics_logs(s: Settings) -> dict[tuple[str, str], list[Mapping[str, Any]]]:
    """The logged physics trials' results (`--stage logs`), by (arena, condition)."""
    physics: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for record in load_trials(s.logs_dir()):
        job = record["record"]
        if job.get("engine", "physics") == "physics":
            physics.setdefault((job["arena"], job["condition"]), []).append(record["result"])
    return physics


def run_audit(s: Settings) -> Outcome:
    out = s.out_dir()
    physics = physics_logs(s)
    arenas = list(dict.fromkeys(a for a, _ in LOG_CELLS))
    starts_of = start_tasks(s, arenas)
    tables: dict[str, dict[str, InterferenceTables]] = {}
    for a in arenas:
        fixed = InterferenceTables.from_dict(fixed_tables(a))
        tasks = [
            t
            for (arena, _), rs in physics.items()
            if arena == a
            for r in rs
            for t in trial_tasks(a, r)
        ]
        starts = starts_of[a]
        learned = learner_tables(fixed, tasks, starts)
        tables[a] = {v: variant_tables(v, fixed, learned) for v in VARIANTS}
        (out / "tables").mkdir(parents=True, exist_ok=True)
        write_record(out / "tables" / f"{a}.json", learned.to_dict())

    # the same learners on the twin, logged as the physics (the fixed tables and the new ones)
    twin_jobs = [
        LogTrial(
            a,
            c,
            k,
            s.convergence_h,
            s.measured_h,
            arena_runs.digest(a),
            engine,
            arena_runs.tables_digest(tables[a][v].to_dict()),
            tables=tables[a][v].to_dict(),
        )
        for k in range(s.twin_log_trials)
        for a, c in LOG_CELLS
        for engine, v in TWIN_ENGINES
    ]
    twin_logs, _ = s.run_jobs(twin_jobs, LOGS, "twin_logs/trials", provenance_in="twin_logs")
    twin: dict[tuple[str, str, str], list[Mapping[str, Any]]] = {}
    for job in twin_jobs:
        twin.setdefault((job.arena, job.condition, job.engine), []).append(twin_logs[log_key(job)])

    rows: list[Row] = []
    for a, c in LOG_CELLS:
        learned = tables[a]["learners"]
        sources = {
            "physics": physics.get((a, c), []),
            "twin_fixed": twin[(a, c, "twin_fixed")],
            "twin_learners": twin[(a, c, "twin_learners")],
        }
        for engine, results in sources.items():
            for name, values in trial_measures(a, results, learned, s.convergence_h).items():
                rows.append(_ci_row(values, arena=a, condition=c, measure=name, source=engine))
    effects: list[Row] = []
    for k, (a, c) in enumerate(LOG_CELLS):
        committed = list(committed_physics(a, c).values())
        effects.append(_ci_row(committed, arena=a, condition=c, source="physics (committed)"))
        for j, v in enumerate(VARIANTS):
            rng = np.random.default_rng([s.seed, 2, k, j])
            diff = batch_effect(a, tables[a][v], c, s.twin_trials, rng, s)
            effects.append(_ci_row(diff.tolist(), arena=a, condition=c, source=f"twin: {v}"))
    discrepancy = committed_rerun(s)
    body = audit_body(s, rows, effects, discrepancy)
    provenance = run_metadata(settings=s.recorded())
    report = Report(
        "twin_learners",
        "The twin among moving learners: an audit per mechanism",
        body,
        rows,
        summary={"effects": effects, "discrepancy": discrepancy, "settings": s.recorded()},
    )
    written = report.write(out, provenance)
    write_csv(out / "effects.csv", effects)
    return Outcome(out, [*written, out / "effects.csv"], body.split("## Method")[0])


PASSING = "dahl2004_passing"
TOLERANCE = 0.01
"""the passing cells' check: the new twin's fast - slow within this of the physics'"""


def committed_rerun(s: Settings) -> dict[str, Any]:
    """The committed prediction at T = 0.002 (`benchmarks/passing.py --stage predict`: its tables,
    generator [0, 0], 2000 batched trials of 15 h + 5 h) rerun here, against its committed
    per-trial values; the spread of 200-trial means; and 200 trials of the Policy-based twin with
    the same tables (`arena_runs.run_map_trial`, seeds 0-199), as an audit of 200 twin trials
    would run them."""
    condition = "softmax_T0.002"
    committed = [
        float(r["fast_share"]) - float(r["slow_share"])
        for r in read_csv(RESULTS_DIR / "passing_prediction" / "prediction_trials.csv")
        if r["condition"] == condition
    ]
    fixed = fixed_tables(PASSING)
    rerun = arena_runs.run_batch(
        arena_runs.arena_config(PASSING),
        InterferenceTables.from_dict(fixed),
        arena_runs.learner_of(condition),
        len(committed),
        np.random.default_rng([0, 0]),
    )
    diff = rerun.fast_share - rerun.slow_share
    chunks = np.asarray(committed[: len(committed) // 200 * 200]).reshape(-1, 200).mean(axis=1)
    n_policy = 4 if s.quick else 200
    jobs = [
        arena_runs.MapTrial(
            PASSING,
            condition,
            k,
            15.0,
            5.0,
            "twin",
            arena_runs.tables_digest(fixed),
            arena_runs.digest(PASSING),
            fixed,
        )
        for k in range(n_policy)
    ]
    done, _ = s.run_jobs(jobs, arena_runs.TRIALS, "policy_twin/trials", provenance_in="policy_twin")
    policy = arena_runs.diff_of([done[arena_runs.trial_key(j)] for j in jobs])
    m, lo, hi, n = mean_ci(policy)
    return {
        "committed_mean": float(np.mean(committed)),
        "committed_sd": float(np.std(committed, ddof=1)),
        "rerun_mean": float(np.mean(diff)),
        "rerun_identical": bool(np.array_equal(diff, np.asarray(committed))),
        "trials": len(committed),
        "means_of_200": [float(x) for x in chunks],
        "policy_twin": {"mean": m, "low": lo, "high": hi, "n": n},
    }


def _cell(rows: Sequence[Row], digits: int) -> str:
    if not rows:
        return "-"
    r = rows[0]
    return f"{fmt_ci(r['mean'], r['low'], r['high'], digits)} ({r['n']})"


def audit_body(
    s: Settings, rows: Sequence[Row], effects: Sequence[Row], discrepancy: Mapping[str, Any]
) -> str:
    lines = ["## Result", ""]
    for a, c in LOG_CELLS:
        if a != PASSING:
            continue
        got = {r["source"]: r for r in effects if (r["arena"], r["condition"]) == (a, c)}
        physics, new = got["physics (committed)"], got["twin: learners"]
        gap = new["mean"] - physics["mean"]
        lines.append(
            f"- `{a}` `{c}`: physics {_cell([physics], 3)}; the committed twin "
            f"{_cell([got['twin: fixed']], 3)}; the twin among learners {_cell([new], 3)}: "
            f"{gap:+.3f} from the physics, {'within' if abs(gap) <= TOLERANCE else '**not** within'}"
            f" {TOLERANCE}."
        )
    lines += [
        "",
        "Fast - slow, mean [95 % CI] (N trials), physics against the batched twin with each "
        "mechanism alone and all three:",
        "",
    ]
    sources = ["physics (committed)", *(f"twin: {v}" for v in VARIANTS)]
    lines.append(
        markdown_table(
            ["arena", "condition", *sources],
            [
                [
                    a,
                    c,
                    *(
                        _cell(
                            [
                                r
                                for r in effects
                                if (r["arena"], r["condition"], r["source"]) == (a, c, src)
                            ],
                            3,
                        )
                        for src in sources
                    ),
                ]
                for a, c in LOG_CELLS
            ],
        )
    )
    lines += ["", "Tables: " + "; ".join(f"`{v}`: {text}" for v, text in VARIANTS.items()) + "."]
    lines += ["", "## The mechanisms, physics against the twin (logged learner trials)", ""]
    for a, c in LOG_CELLS:
        mine = [r for r in rows if (r["arena"], r["condition"]) == (a, c)]
        names = list(dict.fromkeys(r["measure"] for r in mine))
        shown = [
            name
            for name in names
            if not name.startswith("task s on high")
            or any(
                r["measure"] == name and r["source"] == "physics" and r["n"] >= 100 for r in mine
            )
        ]
        lines += [f"### `{a}`, `{c}`", ""]
        lines.append(
            markdown_table(
                ["measure", *ENGINES],
                [
                    [
                        name,
                        *(
                            _cell(
                                [r for r in mine if r["measure"] == name and r["source"] == e],
                                4 if name.startswith(("Q", "R", "switch", "fast", "lag")) else 1,
                            )
                            for e in ENGINES
                        ),
                    ]
                    for name in shown
                ],
            )
        )
        lines.append("")
    d = discrepancy
    p = d["policy_twin"]
    many = next(
        r
        for r in effects
        if (r["arena"], r["condition"], r["source"]) == (PASSING, "softmax_T0.002", "twin: fixed")
    )
    se = (many["high"] - many["low"]) / 2 / 1.96
    committed_se = d["committed_sd"] / math.sqrt(d["trials"])
    lines += [
        "## The committed twin at T = 0.002: +0.022 committed, +0.042 rerun",
        "",
        f"The committed prediction rerun here (its tables, its generator, {d['trials']} batched "
        f"trials): {d['rerun_mean']:+.4f}, per trial "
        f"{'identical to' if d['rerun_identical'] else '**different from**'} the committed "
        f"values (mean {d['committed_mean']:+.4f}). Its trials in disjoint sets of 200 have "
        f"means from {min(d['means_of_200']):+.3f} to {max(d['means_of_200']):+.3f} (sd "
        f"{float(np.std(d['means_of_200'], ddof=1)):.3f}); 200 trials of the Policy-based twin "
        f"with the same tables give {fmt_ci(p['mean'], p['low'], p['high'], 3)} (N = {p['n']}). "
        f"The same committed twin over {many['n']} trials of another generator (above): "
        f"{fmt_ci(many['mean'], many['low'], many['high'], 3)}. So nothing differs but the "
        "generator and the number of trials: tables, code and seeds reproduce the committed "
        "+0.022 exactly, and the twin's mean at T = 0.002 is about "
        f"{many['mean']:+.3f}; the committed 2000-trial mean lies "
        f"{(many['mean'] - d['committed_mean']) / math.hypot(se, committed_se):.1f} standard "
        "errors of the difference below it (a per-trial sd of about 0.3 leaves a 2000-trial "
        "mean +-0.013), while the +0.042 of an earlier audit's 200-trial rerun agrees with "
        "the twin's mean: the committed +0.022 was the low draw.",
        "",
        "## Method",
        "",
        f"Physics: the logged learner trials (`--stage logs`: {', '.join(f'{a} {c} x {n}' for (a, c), n in LOG_CELLS.items())}, "
        f"seeds 0, 1, ...: the committed trials' seeds and trajectories). Learner tables "
        "(`tavc_env.twin.learner_tables`): own-circuit tasks after the first, by the cell at "
        "decision, where a cell has 20 or more; switch costs per class against those cells; "
        f"first tasks from {s.start_runs} physics starts per arena (random first choices, as a "
        "learner with equal Q entries makes them), by cell where it has 5 or more, else by "
        f"class and kind. Twin: {s.twin_log_trials} logged Policy-based twin trials per cell "
        f"and tables; {s.twin_trials} batched trials per cell and tables for fast - slow. Task "
        "times and first tasks: mean over tasks; R (a class's mean own-task time on the "
        "high-value circuit over the other's), switch costs, Q levels and fast - slow: mean over "
        "trials; Student-t 95 % intervals, N in brackets.",
        "",
    ]
    return "\n".join(lines)


# -- stage 3: the pre-registered predictions; stage 4: their physics -----------------------------------
OUT_OF_SAMPLE: tuple[tuple[str, str], ...] = (
    ("dahl2004_passing", "softmax_T0.003"),
    ("dahl2004_passing", "softmax_T0.005_paper"),
    ("dahl2004_passing", "softmax_T0.005_equal"),
    ("dahl2004", "softmax_T0.003"),
    ("dahl2004_congestion", "softmax_T0.005_equal"),
)
"""(arena, condition) of the out-of-sample cells: a temperature the twin was not built on, the
paper's literal initialisation, equal fixed Q levels, and other arenas; no physics trial of any of
them had run when their predictions were committed."""


def planned_trials(needed: float, least: int, most: int) -> int:
    """A cell's physics trials: what 80 % power asks (`needed`; infinite: `most`), within
    [`least`, `most`]."""
    wanted = most if not math.isfinite(needed) else math.ceil(needed)
    return min(max(wanted, least), most)


def learned_tables(arena: str, s: Settings) -> InterferenceTables:
    """The arena's tables among learners as the audit wrote them (its output folder's, else the
    committed ones)."""
    here = s.out_dir() / "tables" / f"{arena}.json"
    path = here if here.exists() else RESULTS_DIR / "twin_learners" / "tables" / f"{arena}.json"
    return InterferenceTables.from_dict(read_record(path))


def run_predict(s: Settings) -> Outcome:
    out = s.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    rows: list[Row] = []
    per_trial: list[Row] = []
    for k, (a, c) in enumerate(OUT_OF_SAMPLE):
        row: Row = {"arena": a, "condition": c}
        for j, (name, tables) in enumerate(
            (
                ("learners", learned_tables(a, s)),
                ("fixed", InterferenceTables.from_dict(fixed_tables(a))),
            )
        ):
            diff = batch_effect(
                a, tables, c, s.twin_trials, np.random.default_rng([s.seed, 3, k, j]), s
            )
            m, lo, hi, _ = mean_ci(diff.tolist())
            sd = float(np.std(diff, ddof=1))
            row |= {f"{name}": m, f"{name}_low": lo, f"{name}_high": hi, f"{name}_sd": sd}
            if name == "learners":  # the prediction's trials (the fixed tables' are context)
                per_trial += [
                    {"arena": a, "condition": c, "trial": t, "fast_minus_slow": float(v)}
                    for t, v in enumerate(diff)
                ]
        row["twin_trials"] = s.twin_trials
        needed = arena_runs.trials_for_power(row["learners_sd"], row["learners"])
        row["trials_for_80_power"] = needed
        row["physics_trials"] = planned_trials(needed, s.min_physics, s.max_physics)
        rows.append(row)
    write_csv(out / "prediction_trials.csv", per_trial)
    body = prediction_body(s, rows)
    report = Report(
        "prediction",
        "The twin among learners, out of sample: predictions before their physics",
        body,
        rows,
        summary={"cells": rows, "settings": s.recorded()},
    )
    written = report.write(out, run_metadata(settings=s.recorded()))
    return Outcome(out, [out / "prediction_trials.csv", *written], body.split("## Method")[0])


def prediction_body(s: Settings, rows: Sequence[Row]) -> str:
    table = markdown_table(
        [
            "arena",
            "condition",
            "twin among learners: fast - slow (95 % CI)",
            "per-trial sd",
            "trials for 80 % power",
            "physics trials planned",
            "committed twin (fixed tables)",
        ],
        [
            [
                r["arena"],
                r["condition"],
                fmt_ci(r["learners"], r["learners_low"], r["learners_high"], 3),
                f"{r['learners_sd']:.3f}",
                "inf"
                if not math.isfinite(r["trials_for_80_power"])
                else math.ceil(r["trials_for_80_power"]),
                r["physics_trials"],
                fmt_ci(r["fixed"], r["fixed_low"], r["fixed_high"], 3),
            ]
            for r in rows
        ],
    )
    return "\n".join(
        [
            "## Prediction",
            "",
            table,
            "",
            "Committed before any physics trial of these cells ran; `--stage test` runs exactly "
            "the planned trials (seeds 0, 1, ...).",
            "",
            "## Method",
            "",
            f"The batched twin with the tables among learners (`--stage audit`'s `tables/`), "
            f"{s.twin_trials} trials per cell of {s.convergence_h:g} h + {s.measured_h:g} h, the "
            "cell's learner (`LEARNERS`: `_paper` the paper's U(-0.1, 0.1), `_equal` every Q "
            "entry at 0, otherwise the scaled initialisation). Fast - slow per trial as "
            "`benchmarks/passing.py` measures it; mean with a Student-t 95 % interval. Physics "
            "trials: what 80 % power in a two-sided 5 % test of the predicted effect asks, "
            f"((z_0.975 + z_0.80) sd / d)^2, within [{s.min_physics}, {s.max_physics}]. The "
            "committed twin's (fixed-allocation tables) prediction beside it, for comparison.",
            "",
        ]
    )


def reward_shape(s: Settings) -> list[Row]:
    """A check on the twin's one assumption about a task time's shape: what a learner is paid is
    w / t, so what matters is E[1/t], which the twin takes from its lognormal (moments matched to
    the cell). Per logged arena and class, over own-circuit tasks after the first of the logged
    physics trials: E[1/t] on the high-value circuit and on the others, in physics and by the
    learner tables' lognormal of each task's own cell, and the ratio low / high that the choice
    turns on. In sample (the tables come from these logs): it tests the shape, not the cells."""
    physics = physics_logs(s)
    rows: list[Row] = []
    for arena in dict.fromkeys(a for a, _ in LOG_CELLS):
        tables = learned_tables(arena, s)
        config = arena_runs.arena_config(arena)
        high = int(np.argmax([c.value for c in config.circuits]))
        tasks = [
            t
            for (logged, _), results in physics.items()
            if logged == arena
            for r in results
            for t in trial_tasks(arena, r)
        ]
        for cls in tables.classes:
            own = [t for t in tasks if _own(t, cls)]
            row: Row = {"arena": arena, "class": cls, "tasks": len(own)}
            for side, keep in (("high", True), ("low", False)):
                picked = [t for t in own if (t.circuit == high) == keep]
                cells = [tables.cell(t.circuit, t.counts, cls).lognormal() for t in picked]
                row[f"physics_{side}"] = float(np.mean([1.0 / t.task_time_s for t in picked]))
                row[f"twin_{side}"] = float(
                    np.mean([math.exp(sd * sd / 2 - mu) for mu, sd in cells])
                )
            for who in ("physics", "twin"):
                row[f"{who}_ratio"] = row[f"{who}_low"] / row[f"{who}_high"]
            rows.append(row)
    return rows


def run_test(s: Settings) -> Outcome:
    cells = read_report(s.prediction)["summary"]["cells"]
    if s.quick:  # a smoke run: the plan's cells, a few trials each
        cells = [
            {**c, "physics_trials": min(int(c["physics_trials"]), s.max_physics)} for c in cells
        ]
    most = max(int(c["physics_trials"]) for c in cells)
    jobs = [
        LogTrial(
            c["arena"],
            c["condition"],
            int(c.get("first_seed", 0)) + k,
            s.convergence_h,
            s.measured_h,
            arena_runs.digest(c["arena"]),
            keep_log=False,
        )
        for k in range(most)
        for c in cells
        if k < int(c["physics_trials"])
    ]
    planned = len(jobs)
    if s.interim:
        jobs = [j for j in jobs if is_saved(s.out_dir() / "trials" / f"{log_key(j)}.json")]
    results, provenance = s.run_jobs(jobs, LOGS, "trials", wall_of=lambda r: float(r["wall_s"]))
    rows: list[Row] = []
    for c in cells:
        diff = [
            float(results[log_key(j)]["fast_share"]) - float(results[log_key(j)]["slow_share"])
            for j in jobs
            if (j.arena, j.condition) == (c["arena"], c["condition"]) and log_key(j) in results
        ]
        m, lo, hi, n = mean_ci(diff)
        inside = lo <= c["learners"] <= hi
        rows.append(
            {
                "arena": c["arena"],
                "condition": c["condition"],
                "physics": m,
                "physics_low": lo,
                "physics_high": hi,
                "trials": n,
                "planned": c["physics_trials"],
                "predicted": c["learners"],
                "predicted_low": c["learners_low"],
                "predicted_high": c["learners_high"],
                "fixed": math.nan if c.get("fixed") is None else float(c["fixed"]),
                "prediction_inside": inside,
            }
        )
    table = markdown_table(
        [
            "arena",
            "condition",
            "N (planned)",
            "physics fast - slow",
            "predicted (learners)",
            "inside",
            "committed twin",
        ],
        [
            [
                r["arena"],
                r["condition"],
                f"{r['trials']} ({r['planned']})",
                fmt_ci(r["physics"], r["physics_low"], r["physics_high"], 3),
                fmt_ci(r["predicted"], r["predicted_low"], r["predicted_high"], 3),
                "yes" if r["prediction_inside"] else "**no**",
                fmt(r["fixed"], 3),
            ]
            for r in rows
        ],
    )
    searched = s.reference_name() == "twin_search_test"  # the search's cell, not the audit's
    shape = [] if searched else reward_shape(s)
    shape_table = markdown_table(
        [
            "arena",
            "class",
            "tasks",
            "E[1/t] high: physics / twin",
            "E[1/t] low: physics / twin",
            "low / high: physics",
            "twin",
        ],
        [
            [
                r["arena"],
                r["class"],
                r["tasks"],
                f"{r['physics_high']:.6f} / {r['twin_high']:.6f}",
                f"{r['physics_low']:.6f} / {r['twin_low']:.6f}",
                f"{r['physics_ratio']:.4f}",
                f"{r['twin_ratio']:.4f}",
            ]
            for r in shape
        ],
    )
    done = len(results)
    status = (
        "All planned trials are in."
        if done >= planned
        else f"**Interim: {done} of {planned} planned trials.** The same command resumes."
    )
    body = "\n".join(
        [
            "## Result",
            "",
            status,
            "",
            table,
            "",
            "## Method",
            "",
            "Physics trials of the committed plan, trial k of a cell with seed k (from the "
            "plan's first seed, if it names one); fast - slow mean with a Student-t 95 % "
            "interval; 'inside': the twin's prediction lies in the physics interval.",
            "",
        ]
    )
    if not searched:
        body += "\n" + "\n".join(
            [
                "## A check on the misses: the shape of a task time",
                "",
                "A learner is paid w / t, so its choice turns on E[1/t] per circuit, which the twin "
                "takes from the lognormal of each cell (moments matched). Over the logged physics "
                "trials' own-circuit tasks after the first, per arena and class: E[1/t] on the "
                "high-value circuit and on the others, in physics and by the learner tables' "
                "lognormal of each task's own cell (`reward_shape`; in sample, so it tests the "
                "shape, not the cells):",
                "",
                shape_table,
                "",
            ]
        )
    report = Report(
        "test",
        "The search's pre-registered cell: the physics"
        if searched
        else "The twin among learners, out of sample: the physics",
        body,
        rows,
        summary={"trials_saved": done, "cells": rows, "reward_shape": shape},
    )
    written = report.write(s.out_dir(), provenance)
    return Outcome(s.out_dir(), written, body.split("## Method")[0])


# -- stage 7: why the twin misses dahl2004 -----------------------------------------------------------
GAP_CELLS: tuple[tuple[str, str], ...] = (
    ("dahl2004", "softmax_T0.005"),
    ("dahl2004", "softmax_T0.003"),
    ("dahl2004_passing", "softmax_T0.005"),
)
"""(arena, condition): dahl2004 at the audit's temperature and at the missed out-of-sample cell's;
the passing arena, where the twin held, as the control"""
GAP_FIRST_SEED = 10000
"""the gap stage's trials take seeds 10000, 10001, ...: none of them has run in a committed study
(those use seeds below 1500), so they are a fresh sample of each cell"""
GAP_EFFECT = 0.05
"""the paired difference (twin-paid - physics) that the gap stage detects with 80 % power: about
the twin's miss on dahl2004 once the physics is measured on more trials (an uncommitted probe
put it at 0.05-0.06; the committed T = 0.003 miss, -0.116 against -0.010 over 100 trials, is
larger)"""
GAP_ENGINES: tuple[Engine, ...] = ("physics", "physics_twin_paid", "physics_corrected_pay")
"""each gap seed on the physics, paid as the twin pays, and paid so with the measured factors"""
GAP_PERIODS_H: tuple[tuple[float, float], ...] = ((0.0, 1.0), (1.0, 3.0), (3.0, math.inf))
"""the periods of a trial (decision time, hours) over which the gap stage compares task times
with their cells: the first hour, the next two, the rest (a trial's share locks in early)"""


def gap_trials(s: Settings) -> int:
    """Pairs per gap cell: 80 % power for `GAP_EFFECT` in a paired difference whose pairs are
    taken as independent (conservative: sd sqrt(2) times the committed dahl2004 T = 0.005
    physics trials' sd), within [`min_physics`, `max_physics`]."""
    sd = float(np.std(list(committed_physics("dahl2004", "softmax_T0.005").values()), ddof=1))
    return planned_trials(
        arena_runs.trials_for_power(math.sqrt(2.0) * sd, GAP_EFFECT), s.min_physics, s.max_physics
    )


def period_of(decided_s: float) -> int:
    """The index of the period (`GAP_PERIODS_H`) a task decided at `decided_s` falls in."""
    return next(k for k, (a, b) in enumerate(GAP_PERIODS_H) if decided_s < b * 3600.0)


def task_kind(circuit: int, switch: bool, high: int) -> str:
    """What kind of task: staying on or switching into the high-value circuit (`high`) or the
    others."""
    where = "high" if circuit == high else "low"
    return f"into {where}" if switch else f"stay {where}"


def paid_ratios(
    arena: str, result: Mapping[str, Any], tables: InterferenceTables
) -> list[tuple[ObservedTask, int, float, float]]:
    """Each task of a logged trial after its robot's first: the task, its robot, when it was
    delivered, and its time over what the twin draws for its cell on average (the cell's mean,
    times the class's switch cost for a switch)."""
    log = result["log"]
    deliveries = sorted(
        zip(
            log["delivery_time_s"],
            log["delivery_robot"],
            log["delivery_circuit"],
            log["delivery_task_time_s"],
        )
    )  # `logged_tasks`' order: task k is delivery k
    out = []
    for task, (done, robot, _, _) in zip(trial_tasks(arena, result), deliveries):
        if task.first:
            continue
        expected = tables.cell(task.circuit, task.counts, task.robot_class).mean_s
        if task.switch:
            expected *= tables.class_switch_cost(task.robot_class)
        out.append((task, int(robot), float(done), task.task_time_s / expected))
    return out


PaidRatios = Sequence[tuple[ObservedTask, int, float, float]]
"""one logged trial's `paid_ratios`"""


def cell_residuals(arena: str, trials: Sequence[PaidRatios]) -> list[Row]:
    """Per class, kind of task (`task_kind`) and period (`GAP_PERIODS_H`, by when it was
    decided), the physics task time over what the twin draws for its cell on average (each
    trial's `paid_ratios`): mean per trial, then mean and 95 % interval over trials."""
    config = arena_runs.arena_config(arena)
    high = int(np.argmax([c.value for c in config.circuits]))
    per_trial: dict[tuple[str, str, int], list[float]] = {}
    for trial in trials:
        ratios: dict[tuple[str, str, int], list[float]] = {}
        for task, _, done, ratio in trial:
            decided = done - task.task_time_s
            kind = task_kind(task.circuit, task.switch, high)
            key = (task.robot_class, kind, period_of(decided))
            ratios.setdefault(key, []).append(ratio)
        for key, values in ratios.items():
            per_trial.setdefault(key, []).append(float(np.mean(values)))
    rows = []
    for (cls, kind, period), values in sorted(per_trial.items()):
        a, b = GAP_PERIODS_H[period]
        rows.append(
            _ci_row(
                values,
                arena=arena,
                robot_class=cls,
                kind=kind,
                period=period,
                period_h=f"{a:g}-{b:g}",
            )
        )
    return rows


CONVOY_WINDOW_S = 30.0
"""two deliveries on one circuit this close in time, by different robots, count as one behind
the other (a dock's service and a short queue's step take about this long)"""


def convoy_correlations(arena: str, trials: Sequence[PaidRatios]) -> list[Row]:
    """Per pair of classes (a robot's delivery, then the next delivery on the same circuit, by
    another robot within `CONVOY_WINDOW_S`), the correlation of the two tasks' log time over the
    twin's mean (each trial's `paid_ratios`): per trial (10 pairs or more), then the mean and
    95 % interval over trials, with the pairs in all. The twin draws every task on its own: 0
    there by construction."""
    per_trial: dict[str, list[float]] = {}
    counted: dict[str, int] = {}
    for trial in trials:
        on: dict[int, list[tuple[float, int, str, float]]] = {}
        for task, robot, done, ratio in trial:
            on.setdefault(task.circuit, []).append((done, robot, task.robot_class, math.log(ratio)))
        pairs: dict[str, list[tuple[float, float]]] = {}
        for items in on.values():
            items.sort()
            for (d0, r0, c0, x0), (d1, r1, c1, x1) in itertools.pairwise(items):
                if r0 != r1 and d1 - d0 <= CONVOY_WINDOW_S:
                    pairs.setdefault(f"{c0}, then {c1}", []).append((x0, x1))
        for kind, xy in pairs.items():
            counted[kind] = counted.get(kind, 0) + len(xy)
            if len(xy) >= 10:
                x = np.array(xy)
                per_trial.setdefault(kind, []).append(float(np.corrcoef(x[:, 0], x[:, 1])[0, 1]))
    return [
        _ci_row(v, arena=arena, pair=kind, pairs=counted[kind])
        for kind, v in sorted(per_trial.items())
    ]


def run_gap(s: Settings) -> Outcome:
    out = s.out_dir()
    n = gap_trials(s)
    tables = {a: learned_tables(a, s) for a in dict.fromkeys(a for a, _ in GAP_CELLS)}
    # the audit's logged physics trials at T = 0.005, each task's time over the twin's mean
    logged = {
        a: [paid_ratios(a, r, tables[a]) for r in results]
        for (a, c), results in physics_logs(s).items()
        if c == "softmax_T0.005" and a in tables
    }
    residuals = [row for a, trials in logged.items() for row in cell_residuals(a, trials)]
    factors = {
        a: tuple(
            (r["robot_class"], r["kind"], int(r["period"]), float(r["mean"]))
            for r in residuals
            if r["arena"] == a
        )
        for a in tables
    }
    jobs = [
        LogTrial(
            a,
            c,
            GAP_FIRST_SEED + k,
            s.convergence_h,
            s.measured_h,
            arena_runs.digest(a),
            engine=engine,
            tables_sha256=""
            if engine == "physics"
            else arena_runs.tables_digest(tables[a].to_dict()),
            keep_log=False,
            pay_factors=factors[a] if engine == "physics_corrected_pay" else (),
            tables=None if engine == "physics" else tables[a].to_dict(),
        )
        for k in range(n)
        for a, c in GAP_CELLS
        for engine in GAP_ENGINES
    ]
    results, provenance = s.run_jobs(jobs, LOGS, "trials", wall_of=lambda r: float(r["wall_s"]))

    def diff(job: LogTrial) -> float:
        r = results[log_key(job)]
        return float(r["fast_share"]) - float(r["slow_share"])

    by_seed = {(j.arena, j.condition, j.engine, j.seed): diff(j) for j in jobs}
    rows: list[Row] = []
    for k, (a, c) in enumerate(GAP_CELLS):
        seeds = sorted({j.seed for j in jobs if (j.arena, j.condition) == (a, c)})
        true, paid, corrected = (
            np.array([by_seed[(a, c, engine, seed)] for seed in seeds]) for engine in GAP_ENGINES
        )
        twin = batch_effect(
            a, tables[a], c, s.twin_trials, np.random.default_rng([s.seed, 7, k]), s
        )
        committed = list(committed_physics(a, c).values())
        row: Row = {"arena": a, "condition": c, "pairs": len(seeds)}
        for name, values in (
            ("physics", true),
            ("twin_paid", paid),
            ("paired_difference", paid - true),
            ("corrected", corrected),
            ("corrected_difference", corrected - true),
            ("twin", twin),
            ("committed_physics", committed),
        ):
            m, lo, hi, count = mean_ci(list(map(float, values)))
            row |= {name: m, f"{name}_low": lo, f"{name}_high": hi, f"{name}_n": count}
        row["pair_correlation"] = float(np.corrcoef(true, paid)[0, 1])
        rows.append(row)
    convoys = [row for a, trials in logged.items() for row in convoy_correlations(a, trials)]
    write_csv(out / "gap_residuals.csv", residuals)
    write_csv(out / "gap_convoys.csv", convoys)
    body = gap_body(s, n, rows, residuals, convoys)
    report = Report(
        "gap",
        "Why the twin misses dahl2004: the physics paid as the twin pays",
        body,
        rows,
        summary={"cells": rows, "residuals": residuals, "convoys": convoys, "pairs_per_cell": n},
    )
    report.figures.append((GAP_FIGURE, lambda path: draw_gap(path, rows)))
    written = report.write(out, provenance)
    csvs = [out / "gap_residuals.csv", out / "gap_convoys.csv"]
    return Outcome(out, [*csvs, *written], body.split("## Method")[0])


GAP_FIGURE = "gap.png"
GAP_SERIES = (
    ("physics", "physics", "o", "black"),
    ("twin_paid", "physics paid as the twin pays", "s", "tab:red"),
    ("corrected", "the same, times the measured factors", "D", "tab:orange"),
    ("twin", "twin among learners", "^", "tab:blue"),
)
"""(row field, label, marker, colour) of the gap figure's series"""


def draw_gap(path: Path, rows: Sequence[Row]) -> None:
    """Per gap cell, fast - slow in the physics, in the physics paid as the twin pays (without and
    with the measured factors), and in the twin; 95 % intervals."""
    fig, ax = subplots(figsize=(8.6, 3.4))
    for k, (field_name, label, marker, colour) in enumerate(GAP_SERIES):
        x = np.arange(len(rows)) + 0.12 * (k - 1.5)
        m = np.array([r[field_name] for r in rows])
        err = [
            m - [r[f"{field_name}_low"] for r in rows],
            [r[f"{field_name}_high"] for r in rows] - m,
        ]
        ax.errorbar(x, m, yerr=err, fmt=marker, ms=5, color=colour, label=label)
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xticks(
        np.arange(len(rows)),
        [f"{r['arena']}\nT = {LEARNERS[r['condition']].temperature:g}" for r in rows],
    )
    ax.set_ylabel("fast - slow (hours 15-20)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


def gap_body(
    s: Settings,
    n: int,
    rows: Sequence[Row],
    residuals: Sequence[Row],
    convoys: Sequence[Row],
) -> str:
    def ci(r: Row, name: str) -> str:
        return fmt_ci(r[name], r[f"{name}_low"], r[f"{name}_high"], 3)

    table = markdown_table(
        [
            "arena",
            "condition",
            "pairs",
            "physics",
            "physics, twin-paid",
            "paired difference",
            "physics, paid with the factors",
            "its paired difference",
            "twin among learners",
            "committed physics (N)",
        ],
        [
            [
                r["arena"],
                r["condition"],
                r["pairs"],
                ci(r, "physics"),
                ci(r, "twin_paid"),
                ci(r, "paired_difference"),
                ci(r, "corrected"),
                ci(r, "corrected_difference"),
                ci(r, "twin"),
                f"{ci(r, 'committed_physics')} ({r['committed_physics_n']})",
            ]
            for r in rows
        ],
    )
    residual_table = markdown_table(
        [
            "arena",
            "class",
            "task",
            "decided in (h)",
            "physics time / twin's mean (95 % CI)",
            "trials",
        ],
        [
            [
                r["arena"],
                r["robot_class"],
                r["kind"],
                r["period_h"],
                fmt_ci(r["mean"], r["low"], r["high"], 3),
                r["n"],
            ]
            for r in residuals
        ],
    )
    convoy_table = markdown_table(
        ["arena", "deliveries, one right behind the other", "pairs", "correlation (95 % CI)"],
        [
            [r["arena"], r["pair"], r["pairs"], fmt_ci(r["mean"], r["low"], r["high"], 3)]
            for r in convoys
        ],
    )
    return "\n".join(
        [
            "## Result",
            "",
            "Fast - slow share of the high-value circuit (hours "
            f"{s.convergence_h:g}-{s.convergence_h + s.measured_h:g}), mean and 95 % interval:",
            "",
            table,
            "",
            "## What the twin's pay leaves out",
            "",
            "Physics task times among learners (the audit's logged trials at T = 0.005) over the "
            "time the twin draws for the same cell on average, after each robot's first task, by "
            "class, kind of task and when it was decided (a trial's mean, then the mean over "
            "trials):",
            "",
            residual_table,
            "",
            "## How task times hang together",
            "",
            "Two deliveries on one circuit by different robots at most "
            f"{CONVOY_WINDOW_S:g} s apart, in the same logged trials: the correlation of the two "
            "tasks' log time over the twin's mean (per trial with 10 pairs or more, then the mean "
            "over trials; the twin draws each task on its own, so 0 there):",
            "",
            convoy_table,
            "",
            "## Method",
            "",
            f"Each cell runs {n} seeds of physics trials, fresh ({GAP_FIRST_SEED} on; the "
            "committed studies use seeds below 1500): the physics as it is, and the same seed on "
            "`tavc_env.twin.TwinPaidArenaEnv`, where robots move and decide as in the physics but "
            "every task's reward is paid with a time drawn from the twin's learner tables for its "
            "cell at decision. Same seed, same start and same first choices; the trials part once the "
            "first rewards differ. The pairs follow from 80 % power for a paired difference of "
            f"{GAP_EFFECT:g} (`gap_trials`). 'twin among learners': "
            f"{s.twin_trials} batched twin trials on the same tables.",
            "",
            "What each outcome would mean (stated before the trials ran): if the twin's task "
            "times are what it gets wrong, the twin-paid physics lands on the twin's value and "
            "the paired difference on dahl2004 is the twin's gap (twin - physics), while on the "
            "passing arena, where the twin held, it is near 0. If the twin-paid physics stays "
            "at the physics, the miss lies in how the twin moves robots or times decisions, not "
            "in what it pays.",
            "",
            "A third run of each seed, added once the first two had run and stated before its "
            "own trials ran (`CorrectedPayEnv`), pays the twin's draw times the measured factor "
            "of the task's class, kind and period (the second table, its arena's; a robot's "
            "first task unfactored; dahl2004 at T = 0.003 takes the factors measured at "
            "T = 0.005). If those effects are all that the twin's pay leaves out, this run lands "
            "back on the physics (its paired difference near 0); if they are part of it, between "
            "the physics and the twin-paid run; if none, on the twin-paid run.",
            "",
        ]
    )


# -- stage 5: the search for the paper's condition (its rule: docs/results/differentiation.md) ------
SEARCH_PREMIUM = 1.1
"""the high-value circuit's premium per second of task time the search's values keep (2200 /
2000 on equal lanes)"""
FAMILY_TABLE_SEEDS = (0, 1, 2)
FAMILY_TABLE_HOURS = 1.0


def split_times(tables: InterferenceTables) -> tuple[float, float]:
    """The mean task time of the whole team on the high-value circuit (0) and on the low-value
    one (1) in the 3 + 3 split: one class on each, both ways round (each class alone in its own
    cell, every robot weighted alike)."""
    classes, team = tables.classes, tables.team

    def alone(circuit: int, k: int) -> float:
        counts = tuple(n if j == k else 0 for j, n in enumerate(team))
        return tables.cell(circuit, counts, classes[k]).mean_s

    def split(circuit: int) -> float:
        return sum(n * alone(circuit, k) for k, n in enumerate(team)) / sum(team)

    return split(0), split(1)


def low_value_of(tables: InterferenceTables) -> float:
    """The search's value of the low-value circuit: the high-value one's 2200 over
    `SEARCH_PREMIUM`, scaled by the split's task times (low over high), rounded to 10."""
    t_high, t_low = split_times(tables)
    return float(round(2200.0 / SEARCH_PREMIUM * t_low / t_high, -1))


def fixed_ratios(tables: InterferenceTables) -> dict[str, float]:
    """Per class R = task time on the high-value circuit over the low-value one under fixed
    allocations: the mean over the mixed cells of 1 + 2 and 2 + 1 robots (the same crowd on
    both circuits)."""
    return {
        cls: float(
            np.mean(
                [
                    tables.cell(0, counts, cls).mean_s / tables.cell(1, counts, cls).mean_s
                    for counts in ((1, 2), (2, 1))
                ]
            )
        )
        for cls in tables.classes
    }


def run_family(s: Settings) -> Outcome:
    """The search's arenas measured in physics, no learner: each arena's fixed-allocation
    tables, the low-value circuit's value the rule gives, and R per class under fixed
    allocations."""
    jobs = [
        arena_runs.TablesJob(a, FAMILY_TABLE_SEEDS, FAMILY_TABLE_HOURS, arena_runs.digest(a))
        for a in arena_runs.SEARCH_ARENAS
    ]
    measured, provenance = s.run_jobs(jobs, arena_runs.TABLES, "tables")
    rows: list[Row] = []
    for job, lane in zip(jobs, arena_runs.SEARCH_LANES):
        tables = InterferenceTables.from_dict(measured[arena_runs.TABLES.key(job)])
        t_high, t_low = split_times(tables)
        ratios = fixed_ratios(tables)
        order = "R_fast < R_slow" if ratios["fast"] < ratios["slow"] else "R_fast >= R_slow"
        rows.append(
            {
                "arena": job.arena,
                "lane": lane,
                "t_high_s": t_high,
                "t_low_s": t_low,
                "low_value": low_value_of(tables),
                **{f"R_{cls}": r for cls, r in ratios.items()},
                "fixed_order": order,
            }
        )
    body = family_body(rows)
    report = Report(
        "family",
        "The search's arenas in physics, before any learner: values and R under fixed allocations",
        body,
        rows,
        summary={"arenas": rows, "settings": s.recorded()},
    )
    written = report.write(s.out_dir(), provenance)
    return Outcome(s.out_dir(), written, body)


def family_body(rows: Sequence[Row]) -> str:
    header = [
        "arena",
        "low lane / high lane",
        "3 + 3 split: t high, t low (s)",
        "low-value circuit's w",
        "R fast (fixed)",
        "R slow (fixed)",
        "under fixed allocations",
    ]
    table = markdown_table(
        header,
        [
            [
                r["arena"],
                f"{r['lane']:g}",
                f"{r['t_high_s']:.1f}, {r['t_low_s']:.1f}",
                f"{r['low_value']:.0f}",
                f"{r['R_fast']:.3f}",
                f"{r['R_slow']:.3f}",
                r["fixed_order"],
            ]
            for r in rows
        ],
    )
    return (
        "The search for the paper's condition (its rule, committed before this ran: "
        "docs/results/differentiation.md) varies the passing arena's low-value lane. This stage "
        "measures each arena in physics with fixed allocations only (no learner has run on any "
        f"of them): the twin's tables ({len(FAMILY_TABLE_SEEDS)} seeds x "
        f"{FAMILY_TABLE_HOURS:g} h per allocation), the 3 + 3 split's mean task times on each "
        "circuit, the low-value circuit's value that keeps the high-value one's premium per "
        f"second at {SEARCH_PREMIUM:g} (2200 / {SEARCH_PREMIUM:g} x t low / t high, rounded to "
        "10), and each class's R = t(high) / t(low) in the mixed cells (1 + 2 and 2 + 1 robots, "
        "the same crowd on both circuits). The paper's direction needs R_fast < R_slow among "
        "moving learners; these are the fixed-allocation values, before any learner.\n\n" + table
    )


SEARCH_CONDITIONS = ("softmax_T0.002", "softmax_T0.005")
"""the search map's learners (the rule's 8 cells: these x the four arenas)"""
SEARCH_LOG_CONDITION = "softmax_T0.005"
SEARCH_LOG_TRIALS = 30
"""physics learner trials per arena that the learner tables are measured from (seeds 0-29)"""
SEARCH_TWIN_TRIALS = 2000
"""batched twin trials per cell of the map"""
SEARCH_FIRST_SEED = 20000
"""the first seed of a pre-registered cell's physics: fresh, never a calibration trial's"""
SEARCH_MAX_PHYSICS = 3000


def search_log_jobs(s: Settings) -> list[LogTrial]:
    """The search's calibration: physics learner trials in each of its arenas, seed by seed."""
    return [
        LogTrial(a, SEARCH_LOG_CONDITION, k, s.convergence_h, s.measured_h, arena_runs.digest(a))
        for k in range(s.log_trials or SEARCH_LOG_TRIALS)
        for a in arena_runs.SEARCH_LEARNER_ARENAS
    ]


def family_tables(s: Settings, table_arena: str) -> InterferenceTables:
    """An arena's fixed-allocation tables as the family stage measured them."""
    here = s.out_dir() / "tables" / f"tables_{table_arena}.json"
    path = here if here.exists() else RESULTS_DIR / "twin_search" / "tables" / here.name
    return InterferenceTables.from_dict(read_saved(path)["result"])


def run_search(s: Settings) -> Outcome:
    """The search's calibration, its map and its decision, by its committed rule: per arena the
    physics learner trials and first tasks that the learner tables come from; per cell the twin
    among learners' fast - slow (batched) and R per class (logged twin trials); the candidate
    cells, and the pre-registered plan of the best one (prediction.json), if any."""
    out = s.out_dir()
    logs = search_log_jobs(s)
    physics, provenance = s.run_jobs(
        logs, LOGS, "logs/trials", provenance_in="logs", wall_of=lambda r: float(r["wall_s"])
    )  # (the folder's own provenance.json is the family stage's)
    arenas = arena_runs.SEARCH_LEARNER_ARENAS
    starts_of = start_tasks(s, arenas)
    learned: dict[str, InterferenceTables] = {}
    calibration: dict[str, list[Mapping[str, Any]]] = {}
    for a, table_arena in zip(arenas, arena_runs.SEARCH_ARENAS):
        calibration[a] = [physics[log_key(j)] for j in logs if j.arena == a]
        tasks = [t for r in calibration[a] for t in trial_tasks(a, r)]
        starts = starts_of[a]
        # (a smoke run's few trials cannot fill a cell of 20 tasks: it asks for 2)
        least = 2 if s.quick else 20
        fixed = family_tables(s, table_arena)
        learned[a] = learner_tables(fixed, tasks, starts, min_tasks=least, min_first=min(least, 5))
        (out / "learner_tables").mkdir(parents=True, exist_ok=True)
        write_record(out / "learner_tables" / f"{a}.json", learned[a].to_dict())
    cells = [(a, c) for a in arenas for c in SEARCH_CONDITIONS]
    twin_jobs = [
        LogTrial(
            a,
            c,
            k,
            s.convergence_h,
            s.measured_h,
            arena_runs.digest(a),
            "twin_learners",
            arena_runs.tables_digest(learned[a].to_dict()),
            tables=learned[a].to_dict(),
        )
        for k in range(s.twin_log_trials)
        for a, c in cells
    ]
    twin_logs, _ = s.run_jobs(twin_jobs, LOGS, "twin_logs/trials", provenance_in="twin_logs")
    rows: list[Row] = []
    for k, (a, c) in enumerate(cells):
        lane = arena_runs.SEARCH_LANES[arenas.index(a)]
        high = int(np.argmax([x.value for x in arena_runs.arena_config(a).circuits]))
        diff = batch_effect(
            a,
            learned[a],
            c,
            min(s.twin_trials, SEARCH_TWIN_TRIALS),
            np.random.default_rng([s.seed, 5, k]),
            s,
        )
        m, lo, hi, _ = mean_ci(diff.tolist())
        twin_r = [
            time_ratios(trial_tasks(a, twin_logs[log_key(j)]), high)
            for j in twin_jobs
            if (j.arena, j.condition) == (a, c)
        ]
        row: Row = {
            "arena": a,
            "lane": lane,
            "condition": c,
            "learners": m,
            "learners_low": lo,
            "learners_high": hi,
            "learners_sd": float(np.std(diff, ddof=1)),
            "twin_trials": len(diff),
            **{
                f"twin_R_{cls}": float(np.nanmean([r[cls] for r in twin_r]))
                for cls in ("fast", "slow")
            },
        }
        if c == SEARCH_LOG_CONDITION:  # the calibration trials: reported, deciding nothing
            measures = trial_measures(a, calibration[a], learned[a], s.convergence_h)
            pm, plo, phi, pn = mean_ci(measures["fast - slow"])
            row |= {
                "calibration_physics": pm,
                "calibration_low": plo,
                "calibration_high": phi,
                "calibration_trials": pn,
                **{
                    f"physics_R_{cls}": float(np.nanmean(measures[f"R {cls} (high / low)"]))
                    for cls in ("fast", "slow")
                },
            }
        row["candidate"] = bool(lo > 0.0)
        rows.append(row)
    plan = search_plan(s, rows)
    body = search_body(s, rows, plan)
    report = Report(
        "search",
        "The search for the paper's condition: the twin's map and its decision",
        body,
        rows,
        summary={"cells": rows, "settings": s.recorded()},
    )
    report.figures.append((SEARCH_FIGURE, lambda path: draw_search(path, rows)))
    written = report.write(out, provenance)
    # the pre-registered plan, in the form `--stage test --prediction` runs
    Report(
        "prediction",
        "The search's pre-registered cell",
        "The search's pre-registered cell (see search.md): "
        + (
            "none, no cell is a candidate"
            if not plan
            else f"{plan[0]['arena']}, {plan[0]['condition']}"
        ),
        plan,
        summary={"cells": plan, "settings": s.recorded()},
    ).write(out, provenance)
    # beyond the rule: every candidate, the pre-registered one first, for a replication
    replication = [plan_of(s, r) for r in candidates_of(rows)]  # (the first is `plan`'s)
    Report(
        "replication",
        "The search's candidates, the pre-registered one first: a replication's plan",
        "Every candidate cell of the map (search.md), the pre-registered one first; each with "
        "the physics trials 80 % power at its own prediction needs, on fresh seeds. Not the "
        "rule's decision (prediction.json): a replication beyond it.",
        replication,
        summary={"cells": replication, "settings": s.recorded()},
    ).write(out, provenance)
    return Outcome(out, written, body)


SEARCH_FIGURE = "search.png"


def draw_search(path: Path, rows: Sequence[Row]) -> None:
    """The twin's map: predicted fast - slow against the low lane's length, per temperature, with
    the calibration trials' physics (T = 0.005) beside; 95 % intervals."""
    fig, ax = subplots(figsize=(6.0, 3.6))
    for k, c in enumerate(SEARCH_CONDITIONS):
        mine = [r for r in rows if r["condition"] == c]
        x = np.array([r["lane"] for r in mine]) + 0.006 * (k - 0.5)
        m = np.array([r["learners"] for r in mine])
        err = [m - [r["learners_low"] for r in mine], [r["learners_high"] for r in mine] - m]
        ax.errorbar(x, m, yerr=err, fmt="o-", ms=4, label=f"twin, T = {LEARNERS[c].temperature:g}")
    cal = [r for r in rows if "calibration_physics" in r]
    x = np.array([r["lane"] for r in cal]) + 0.012
    m = np.array([r["calibration_physics"] for r in cal])
    err = [m - [r["calibration_low"] for r in cal], [r["calibration_high"] for r in cal] - m]
    ax.errorbar(x, m, yerr=err, fmt="s", ms=4, color="grey", label="physics, calibration (30)")
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xlabel("low-value lane / high-value lane")
    ax.set_ylabel("fast - slow")
    ax.invert_xaxis()
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


def candidates_of(rows: Sequence[Row]) -> list[Row]:
    """The map's candidate cells, largest prediction first."""
    return sorted((r for r in rows if r["candidate"]), key=lambda r: -r["learners"])


def search_plan(s: Settings, rows: Sequence[Row]) -> list[Row]:
    """The rule's decision: the candidate with the largest prediction (`plan_of`); none if no
    cell is a candidate."""
    return [plan_of(s, r) for r in candidates_of(rows)[:1]]


def plan_of(s: Settings, cell: Row) -> Row:
    """A candidate cell's physics plan: the trials that 80 % power at its prediction needs
    (capped), on fresh seeds."""
    needed = arena_runs.trials_for_power(cell["learners_sd"], cell["learners"])
    cap = s.max_physics if s.quick else SEARCH_MAX_PHYSICS  # the rule's cap (a smoke run's own)
    return {
        **cell,
        "fixed": math.nan,
        "trials_for_80_power": needed,
        "physics_trials": planned_trials(needed, s.min_physics, cap),
        "first_seed": SEARCH_FIRST_SEED,
    }


def search_body(s: Settings, rows: Sequence[Row], plan: Sequence[Row]) -> str:
    table = markdown_table(
        [
            "arena",
            "low lane / high lane",
            "softmax T",
            "twin among learners: fast - slow (95 % CI)",
            "twin's R fast / R slow",
            "calibration physics: fast - slow (N)",
            "physics R fast / R slow",
            "candidate",
        ],
        [
            [
                r["arena"],
                f"{r['lane']:g}",
                LEARNERS[r["condition"]].temperature,
                fmt_ci(r["learners"], r["learners_low"], r["learners_high"], 3),
                f"{r['twin_R_fast']:.3f} / {r['twin_R_slow']:.3f}",
                (
                    f"{fmt_ci(r['calibration_physics'], r['calibration_low'], r['calibration_high'], 3)}"
                    f" ({r['calibration_trials']})"
                    if "calibration_physics" in r
                    else "-"
                ),
                f"{r['physics_R_fast']:.3f} / {r['physics_R_slow']:.3f}"
                if "physics_R_fast" in r
                else "-",
                "**yes**" if r["candidate"] else "no",
            ]
            for r in rows
        ],
    )
    if plan:
        p = plan[0]
        decision = (
            f"**A candidate: {p['arena']} at {p['condition']}.** The twin predicts fast - slow = "
            f"{fmt_ci(p['learners'], p['learners_low'], p['learners_high'], 3)}; 80 % power at it "
            f"needs {p['trials_for_80_power']:.0f} physics trials, so {p['physics_trials']} run "
            f"(seeds {p['first_seed']} and up) by `--stage test --prediction "
            "benchmarks/results/twin_search/prediction.json`, after this commit."
        )
    else:
        decision = (
            "**No cell is a candidate**: nowhere in this family does the twin among learners put "
            "fast - slow's 95 % interval above 0, so by the rule no physics cell is "
            "pre-registered, and the answer in this family is no."
        )
    return (
        "The search's map (its rule, committed before any of its arenas was measured: "
        "docs/results/differentiation.md; the arenas' fixed-allocation measurements: family.md). "
        f"Per arena, {s.log_trials or SEARCH_LOG_TRIALS} physics learner trials at "
        f"{SEARCH_LOG_CONDITION} (seeds 0 up; their fast - slow is reported and decides nothing) "
        f"and {s.start_runs} runs from the start give the learner tables; the twin among learners "
        f"then predicts fast - slow in each cell from {min(s.twin_trials, SEARCH_TWIN_TRIALS)} "
        f"batched trials, and R = t(high) / t(low) per class among {s.twin_log_trials} logged "
        "twin trials (own-circuit tasks after the first). A cell is a candidate if the "
        "predicted interval lies above 0.\n\n" + table + "\n\n" + decision
    )


# -- settings ---------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The study's settings (its command line)."""

    quick_sizes: ClassVar = {
        "log_trials": 2,
        "twin_log_trials": 2,
        "twin_trials": 20,
        "start_runs": 4,
        "convergence_h": 0.3,
        "measured_h": 0.2,
        "min_physics": 2,
        "max_physics": 3,
    }

    stage: Stage = "logs"
    """logs (physics task logs), audit (learner tables and the audit), predict (pre-registered
    out-of-sample predictions), test (their physics) or family (the search's arenas, measured in
    physics without learners) or search (its learner tables, the twin's map and the decision)"""
    log_trials: int = 0
    """logged physics trials per cell (0: `LOG_CELLS`' numbers)"""
    twin_log_trials: int = 20
    """logged twin trials per cell and tables (audit)"""
    twin_trials: int = 10000
    """batched twin trials per cell and tables (audit, predict): at a per-trial sd of 0.3 (the
    passing arena at T = 0.002) the mean's 95 % interval is +-0.006, finer than the 0.01 check"""
    start_runs: int = 400
    """physics runs per arena that measure first tasks from the start allocation (audit)"""
    min_physics: int = 100
    """the fewest physics trials of a predicted cell (predict)"""
    max_physics: int = 1500
    """the most physics trials of a predicted cell, whatever the power analysis asks (predict)"""
    convergence_h: float = 15.0
    """convergence period, simulated hours"""
    measured_h: float = 5.0
    """measured period, simulated hours"""
    prediction: Path = RESULTS_DIR / "twin_learners_prediction" / "prediction.json"
    """the committed prediction whose plan the test stage runs (test)"""
    interim: bool = False
    """run no trial: write the test stage's report from the trials saved so far (test)"""
    seed: int = 2026
    """the batched twin's generator: cell k of a stage draws from [seed, stage, k]"""
    quick: bool = False
    """smoke run: 2 logged trials per cell of 0.3 + 0.2 h, 20 batched twin trials, 4 start runs"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                ("stage", self.stage in STAGES, f"one of {list(STAGES)}"),
                ("log_trials", at_least(self.log_trials, 0), "an integer >= 0"),
                ("twin_log_trials", at_least(self.twin_log_trials, 2), "an integer >= 2"),
                ("twin_trials", at_least(self.twin_trials, 2), "an integer >= 2"),
                ("start_runs", at_least(self.start_runs, 2), "an integer >= 2"),
                ("min_physics", at_least(self.min_physics, 2), "an integer >= 2"),
                (
                    "max_physics",
                    at_least(self.max_physics, 2) and self.max_physics >= self.min_physics,
                    "an integer >= min_physics",
                ),
                ("convergence_h", positive(self.convergence_h), "a finite number > 0"),
                ("measured_h", positive(self.measured_h), "a finite number > 0"),
                ("seed", at_least(self.seed, 0), "an integer >= 0"),
            ],
        )

    def reference_name(self) -> str:
        if self.stage == "test" and Path(self.prediction).parent.name == "twin_search":
            return "twin_search_test"  # the search's pre-registered cell
        return {
            "predict": "twin_learners_prediction",
            "test": "twin_learners_test",
            "family": "twin_search",
            "search": "twin_search",
            "gap": "twin_gap",
        }.get(self.stage, "twin_learners")

    def recorded(self) -> dict[str, Any]:
        sizes = {
            "logs": "log_trials",
            "audit": "log_trials twin_log_trials twin_trials start_runs",
            "predict": "twin_trials min_physics max_physics",
            "test": "prediction=prediction_name",
            "family": "",
            "search": "log_trials twin_log_trials twin_trials start_runs min_physics max_physics",
            "gap": "twin_trials min_physics max_physics",
        }[self.stage]
        return self.recorded_of(f"stage {sizes} convergence_h measured_h seed")

    @property
    def prediction_name(self) -> str:
        return Path(self.prediction).name

    def log_jobs(self) -> list[LogTrial]:
        """The logged physics trials, seed by seed across cells."""
        sizes = {cell: self.log_trials or n for cell, n in LOG_CELLS.items()}
        return [
            LogTrial(a, c, k, self.convergence_h, self.measured_h, arena_runs.digest(a))
            for k in range(max(sizes.values()))
            for (a, c), n in sizes.items()
            if k < n
        ]

    def logs_dir(self) -> Path:
        """The folder of the logged trials: the audit's own output folder's, or the committed
        one's if the audit writes elsewhere (`--out`, a new run folder)."""
        here = self.out_dir() / "logs"
        return here if here.is_dir() else RESULTS_DIR / "twin_learners" / "logs"


STAGES: tuple[Stage, ...] = ("logs", "audit", "predict", "test", "family", "search", "gap")


# -- stage 1: the logs ------------------------------------------------------------------------------
def run_logs(s: Settings) -> Outcome:
    jobs = s.log_jobs()
    results, _ = s.run_jobs(jobs, LOGS, "logs", wall_of=lambda r: float(r["wall_s"]))
    identical = 0
    compared = 0
    for job in jobs:
        committed = committed_physics(job.arena, job.condition).get(job.seed)
        if committed is not None:
            r = results[log_key(job)]
            compared += 1
            identical += float(r["fast_share"]) - float(r["slow_share"]) == committed
    text = (
        f"{len(results)} logged physics trials in {s.out_dir() / 'logs'}/; {identical} of "
        f"{compared} with a committed trial of the same seed give its fast - slow exactly."
    )
    return Outcome(s.out_dir(), [], text)


def run(settings: Settings) -> Outcome:
    s = settings.sized()
    if s.stage == "logs":
        return run_logs(s)
    if s.stage == "audit":
        return run_audit(s)
    if s.stage == "predict":
        return run_predict(s)
    if s.stage == "family":
        return run_family(s)
    if s.stage == "search":
        return run_search(s)
    if s.stage == "gap":
        return run_gap(s)
    return run_test(s)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
