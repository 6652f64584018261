"""The runs several studies make of an arena, shared beside them (the studies import this module
and the package, never each other):

- the interference study's fixed-allocation runs (`Job`, `RUNS`): f fast and s slow robots held on
  their circuits, reduced to group rows;
- the elasticity e of any arena, measured from those runs: `measure_elasticity(config)` runs the
  cells e needs (`tavc_agents.analysis.elasticity`: f fast and s slow robots on circuit 0, for
  (1, 0), (0, 1) and f, s in 1..3) and returns e with its bootstrap interval over seeds
  (`tavc_agents.analysis.elasticity`);
- the regime family: the arenas and learner conditions of the regime map, the passing test, the
  twin audit and the twin studies, their twin tables (`TABLES`) and their trials (`TRIALS`) on the
  physics or on the twin, and the cell statistics those studies report.

    measure_elasticity(tavc_env.preset("dahl2004_competence"), seeds=range(3), hours=2.0)

For a dahl2004 preset the elasticity runs are exactly the interference study's cross runs of that
preset, so with the same seeds and settings e is the one its report gives.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import itertools
import json
import math
import re
import tempfile
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from scipy import stats

import arena_analysis as ia
import tavc_env
from arena_analysis import (
    CELLS,
    Elasticity,
    cross_allocation,
    elasticity,
    seed_tables,
)
from tavc_agents.analysis.measures import TrialMeasures, measure
from tavc_agents.analysis.stats import mean_ci, ratio_ci
from tavc_agents.experiments.registry import make_allocator
from tavc_agents.experiments.runner import TrialResult, env_arguments, run_trial
from tavc_agents.experiments.study import (
    StudySettings,
    at_least,
    choices,
    positive,
    refuse_invalid,
    replace,
)
from tavc_agents.experiments.sweep import TrialSpec, arena_digest, json_jobs, run_jobs, run_sweep
from tavc_agents.learners.tavc import TavcParams
from tavc_agents.model import CompletionModel, Group, SpeedClasses, model_from_runs
from tavc_env import ArenaConfig, make_config
from tavc_env.measurement import CommandRecorder, FixedAllocation, run_fixed
from tavc_env.twin import InterferenceTables, build_tables, team_classes
from tavc_env.validation import is_integer, is_number, require

ELASTICITY_BOOT_SEED = 2004
"""the Generator of the elasticity's bootstrap (the interference study's)"""

BOOT_SEED = ELASTICITY_BOOT_SEED
"""the seed of the bootstrap's Generator when none is given (the interference study's)"""


def elasticity_jobs(
    config: ArenaConfig,
    seeds: Iterable[int],
    hours: float,
    warmup_min: float,
    skip_first: int,
) -> list[Job]:
    """The interference study's jobs for the runs e needs in `config`'s arena, one per cell and
    seed."""
    if not (math.isfinite(hours) and hours > 0):
        raise ValueError(f"hours = {hours!r} is invalid; allowed: > 0")
    if not (math.isfinite(warmup_min) and warmup_min >= 0):
        raise ValueError(f"warmup_min = {warmup_min!r} is invalid; allowed: >= 0")
    if not (isinstance(skip_first, int) and skip_first >= 0):
        raise ValueError(f"skip_first = {skip_first!r} is invalid; allowed: an integer >= 0")
    jobs = []
    for seed in seeds:
        for f, s in CELLS:
            alloc = cross_allocation(
                config,
                f,
                s,
                seed=seed,
                hours=hours,
                warmup_s=warmup_min * 60.0,
                skip_first=skip_first,
            )
            alloc.config()  # a bad arena is refused before any run
            fields = {x.name: getattr(alloc, x.name) for x in dataclasses.fields(FixedAllocation)}
            jobs.append(Job(experiment="cross", label=ia.cross_label(f, s), **fields))
    return jobs


def measure_elasticity(
    config: ArenaConfig,
    seeds: Iterable[int] = range(5),
    hours: float = 3.0,
    *,
    warmup_min: float = 10.0,
    skip_first: int = 2,
    workers: int | None = None,
    out: Path | None = None,
    rng: np.random.Generator | None = None,
) -> Elasticity:
    """e of `config`'s arena with a 95 % percentile-bootstrap interval over `seeds`.

    Each seed runs the 11 cells e needs for `hours` simulated hours (a task counts if decided at
    or after `warmup_min` minutes and not among the robot's first `skip_first`), the defaults
    being the interference study's. `workers`: processes (default: all cores). `out`: a folder
    that keeps the runs (a later call with the same settings resumes them; default: a temporary
    folder). `rng`: the bootstrap's Generator (default: seeded with `BOOT_SEED`)."""
    seed_list = list(seeds)
    if not seed_list or not all(isinstance(s, int) and s >= 0 for s in seed_list):
        raise ValueError(f"seeds = {seed_list!r} is invalid; allowed: one or more integers >= 0")
    jobs = elasticity_jobs(config, seed_list, hours, warmup_min, skip_first)
    with tempfile.TemporaryDirectory(prefix="elasticity-") as tmp:
        results = run_jobs(jobs, RUNS, out if out is not None else tmp, workers)
    rows = [r for job in jobs for r in results[job_key(job)]["rows"]]
    boot = rng if rng is not None else np.random.default_rng(BOOT_SEED)
    return elasticity(seed_tables(rows, seed_list), boot)


# -- the interference study's runs (f fast and s slow robots held on circuits) ---------------------
@dataclass(frozen=True)
class Job:
    """One run: which experiment (t_n | switch | switch_lone | cross) and allocation it is."""

    experiment: str
    preset: str
    circuit_of: tuple[int, ...]  # each robot's circuit (the switcher's first circuit)
    seed: int
    hours: float
    warmup_s: float
    skip_first: int
    switcher: int = -1
    switch_every: int = 3
    speeds: tuple[float, ...] | None = None
    label: str = ""
    arena: tuple[tuple[str, Any], ...] = ()  # ArenaConfig overrides (--set)

    def allocation(self) -> FixedAllocation:
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(FixedAllocation)}
        return FixedAllocation(**fields)


def run_job(job: Job) -> dict[str, Any]:
    """One run reduced to its per-group rows (JSON data, what the sweep saves)."""
    return {"rows": ia.group_rows(run_fixed(job.allocation()), job.experiment, job.label)}


def job_key(job: Job) -> str:
    label = re.sub(r"[^A-Za-z0-9_.=-]+", "-", job.label).strip("-")
    return f"{job.experiment}_{label}_s{job.seed}"


RUNS = json_jobs(run_job, job_key, unit="run")


# -- the regime family: arenas, learner conditions, twin tables and trials ----------------------
ARENAS: Mapping[str, Mapping[str, Any]] = {
    "dahl2004": {"preset": "dahl2004"},
    "dahl2004_instant_docks": {
        "preset": "dahl2004",
        "source_service_s": 0.0,
        "sink_service_s": 0.0,
    },
    "dahl2004_competence": {"preset": "dahl2004_competence"},
    "dahl2004_light_stations": {"preset": "dahl2004_light_stations"},
    "dahl2004_congestion": {"preset": "dahl2004_congestion"},
    "dahl2004_bays": {"preset": "dahl2004_bays"},
    "dahl2004_passing": {"preset": "dahl2004_passing"},
}
"""Arena name -> `tavc_env.parallel_env` keyword arguments (a preset and its overrides)."""


def passing_lane_arena(lane: float, low_value: float = 2000.0) -> dict[str, Any]:
    """`dahl2004_passing` with the low-value circuit's lane `lane` times the high-value lane's
    length (its source moved toward its sink; the sink, the queues and all else kept), its
    value `low_value`: the family of the search for the paper's condition
    (`benchmarks/twin_learners.py --stage family`)."""
    high, low = make_config("dahl2004_passing").circuits
    source = (low.source[0], low.sink[1] + lane * (low.source[1] - low.sink[1]))
    shortened = dataclasses.replace(low, source=source, value=low_value)
    return {"preset": "dahl2004_passing", "circuits": (high, shortened)}


SEARCH_LANES = (1.0, 0.85, 0.7, 0.55)
"""the search's lane lengths, low-value over high-value (its rule: the differentiation page)"""
SEARCH_ARENAS = tuple(f"passing_lane{lane:g}" for lane in SEARCH_LANES)
"""the search's arenas at their first values (2200 / 2000), where their tables are measured"""
SEARCH_VALUES = (2000.0, 2000.0, 2000.0, 1990.0)
"""the low-value circuit's value in each of the search's arenas, as its rule computed them from
the arenas' fixed-allocation tables (benchmarks/results/twin_search/family.md)"""
SEARCH_LEARNER_ARENAS = tuple(
    f"passing_lane{lane:g}_w{w:g}" for lane, w in zip(SEARCH_LANES, SEARCH_VALUES)
)
"""the search's arenas with those values: where its learners run"""
ARENAS = {
    **ARENAS,
    **{a: passing_lane_arena(lane) for a, lane in zip(SEARCH_ARENAS, SEARCH_LANES)},
    **{
        a: passing_lane_arena(lane, w)
        for a, lane, w in zip(SEARCH_LEARNER_ARENAS, SEARCH_LANES, SEARCH_VALUES)
    },
}
MAPPED = tuple(
    a for a in ARENAS if a not in ("dahl2004_passing", *SEARCH_ARENAS, *SEARCH_LEARNER_ARENAS)
)
"""the arenas of the committed map; `dahl2004_passing` has its own decisive test
(`benchmarks/passing.py`), which runs its cells through this module's jobs"""

TEMPERATURES = (0.002, 0.005, 0.01, 0.02)
EPSILON = 0.1
DECISIVE = (
    ("dahl2004_congestion", 0.005),
    ("dahl2004_congestion", 0.01),
    ("dahl2004", 0.005),
    ("dahl2004", 0.01),
)
"""(arena, softmax temperature) of the cells that decide the question, in the order they run."""

Z_POWER = stats.norm.ppf(0.975) + stats.norm.ppf(0.80)  # two-sided 5 %, 80 % power
Engine = Literal["physics", "twin"]
Row = dict[str, Any]


def softmax_condition(temperature: float) -> str:
    return f"softmax_T{temperature:g}"


CONDITIONS: Mapping[str, tuple[str, Mapping[str, Any]]] = {
    **{
        softmax_condition(t): ("softmax_tavc", {"temperature": t, "init": "scaled"})
        for t in TEMPERATURES
    },
    "epsilon_0.1": ("epsilon_tavc", {"epsilon": EPSILON, "init": "scaled"}),
    "random": ("random", {}),
}
"""Condition name -> (allocator, its parameters)."""


QUICK_DESIGN: Mapping[str, Any] = {
    "convergence_h": 0.3,
    "measured_h": 0.2,
    "e_seeds": 2,
    "e_hours": 0.4,
    "table_seeds": 2,
    "table_hours": 0.4,
}
"""`CellDesign`'s sizes in a smoke run (`--quick`)"""


@dataclass(frozen=True, kw_only=True)
class CellDesign(StudySettings):
    """How an arena's cells are made: the trials' periods and seeds, and the runs that measure the
    arena's e and twin tables (the regime map's, and the passing arena's decisive test's)."""

    convergence_h: float = 15.0
    """convergence period, simulated hours"""
    measured_h: float = 5.0
    """measured period, simulated hours"""
    e_seeds: int = 5
    """seeds of each arena's elasticity runs"""
    e_hours: float = 3.0
    """simulated hours per elasticity run"""
    table_seeds: int = 3
    """seeds of each arena's twin-table runs"""
    table_hours: float = 1.0
    """simulated hours per twin-table run"""
    seed: int = 0
    """trial k of every cell uses seed + k"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                ("convergence_h", positive(self.convergence_h), "a finite number > 0"),
                ("measured_h", positive(self.measured_h), "a finite number > 0"),
                ("e_seeds", at_least(self.e_seeds, 2), "an integer >= 2"),
                ("e_hours", positive(self.e_hours), "a finite number > 0"),
                ("table_seeds", at_least(self.table_seeds, 1), "an integer >= 1"),
                ("table_hours", positive(self.table_hours), "a finite number > 0"),
                ("seed", at_least(self.seed, 0), "an integer >= 0"),
            ],
        )


@dataclass(frozen=True, kw_only=True)
class Settings(CellDesign):
    """The regime map's settings (its command line)."""

    reference: ClassVar = "regime_map"
    quick_sizes: ClassVar = {**QUICK_DESIGN, "trials": 2, "decisive_trials": 3}
    recorded_fields: ClassVar = (
        "arenas=arena_list trials decisive_trials decisive_cells twin_trials convergence_h "
        "measured_h e_seeds e_hours table_seeds table_hours seed"
    )

    arenas: str = ",".join(MAPPED)
    """comma-separated subset of the arenas dahl2004, dahl2004_instant_docks, dahl2004_competence,
    dahl2004_light_stations, dahl2004_congestion, dahl2004_bays"""
    trials: int = 60
    """physics trials per cell"""
    decisive_trials: int = 400
    """physics trials in the cells that decide the question (softmax T = 0.005 and 0.01 on
    dahl2004_congestion and dahl2004)"""
    twin_trials: int = 100
    """model-twin trials per cell (0: no twin)"""
    quick: bool = False
    """smoke run: 2 trials (3 in decisive cells, 2 twin) of 0.3 + 0.2 h, short e and table runs"""
    interim: bool = False
    """run no trial: write `regime_map_interim.*` from the trials saved so far (an unfinished
    sweep; every cell states its N, and cells with fewer than 2 trials are left out)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        choices(self, "arenas", ARENAS)  # an unknown arena is refused
        checks = [
            ("trials", at_least(self.trials, 2), "an integer >= 2"),
            ("decisive_trials", at_least(self.decisive_trials, 2), "an integer >= 2"),
            ("twin_trials", at_least(self.twin_trials, 0), "an integer >= 0"),
        ]
        refuse_invalid(self, checks)

    @property
    def arena_list(self) -> list[str]:
        return choices(self, "arenas", ARENAS)

    @property
    def decisive_cells(self) -> list[str]:
        return [f"{a} {softmax_condition(t)}" for a, t in DECISIVE]

    def sized(self) -> Settings:
        """These settings with `--quick`'s sizes applied (and at most 2 twin trials)."""
        sized = super().sized()
        return replace(sized, twin_trials=min(self.twin_trials, 2)) if self.quick else sized

    def trials_in(self, arena: str, condition: str) -> int:
        decisive = {(a, softmax_condition(t)) for a, t in DECISIVE}
        return self.decisive_trials if (arena, condition) in decisive else self.trials


def digest(arena: str) -> str:
    """The digest of the arena's configuration (`tavc_agents.experiments.sweep.arena_digest`)."""
    return arena_digest(ARENAS[arena])


def arena_config(arena: str) -> tavc_env.ArenaConfig:
    kwargs = dict(ARENAS[arena])
    return tavc_env.make_config(kwargs.pop("preset"), **kwargs)


# -- jobs ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TablesJob:
    """Measure one arena's twin tables. `arena_sha` is the digest of the arena's configuration,
    so a stored result is not resumed for an arena whose name now means another configuration."""

    arena: str
    seeds: tuple[int, ...]
    hours: float
    arena_sha: str = ""


def run_tables(job: TablesJob) -> dict[str, Any]:
    return build_tables(arena_config(job.arena), seeds=job.seeds, hours=job.hours).to_dict()


TABLES = json_jobs(run_tables, lambda job: f"tables_{job.arena}", unit="arena")


@dataclass(frozen=True)
class MapTrial:
    """One trial of one cell, on the physics or on the twin (whose tables travel with the job and
    are recorded by their digest)."""

    arena: str
    condition: str
    seed: int
    convergence_h: float
    measured_h: float
    engine: Engine = "physics"
    tables_sha256: str = ""
    arena_sha: str = ""  # the arena configuration's digest (see `TablesJob`)
    tables: Mapping[str, Any] | None = field(default=None, compare=False, repr=False)


def tables_digest(tables: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(tables, sort_keys=True).encode()).hexdigest()


def trial_key(job: MapTrial) -> str:
    return f"{job.arena}__{job.condition}__{job.engine}__seed{job.seed}"


def measures_record(m: TrialMeasures) -> dict[str, float]:
    """The measures a trial's record keeps for the cell statistics (`cell_row`)."""
    return {
        "fast_share": m.fast_share,
        "slow_share": m.slow_share,
        "performance": m.performance,
        "q_gap_fast": m.q_gap_fast,
        "q_gap_slow": m.q_gap_slow,
    }


def run_map_trial(job: MapTrial) -> dict[str, Any]:
    """Run `job` and return its compact record: the measures of `tavc_agents.analysis.measures`."""
    allocator, params = CONDITIONS[job.condition]
    factory = None
    if job.engine == "twin":
        assert job.tables is not None, "a twin trial needs its tables"
        tables = InterferenceTables.from_dict(job.tables)
        factory = functools.partial(tavc_env.twin_parallel_env, tables=tables)
    started = time.perf_counter()
    result = run_trial(
        make_allocator(allocator, **params),
        seed=job.seed,
        convergence_s=job.convergence_h * 3600.0,
        measured_s=job.measured_h * 3600.0,
        snapshot_every_s=(job.convergence_h + job.measured_h) * 3600.0,
        env_factory=factory,
        **env_arguments(ARENAS[job.arena]),
    )
    m = measure(result)
    return {
        **measures_record(m),
        "states_pct": {f"{f}:{s}": round(v, 4) for (f, s), v in sorted(m.states.items())},
        "deliveries": len(result.delivery_time_s),
        "jams": result.jams,
        "sim_s": round(result.end_s, 1),
        "wall_s": round(time.perf_counter() - started, 2),
    }


TRIALS = json_jobs(run_map_trial, trial_key, unit="trial", omit=("tables",))


def physics_trials(s: Settings) -> list[MapTrial]:
    """The physics trials: the decisive cells first (in `DECISIVE` order, seed by seed within
    each arena), then the other cells seed by seed, so that a sweep stopped early leaves whole
    seeds in every cell it reached."""

    def trial(arena: str, condition: str, k: int) -> MapTrial:
        return MapTrial(
            arena, condition, s.seed + k, s.convergence_h, s.measured_h, arena_sha=digest(arena)
        )

    arenas = s.arena_list
    decisive = [(a, softmax_condition(t)) for a, t in DECISIVE if a in arenas]
    jobs = []
    for arena in dict.fromkeys(a for a, _ in decisive):
        cells = [c for a, c in decisive if a == arena]
        jobs += [trial(arena, c, k) for k in range(s.decisive_trials) for c in cells]
    rest = [(a, c) for a in arenas for c in CONDITIONS if (a, c) not in decisive]
    jobs += [trial(a, c, k) for k in range(s.trials) for a, c in rest]
    return jobs


def twin_trials(s: Settings, tables: Mapping[str, Mapping[str, Any]]) -> list[MapTrial]:
    return [
        MapTrial(
            a,
            c,
            s.seed + k,
            s.convergence_h,
            s.measured_h,
            "twin",
            tables_digest(tables[a]),
            digest(a),
            tables[a],
        )
        for k in range(s.twin_trials)
        for a in s.arena_list
        for c in CONDITIONS
    ]


# -- analysis -----------------------------------------------------------------------------------
def _values(records: Sequence[Mapping[str, Any]], key: str) -> list[float]:
    return [float(r[key]) for r in records]


def diff_of(records: Sequence[Mapping[str, Any]]) -> list[float]:
    """Per trial, the fast robots' share of time on the high-value circuit minus the slow ones'."""
    return [float(r["fast_share"]) - float(r["slow_share"]) for r in records]


def trials_for_power(sd: float, effect: float) -> float:
    """Trials for 80 % power in a two-sided 5 % test of a mean `effect` with per-trial spread `sd`
    (inf where the effect is 0 or undefined)."""
    if not (math.isfinite(sd) and math.isfinite(effect)) or effect == 0:
        return math.inf
    return float((Z_POWER * sd / abs(effect)) ** 2)


def minimal_detectable(values: Sequence[float]) -> float:
    """The smallest mean effect that `len(values)` trials of this spread detect with 80 % power
    in a two-sided 5 % test: (z_0.975 + z_0.80) sd / sqrt(n)."""
    if len(values) < 2:
        return math.nan
    return float(Z_POWER * np.std(values, ddof=1) / math.sqrt(len(values)))


def cell_row(records: Sequence[Mapping[str, Any]], random: Sequence[Mapping[str, Any]]) -> Row:
    """One engine's summary of one cell (against that engine's random cell of the same arena)."""
    diff = diff_of(records)
    d, d_lo, d_hi, n = mean_ci(diff)
    s30, s30_lo, s30_hi, _ = mean_ci([r["states_pct"]["3:0"] for r in records])
    q, q_lo, q_hi, _ = mean_ci([float(r["q_gap_fast"]) - float(r["q_gap_slow"]) for r in records])
    perf, perf_lo, perf_hi, _ = mean_ci(_values(records, "performance"))
    ratio = (
        ratio_ci(_values(records, "performance"), _values(random, "performance"))
        if len(random) >= 2
        else (math.nan,) * 3
    )
    return {
        "trials": n,
        "fast_share": float(np.mean(_values(records, "fast_share"))),
        "slow_share": float(np.mean(_values(records, "slow_share"))),
        "fast_minus_slow": d,
        "fast_minus_slow_lo": d_lo,
        "fast_minus_slow_hi": d_hi,
        "fast_minus_slow_sd": float(np.std(diff, ddof=1)) if n >= 2 else math.nan,
        "detectable_80": minimal_detectable(diff),
        "time_3_0_pct": s30,
        "time_3_0_lo": s30_lo,
        "time_3_0_hi": s30_hi,
        "q_gap_fast_minus_slow": q,
        "q_gap_lo": q_lo,
        "q_gap_hi": q_hi,
        "performance": perf,
        "performance_lo": perf_lo,
        "performance_hi": perf_hi,
        "ratio_to_random": ratio[0],
        "ratio_lo": ratio[1],
        "ratio_hi": ratio[2],
        "jams": int(sum(int(r["jams"]) for r in records)),
        "wall_s": float(sum(float(r["wall_s"]) for r in records)),
    }


def welch_difference(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    """Mean of `a` minus mean of `b` with its Welch 95 % interval (nan where undefined)."""
    if len(a) < 2 or len(b) < 2:
        return (math.nan, math.nan, math.nan)
    res = stats.ttest_ind(a, b, equal_var=False)
    ci = res.confidence_interval(0.95)
    return (float(np.mean(a) - np.mean(b)), float(ci.low), float(ci.high))


def overlap(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return a[0] <= b[1] and b[0] <= a[1]


def direction(row: Row) -> str:
    """The paper's direction (interval above 0), reversed (below 0) or not detectable."""
    lo, hi = row["fast_minus_slow_lo"], row["fast_minus_slow_hi"]
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return "undetermined"
    if lo > 0:
        return "paper's direction"
    if hi < 0:
        return "reversed"
    return "not detectable"


def learner_of(condition: str) -> Learner:
    """The batched learner of a regime-map condition."""
    allocator, params = CONDITIONS[condition]
    if allocator == "random":
        return Learner("random")
    if allocator == "softmax_tavc":
        return Learner("softmax", float(params["temperature"]))
    return Learner("epsilon", float(params["epsilon"]))


# -- the twin vectorised over trials, with the learners -------------------------------------------
# Many model-twin trials at once: the twin's decision process (`tavc_env.twin`) with TAVC or
# random robots, vectorised over trials with numpy, for power analyses that need thousands of trials.
#
#     tables = InterferenceTables.from_dict(...)        # e.g. the regime map's twin_tables/
#     out = run_batch(tavc_env.make_config("dahl2004"), tables, Learner("softmax", 0.005),
#                     trials=2000, rng=np.random.default_rng(0))
#     out.fast_share - out.slow_share                   # one value per trial
#
# A second implementation of what `run_trial(..., env_factory=twin_parallel_env)` does with the
# allocators `softmax_tavc`, `epsilon_tavc` (`tavc_agents.learners.tavc`) and `random`, written for
# throughput: one numpy step takes every unfinished trial to its next task completion. The same
# process, step for step:
#
# * at the start the robots stand on the circuits in an order drawn per trial (rank mod circuits) and
#   all choose; once all have chosen, each draws its task time from its cell of the tables (the
#   robots of each class committed to its circuit, itself included), times the switch cost if it
#   changed circuits;
# * at a completion the robot earns `w / t` (t in ms, the env's default), updates
#   Q(s, a) += alpha (r + gamma max Q(a, .) - Q(s, a)) (with the scaled initialisation, the first
#   reward first sets every entry to r / (1 - gamma) (1 + optimism) with relative noise), chooses
#   its next circuit from the row of its new state, and draws the next task time;
# * measures over the measured window as `tavc_agents.analysis.measures`: each robot's share of time on
#   the high-value circuit (its current task's circuit), delivered value per robot per 10 s, time in
#   each fast:slow state, and the final Q gap Q(s, high) - max Q(s, other) averaged over states.
#
# Not covered (a ValueError says so): breakdowns, priority changes, other allocators. The random
# streams differ from the Policy-based twin's, so the two agree in distribution, not trial by trial;
# `benchmarks/twin_batch.py` checks that agreement against the regime map's twin trials.
REWARD_UNIT = 1000.0  # the env's default reward time unit: t in ms


@dataclass(frozen=True)
class Learner:
    """The robots' allocator: softmax TAVC (`parameter`: the temperature), epsilon-greedy TAVC
    (`parameter`: epsilon) or random choice (no parameter), with TAVC's learning parameters."""

    kind: Literal["softmax", "epsilon", "random"]
    parameter: float = 0.0
    params: TavcParams = field(default_factory=TavcParams)

    def __post_init__(self) -> None:
        require(
            self.kind in ("softmax", "epsilon", "random"),
            "learner.kind",
            self.kind,
            "'softmax', 'epsilon' or 'random'",
        )
        if self.kind == "softmax":
            ok = is_number(self.parameter) and self.parameter > 0
            require(ok, "learner.parameter", self.parameter, "a softmax temperature > 0")
        if self.kind == "epsilon":
            ok = is_number(self.parameter) and 0 <= self.parameter <= 1
            require(ok, "learner.parameter", self.parameter, "an epsilon in [0, 1]")


@dataclass(frozen=True)
class BatchOutcome:
    """Per trial (arrays of length `trials`) the measures of the measured window; `states` is
    (trials, fast + 1, slow + 1): the fraction of the window with f fast and s slow robots on the
    high-value circuit. Q gaps are nan for random choice."""

    fast_share: np.ndarray
    slow_share: np.ndarray
    performance: np.ndarray
    q_gap_fast: np.ndarray
    q_gap_slow: np.ndarray
    states: np.ndarray
    completions: int


def run_batch(
    config: ArenaConfig,
    tables: InterferenceTables,
    learner: Learner,
    trials: int,
    rng: np.random.Generator,
    convergence_s: float = 15 * 3600.0,
    measured_s: float = 5 * 3600.0,
) -> BatchOutcome:
    """`trials` independent twin trials of `config` with `tables`, every robot a `learner`, each
    running `convergence_s` then `measured_s` simulated seconds; every draw from `rng`."""
    require(isinstance(config, ArenaConfig), "config", type(config).__name__, "an ArenaConfig")
    require(not config.breakdowns, "config.breakdowns", config.breakdowns, "none (not modelled)")
    tables.check_team(config)
    require(is_integer(trials) and trials >= 1, "trials", trials, "an integer >= 1")
    require(isinstance(rng, np.random.Generator), "rng", rng, "a numpy.random.Generator")
    for name, value in (("convergence_s", convergence_s), ("measured_s", measured_s)):
        require(is_number(value) and value > 0, name, value, "a number of seconds > 0")
    return _Batch(config, tables, learner, int(trials), rng).run(
        float(convergence_s), float(convergence_s + measured_s)
    )


class _Batch:
    def __init__(
        self,
        config: ArenaConfig,
        tables: InterferenceTables,
        learner: Learner,
        trials: int,
        rng: np.random.Generator,
    ) -> None:
        classes, team = team_classes(config)
        self.k, self.n, self.m = trials, config.n_robots, config.n_circuits
        self.rng = rng
        self.learner = learner
        self.values = np.array([c.value for c in config.circuits], dtype=float)
        self.high = int(np.argmax(self.values))
        self.robot_class = np.array([classes.index(r.speed_class) for r in config.robots])
        self.fast = np.array([r.speed_class == "fast" for r in config.robots])
        self.slow = np.array([r.speed_class == "slow" for r in config.robots])
        # the lognormal of every cell, indexed [switch, circuit, count vector (mixed radix),
        # class]: tasks after the first (switch 0, the switch cost applied on top), first tasks
        self.radix = np.cumprod([1, *(t + 1 for t in team[:-1])])
        size = int(np.prod([t + 1 for t in team]))
        self.mu = np.zeros((2, self.m, size, len(classes)))
        self.sigma = np.zeros_like(self.mu)
        self.first_mu = np.zeros_like(self.mu)
        self.first_sigma = np.zeros_like(self.mu)
        for mu, sigma, switch, cells in (
            (self.mu, self.sigma, 0, tables.cells),
            (self.first_mu, self.first_sigma, 0, tables.first_own_cells),
            (self.first_mu, self.first_sigma, 1, tables.first_switch_cells),
        ):
            for cell in cells:
                at = (
                    switch,
                    cell.circuit,
                    int(np.dot(cell.counts, self.radix)),
                    classes.index(cell.robot_class),
                )
                mu[at], sigma[at] = cell.lognormal()
        self.has_first = bool(tables.first_own_cells)
        self.switch_cost = np.array([tables.class_switch_cost(c) for c in classes])
        self.class_count = np.zeros((self.k, self.m, len(classes)), dtype=np.int64)

    # -- the learners ------------------------------------------------------------------------
    def choose(self, q_rows: np.ndarray) -> np.ndarray:
        """One circuit per row of Q-values (rows, circuits), by the learner's selection rule."""
        rows = q_rows.shape[0]
        kind, m = self.learner.kind, self.m
        if kind == "random":
            p = np.full((rows, m), 1.0 / m)
        elif kind == "softmax":
            z = np.exp((q_rows - q_rows.max(axis=1, keepdims=True)) / self.learner.parameter)
            p = z / z.sum(axis=1, keepdims=True)
        else:
            best = q_rows == q_rows.max(axis=1, keepdims=True)
            n_best = best.sum(axis=1, keepdims=True)
            eps = self.learner.parameter
            p = np.where(best, (1.0 - eps) / n_best, eps / np.maximum(m - n_best, 1))
            p = np.where(n_best == m, 1.0 / m, p)
        cdf: np.ndarray = np.cumsum(p, axis=1)
        u = self.rng.random((rows, 1)) * cdf[:, -1:]
        return np.minimum((cdf <= u).sum(axis=1), m - 1)

    def draw(
        self, trials: np.ndarray, robots: np.ndarray, switched: np.ndarray, first: bool = False
    ) -> np.ndarray:
        """Task times of `robots` in `trials` on their current circuits, crowds as they are now
        (`first`: their first tasks, from the tables' first-task cells if they have them)."""
        circuit = self.current[trials, robots]
        counts = self.class_count[trials, circuit] @ self.radix
        cls = self.robot_class[robots]
        if first and self.has_first:
            at = (switched.astype(np.int64), circuit, counts, cls)
            z = self.rng.standard_normal(len(trials))
            return np.asarray(np.exp(self.first_mu[at] + self.first_sigma[at] * z))
        mu, sigma = self.mu[0, circuit, counts, cls], self.sigma[0, circuit, counts, cls]
        t = np.exp(mu + sigma * self.rng.standard_normal(len(trials)))
        return np.where(switched, t * self.switch_cost[cls], t)

    # -- the process -------------------------------------------------------------------------
    def run(self, t0: float, t1: float) -> BatchOutcome:
        k, n, m = self.k, self.n, self.m
        p = self.learner.params
        learning = self.learner.kind != "random"
        rng = self.rng
        start = np.array([rng.permutation(n) for _ in range(k)])
        self.current = np.empty((k, n), dtype=np.int64)
        np.put_along_axis(self.current, start, np.arange(n)[None, :] % m, axis=1)
        state = self.current.copy()  # each robot's observation: the circuit of its last task
        if p.init == "paper":
            q = rng.uniform(-p.init_range, p.init_range, size=(k, n, m, m))
        else:
            q = np.zeros((k, n, m, m))
        pending = np.full((k, n), p.init == "scaled")
        rows = np.repeat(np.arange(k), n)
        robots = np.tile(np.arange(n), k)
        chosen = self.choose(q[rows, robots, state.ravel()]).reshape(k, n)
        switched = chosen != state
        self.current = chosen
        np.add.at(self.class_count, (rows, chosen.ravel(), self.robot_class[robots]), 1)
        started = np.zeros((k, n))
        due = self.draw(rows, robots, switched.ravel(), first=True).reshape(k, n)

        on_high_time = np.zeros((k, n))
        state_time = np.zeros((k, int(self.fast.sum()) + 1, int(self.slow.sum()) + 1))
        delivered = np.zeros(k)
        last_event = np.zeros(k)
        active = np.arange(k)
        completions = 0
        w_max = self.values.max()
        while active.size:
            robot = due[active].argmin(axis=1)
            now = due[active, robot]
            # time on the high-value circuit over the measured window, up to this event
            overlap = np.clip(np.minimum(now, t1) - np.maximum(last_event[active], t0), 0.0, None)
            on_high = self.current[active] == self.high
            on_high_time[active] += overlap[:, None] * on_high
            f, s = on_high[:, self.fast].sum(axis=1), on_high[:, self.slow].sum(axis=1)
            state_time[active, f, s] += overlap
            last_event[active] = now
            going = now < t1
            active, robot, now = active[going], robot[going], now[going]
            if not active.size:
                break
            completions += active.size
            circuit = self.current[active, robot]
            reward = self.values[circuit] / ((now - started[active, robot]) * REWARD_UNIT)
            delivered[active] += np.where(now >= t0, self.values[circuit] / w_max, 0.0)
            if learning:
                first = pending[active, robot]
                if first.any():
                    a, r = active[first], robot[first]
                    level = p.scaled_level(reward[first])
                    jitter = rng.uniform(-p.noise, p.noise, size=(a.size, m, m))
                    q[a, r] = level[:, None, None] * (1.0 + jitter)
                    pending[a, r] = False
                s = state[active, robot]
                target = reward + p.gamma * q[active, robot, circuit].max(axis=1)
                q[active, robot, s, circuit] += p.alpha * (target - q[active, robot, s, circuit])
            state[active, robot] = circuit
            nxt = self.choose(q[active, robot, circuit])
            cls = self.robot_class[robot]
            np.add.at(self.class_count, (active, circuit, cls), -1)
            np.add.at(self.class_count, (active, nxt, cls), 1)
            self.current[active, robot] = nxt
            started[active, robot] = now
            due[active, robot] = now + self.draw(active, robot, nxt != circuit)
        window = t1 - t0
        share = on_high_time / window
        others = [c for c in range(m) if c != self.high]
        gap = (q[..., self.high] - q[..., others].max(axis=-1)).mean(axis=-1)  # (trials, robots)
        nan = np.full(k, math.nan)
        return BatchOutcome(
            fast_share=share[:, self.fast].mean(axis=1),
            slow_share=share[:, self.slow].mean(axis=1),
            performance=delivered / n / (window / 10.0),
            q_gap_fast=gap[:, self.fast].mean(axis=1) if learning else nan,
            q_gap_slow=gap[:, self.slow].mean(axis=1) if learning else nan,
            states=state_time / window,
            completions=completions,
        )


# -- the env's speed with random choices (the throughput benchmarks) -----------------------------
# Timing the env: the PettingZoo env's speed with random choices, in CPU seconds of the measuring
# process (`time.process_time`: on a shared machine wall time also counts the other processes' turns).
#
# The bare-physics yardsticks it is set beside (`physics_replay`, `physics_floor`) and the recorder of
# a run's velocity commands live with the engine's other measurements, in `tavc_env.measurement`.
def random_choice_run(
    config: ArenaConfig,
    seed: int,
    sim_s: float,
    decision_interval_s: float | None = None,
    record: bool = False,
) -> dict[str, Any]:
    """Time `sim_s` simulated seconds of the PettingZoo parallel env (event-driven stepping, or
    every `decision_interval_s`), every robot that must decide picking a circuit uniformly at
    random (numpy Generator seeded [seed, 1]): CPU and wall seconds, simulated seconds, physics
    ticks and decisions. With `record`, also the run's physics (untimed: an observer reads every
    tick): `start` (positions after reset), `commands` (ticks, n, 2: every tick's velocity
    commands) and `end` (positions at the end), for `physics_replay`."""
    env = tavc_env.parallel_env(
        config=config,
        max_sim_time_s=sim_s,
        max_cycles=10**9,
        decision_interval_s=decision_interval_s,
    )
    m = config.n_circuits
    rng = np.random.default_rng([seed, 1])
    _, infos = env.reset(seed=seed)
    recorder = CommandRecorder(env.sim) if record else None
    decisions = 0
    cpu0, wall0 = time.process_time(), time.perf_counter()
    while env.agents:
        actions = {a: int(rng.integers(m)) for a in env.agents if infos[a]["action_required"]}
        decisions += len(actions)
        _, _, _, _, infos = env.step(actions)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    found: dict[str, Any] = {
        "cpu_s": cpu,
        "wall_s": wall,
        "sim_s": env.sim_time_s,
        "ticks": env.sim.ticks,
        "decisions": decisions,
    }
    if recorder is not None:
        found.update(recorder.recording(env.sim))
    return found


TEAM_SIZES = {6: None, 24: 8, 96: 32, 384: 128}
"""The team sizes the throughput benchmarks time: robots -> lanes of `tavc_env.scaled_config`
(None: the `dahl2004` preset)."""


def team_config(robots: int, dt: float | None = None) -> ArenaConfig:
    """`dahl2004` for 6 robots, `scaled_config(lanes, 3)` for more (`TEAM_SIZES`); with step `dt`
    if given."""
    if robots not in TEAM_SIZES:
        raise ValueError(f"robots = {robots!r} is invalid; allowed: one of {list(TEAM_SIZES)}")
    lanes = TEAM_SIZES[robots]
    config = tavc_env.make_config("dahl2004") if lanes is None else tavc_env.scaled_config(lanes, 3)
    return config if dt is None else config.replace(dt=dt)


# -- the TAVC model measured by simulation (the model-based allocators' c) --------------------------
# The TAVC model measured by simulation: every group of robots alone on every circuit, as fixed
# allocations, gives the task-completion frequencies c_{i,J} of `tavc_agents.model.CompletionModel`.
def group_specs(
    config: ArenaConfig,
    seeds: Sequence[int],
    warmup_s: float,
    measure_s: float,
    key_prefix: str = "",
) -> list[TrialSpec]:
    """The sweep that measures c: every non-empty group alone on every circuit, as fixed
    allocations. Each spec is tagged with its `circuit`, `group` (robots per class) and `seed`;
    its key, `<prefix>c<i>_g<counts>_s<seed>`, is derived from those tags."""
    classes = SpeedClasses.of(config)
    specs = []
    for i in range(config.n_circuits):
        for group in itertools.product(*(range(n + 1) for n in classes.team)):
            if sum(group) == 0:
                continue
            robots = tuple(r for r, n in zip(classes.robots, group) for _ in range(n))
            for seed in seeds:
                specs.append(
                    TrialSpec(
                        key=f"{key_prefix}c{i}_g{'-'.join(map(str, group))}_s{seed}",
                        allocator="fixed",
                        allocator_kwargs={"circuit": i},
                        seed=seed,
                        env_kwargs={"config": config, "robots": robots},
                        convergence_s=warmup_s,
                        measured_s=measure_s,
                        snapshot_every_s=warmup_s + measure_s,
                        tags={"circuit": i, "group": tuple(group), "seed": seed},
                    )
                )
    return specs


def group_of(spec: TrialSpec) -> Group:
    """The group (robots per class) a `group_specs` spec measures."""
    group = spec.tags["group"]
    assert isinstance(group, tuple)
    return tuple(int(n) for n in group)


def circuit_of(spec: TrialSpec) -> int:
    """The circuit a `group_specs` spec measures."""
    circuit = spec.tags["circuit"]
    assert isinstance(circuit, int)
    return circuit


def measured_rate(result: TrialResult) -> float:
    """Tasks per second completed in a trial's measured window."""
    t0, t1 = result.measured_window
    times = np.asarray(result.delivery_time_s, dtype=float)
    return float(((times >= t0) & (times < t1)).sum() / (t1 - t0))


def estimate_model(
    config: ArenaConfig | str = "dahl2004",
    *,
    seeds: Sequence[int] = (0, 1, 2),
    warmup_s: float = 600.0,
    measure_s: float = 7200.0,
    out_dir: str | Path | None = None,
    workers: int | None = None,
    progress_bar: bool = False,
) -> CompletionModel:
    """Measure c_{i,J} for every group and circuit of `config` (or a preset name) by simulation.

    Each group serves each circuit alone (the other robots absent) for `warmup_s` then `measure_s`
    simulated seconds, once per seed. With `out_dir`, runs are saved as they finish and a rerun
    resumes; otherwise they run in a temporary folder.
    """
    cfg = make_config(config) if isinstance(config, str) else config
    require(len(seeds) >= 1, "seeds", seeds, "at least one seed")
    specs = group_specs(cfg, seeds, warmup_s, measure_s)
    with tempfile.TemporaryDirectory() as tmp:
        results = run_sweep(
            specs, out_dir if out_dir is not None else tmp, workers, progress_bar=progress_bar
        )
    runs = [(circuit_of(s), group_of(s), measured_rate(results[s.key])) for s in specs]
    return model_from_runs(cfg, runs)
