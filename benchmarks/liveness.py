"""Liveness at length: the jam rate and the longest gap per robot over team sizes and random arenas.

Runs the PettingZoo env with uniformly random circuit choices (`RandomAllocator` through
`tavc_agents.experiments.runner.run_trial`) in three arms: `dahl2004` with k fast + k slow robots
(k = 3..6; a team of 14 is refused, and the report quotes why), two-lane arenas
`tavc_env.scaled_config(2, rpc)` with rpc = 3, 6, 12, 18, 24 robots per circuit (4 simulated hours
x 4 seeds each), and 120 random valid arenas (`tavc_agents.experiments.arenas`; 2 h x 1 seed each).
Counts the jams the engine's detector finds and every robot's longest gap without a delivery.

Reports the jam rate with an exact (Clopper-Pearson) 95 % interval overall, per arm and per team
size, the longest gap per team size and overall, the random arenas' refused draws by reason, and
the wall time. Exits with status 1 if any trial has an unreported jam: a robot longer than
`--max-gap-min` (default 60 simulated minutes) without a delivery while the detector found none.

Writes `liveness.{md,csv,json}` (one CSV row per trial) and `provenance.json` into a new run folder
under runs/ (git ignores it), `--out`, or with `--update-reference` benchmarks/results/liveness/;
each trial is kept as a small record in the output folder's trials/ as it finishes, so `--resume
RUN_DIR` continues an interrupted run (`--workers`, `--backend local|ray`). The study is
`benchmarks/liveness.py`.

    python benchmarks/liveness.py                 # 156 trials, ~5 min on one core
    python benchmarks/liveness.py --quick         # smoke run (seconds)

Liveness at length: how often the arena jams, and how long a robot can go without a delivery,
over team sizes and over random valid arenas (issue 12). The script is `benchmarks/liveness.py`.

Every trial runs the PettingZoo env with uniformly random circuit choices
(`tavc_agents.allocators.baselines.RandomAllocator` through `tavc_agents.experiments.runner.run_trial`), so
every robot keeps driving between stations, and counts the jams the engine's detector finds
(`tavc_env.engine.simulation`: no task event for `JAM_WINDOW_S` while no moving robot got
`JAM_MOTION_M` away) and the time spent jammed. Three arms:

* `dahl2004`: the paper's arena with k fast (0.30 m/s) and k slow (0.20 m/s) robots, k = 3..6
  (13 robots is the most its waiting lines hold; a team of 14 is refused, and the report quotes
  the refusal);
* `lanes`: two-lane arenas `tavc_env.scaled_config(2, rpc)` with rpc robots per circuit, up to 24
  (48 robots);
* `random`: random valid arenas (`tavc_agents.experiments.arenas.random_arenas`: 1-4 circuits anywhere
  with queue lines at any angle, 2-24 robots of 0.1-0.4 m/s, random radius, service times and
  physics step; the draws validation refused are counted by reason).

Each trial keeps a small record (`--out`/trials/<key>.json, well under 2 KB): jams, time jammed,
deliveries, escapes, every robot's longest gap without a delivery (the start of the run to its
first delivery and its last delivery to the end count too) and the wall time. A rerun resumes
(`--workers`, `--backend local|ray`). A robot that goes longer than `--max-gap-min` without a
delivery in a trial where the detector found no jam is an *unreported* jam: the study fails.
"""

from __future__ import annotations

import math
import re
import sys
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from scipy import stats

import tavc_env
from tavc_agents.analysis.reports import Report, fmt, markdown_table
from tavc_agents.experiments.registry import make_allocator
from tavc_agents.experiments.runner import run_trial
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import json_jobs
from tavc_env.config import ArenaConfig, Circuit, Robot, robots_from_speeds
from tavc_env.layout import WALL_CLEARANCE_M
from tavc_env.measurement import JAM_MOTION_M, JAM_WINDOW_S

ARMS = ("dahl2004", "lanes", "random")
FAST, SLOW = 0.30, 0.20
DAHL_MAX_K = 6  # k fast + k slow: 13 robots is the most dahl2004's lines hold
REFUSED_K = 7  # the team of 14 the report shows refused
RANDOM_BINS = ((2, 6), (7, 12), (13, 18), (19, 24))  # team sizes of the random arenas, grouped
CONFIDENCE = 0.95
Row = dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The liveness study's settings (its command line)."""

    reference: ClassVar = "liveness"
    quick_sizes: ClassVar = {
        **{"hours": 0.05, "seeds": 1, "teams": (3, 6), "per_circuit": (3, 24), "arenas": 3},
        **{"random_hours": 0.05, "random_seeds": 1},
    }
    recorded_fields: ClassVar = (
        "hours seeds=seed_list teams per_circuit arenas arena_seed random_hours "
        "random_seeds=random_seed_list max_gap_min"
    )

    hours: float = 4.0
    """simulated hours per trial of the dahl2004 and lanes arms"""
    seeds: int = 4
    """seeds per team of the dahl2004 and lanes arms (seed0, seed0 + 1, ...)"""
    seed0: int = 0
    """first seed"""
    teams: tuple[int, ...] = (3, 4, 5, 6)
    """dahl2004 arm: k fast + k slow robots for each k given (1-6)"""
    per_circuit: tuple[int, ...] = (3, 6, 12, 18, 24)
    """lanes arm: robots per circuit of the two-lane arenas (scaled_config(2, rpc))"""
    arenas: int = 120
    """random arm: number of random valid arenas"""
    arena_seed: int = 0
    """random arm: seed of the arena generator"""
    random_hours: float = 2.0
    """simulated hours per trial of the random arm"""
    random_seeds: int = 1
    """seeds per random arena"""
    max_gap_min: float = 60.0
    """unreported jam (the study fails): a robot this long without a delivery (simulated min) in
    a trial where the detector found no jam"""
    quick: bool = False
    """smoke run: 0.05 h trials, 1 seed, k = 3 and 6, rpc = 3 and 24, 3 random arenas"""
    quiet: bool = False
    """no progress output"""

    def __post_init__(self) -> None:
        super().__post_init__()
        teams_ok = (
            isinstance(self.teams, tuple)
            and len(self.teams) >= 1
            and all(at_least(k, 1) and k <= DAHL_MAX_K for k in self.teams)
            and len(set(self.teams)) == len(self.teams)
        )
        per_circuit_ok = (
            isinstance(self.per_circuit, tuple)
            and len(self.per_circuit) >= 1
            and all(at_least(n, 1) for n in self.per_circuit)
            and len(set(self.per_circuit)) == len(self.per_circuit)
        )
        checks = [
            ("hours", positive(self.hours), "> 0"),
            ("seeds", at_least(self.seeds, 1), "an integer >= 1"),
            ("seed0", at_least(self.seed0, 0), "an integer >= 0"),
            ("teams", teams_ok, f"distinct integers k in [1, {DAHL_MAX_K}] (k fast + k slow)"),
            ("per_circuit", per_circuit_ok, "distinct integers >= 1"),
            ("arenas", at_least(self.arenas, 0), "an integer >= 0"),
            ("arena_seed", at_least(self.arena_seed, 0), "an integer >= 0"),
            ("random_hours", positive(self.random_hours), "> 0"),
            ("random_seeds", at_least(self.random_seeds, 1), "an integer >= 1"),
            ("max_gap_min", positive(self.max_gap_min), "> 0"),
        ]
        refuse_invalid(self, checks)

    @property
    def seed_list(self) -> list[int]:
        return list(range(self.seed0, self.seed0 + self.seeds))

    @property
    def random_seed_list(self) -> list[int]:
        return list(range(self.seed0, self.seed0 + self.random_seeds))


# -- one trial ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Trial:
    """One trial as data: its arm, the size it stands for (k of dahl2004, robots per circuit of
    the lanes, the arena's number among the random ones), the seed, its length, and for a random
    arena its description (`tavc_agents.experiments.arenas.draw_arena`)."""

    arm: str
    size: int
    seed: int
    hours: float
    arena_seed: int | None = None
    arena: Mapping[str, Any] | None = field(default=None, compare=False)


def dahl_team(k: int) -> ArenaConfig:
    """`dahl2004` with k fast (0.30 m/s) and k slow (0.20 m/s) robots."""
    robots = tuple(Robot(FAST, "fast") for _ in range(k)) + tuple(
        Robot(SLOW, "slow") for _ in range(k)
    )
    return tavc_env.make_config("dahl2004", robots=robots)


def trial_config(trial: Trial) -> ArenaConfig:
    """The arena of `trial`."""
    if trial.arm == "dahl2004":
        return dahl_team(trial.size)
    if trial.arm == "lanes":
        return tavc_env.scaled_config(2, trial.size)
    assert trial.arena is not None
    return arena_config(trial.arena)


def trial_key(trial: Trial) -> str:
    if trial.arm == "dahl2004":
        size = f"k{trial.size}"
    elif trial.arm == "lanes":
        size = f"rpc{trial.size}"
    else:
        size = f"gen{trial.arena_seed}_a{trial.size:03d}"
    return f"{trial.arm}_{size}_seed{trial.seed}_{trial.hours:g}h"


def longest_gaps(
    times: Sequence[float], robots: Sequence[int], n_robots: int, end_s: float
) -> list[tuple[float, float]]:
    """Per robot, the (from, to) times of its longest gap without a delivery, given every
    delivery's time and robot: the start of the run to the first delivery and the last to
    `end_s` count too (a robot that never delivers has the whole run)."""
    last = [0.0] * n_robots
    best = [(0.0, 0.0)] * n_robots
    for t, i in zip(times, robots):
        if t - last[i] > best[i][1] - best[i][0]:
            best[i] = (last[i], t)
        last[i] = t
    for i in range(n_robots):
        if end_s - last[i] > best[i][1] - best[i][0]:
            best[i] = (last[i], end_s)
    return best


def run_one(trial: Trial) -> dict[str, Any]:
    """Run `trial` (random circuit choices) and return its compact record."""
    config = trial_config(trial)
    started = time.perf_counter()
    total = trial.hours * 3600.0
    result = run_trial(
        make_allocator("random"),
        seed=trial.seed,
        convergence_s=0.0,
        measured_s=total,
        snapshot_every_s=total,
        arena=config,
    )
    n = config.n_robots
    gaps = longest_gaps(result.delivery_time_s, result.delivery_robot, n, result.end_s)
    lengths = [to - frm for frm, to in gaps]
    worst = int(np.argmax(lengths))
    counts = np.bincount(np.asarray(result.delivery_robot, dtype=int), minlength=n)
    return {
        "robots": n,
        "circuits": config.n_circuits,
        "sim_s": round(result.end_s, 1),
        "jams": result.jams,
        "jammed_s": round(result.jammed_s, 1),
        "deliveries": len(result.delivery_time_s),
        "min_deliveries": int(counts.min()),
        "escapes": result.escapes,
        "capped_steps": result.capped_steps,
        "steps": result.steps,
        "longest_gap_s": round(lengths[worst], 1),
        "gap_robot": worst,
        "gap_from_s": round(gaps[worst][0], 1),
        "gap_to_s": round(gaps[worst][1], 1),
        "gaps_s": [round(g) for g in lengths],
        "wall_s": round(time.perf_counter() - started, 2),
    }


RUNS = json_jobs(run_one, trial_key, unit="trial")


def trials(settings: Settings) -> tuple[list[Trial], dict[str, Any]]:
    """The trials of `settings` (sized), the most expensive first so that a pool of workers ends
    together, and the random arenas' draw statistics."""
    s = settings.sized()
    seeds = range(s.seed0, s.seed0 + s.seeds)
    jobs = [Trial("dahl2004", k, seed, s.hours) for k in s.teams for seed in seeds]
    jobs += [Trial("lanes", rpc, seed, s.hours) for rpc in s.per_circuit for seed in seeds]
    draws = random_arenas(s.arenas, np.random.default_rng(s.arena_seed))
    jobs += [
        Trial("random", a, seed, s.random_hours, s.arena_seed, arena)
        for a, arena in enumerate(draws.arenas)
        for seed in range(s.seed0, s.seed0 + s.random_seeds)
    ]

    def cost(trial: Trial) -> float:
        config = trial_config(trial)
        return trial.hours * (config.n_robots + 4) / config.dt

    jobs.sort(key=cost, reverse=True)
    drawn = {"arenas": len(draws.arenas), "draws": draws.draws, "refused": draws.refused}
    return jobs, drawn


def refused_team() -> str:
    """The message with which dahl2004 refuses 7 fast + 7 slow robots."""
    try:
        dahl_team(REFUSED_K)
    except ValueError as error:
        return str(error)
    raise AssertionError(f"dahl2004 accepted {2 * REFUSED_K} robots; update DAHL_MAX_K")


# -- report -------------------------------------------------------------------------------------
def clopper_pearson(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float, float]:
    """Rate k / n with its exact (Clopper-Pearson) interval; nan for n = 0."""
    if n == 0:
        return (math.nan, math.nan, math.nan)
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=confidence, method="exact")
    return (k / n, float(ci.low), float(ci.high))


def trial_row(trial: Trial, result: Mapping[str, Any], limit_s: float) -> Row:
    """One CSV row: what the trial was and what it recorded (the per-robot gaps summarised)."""
    config = trial_config(trial)
    gaps = result["gaps_s"]
    label = {"dahl2004": "k", "lanes": "rpc", "random": "arena"}[trial.arm]
    starved = sum(g > limit_s for g in gaps)
    return {
        "key": trial_key(trial),
        "arm": trial.arm,
        "param": f"{label}={trial.size}",
        "seed": trial.seed,
        "hours": trial.hours,
        "robots": result["robots"],
        "circuits": result["circuits"],
        "width_m": config.width,
        "height_m": config.height,
        "dt_s": config.dt,
        "radius_m": config.robot_radius,
        "jams": result["jams"],
        "jammed_s": result["jammed_s"],
        "deliveries": result["deliveries"],
        "min_deliveries": result["min_deliveries"],
        "escapes": result["escapes"],
        "capped_steps": result["capped_steps"],
        "longest_gap_s": result["longest_gap_s"],
        "gap_robot": result["gap_robot"],
        "gap_from_s": result["gap_from_s"],
        "gap_to_s": result["gap_to_s"],
        "median_robot_gap_s": float(np.median(gaps)),
        "robots_over_limit": starved,
        "unreported": bool(starved and result["jams"] == 0),
        "wall_s": result["wall_s"],
    }


def team_label(row: Row) -> str:
    if row["arm"] != "random":
        return str(row["robots"])
    for lo, hi in RANDOM_BINS:
        if lo <= row["robots"] <= hi:
            return f"{lo}-{hi}"
    return str(row["robots"])


def group(rows: Sequence[Row], by: Callable[[Row], tuple[Any, ...]]) -> dict[tuple[Any, ...], Row]:
    """Rows grouped by `by`, each group summarised: trials, trials with a jam and the jam rate
    with its exact interval, jams, time jammed, the longest gap of any robot and the median of
    the robots' longest gaps, unreported jams, simulated hours and wall time."""
    groups: dict[tuple[Any, ...], list[Row]] = {}
    for row in rows:
        groups.setdefault(by(row), []).append(row)
    out = {}
    for key, members in groups.items():
        jammed = sum(r["jams"] > 0 for r in members)
        rate, low, high = clopper_pearson(jammed, len(members))
        worst = max(members, key=lambda r: r["longest_gap_s"])
        out[key] = {
            "trials": len(members),
            "trials_jammed": jammed,
            "jam_rate": rate,
            "jam_rate_low": low,
            "jam_rate_high": high,
            "jams": sum(r["jams"] for r in members),
            "jammed_s": sum(r["jammed_s"] for r in members),
            "escapes": sum(r["escapes"] for r in members),
            "longest_gap_s": worst["longest_gap_s"],
            "longest_gap_trial": worst["key"],
            "median_robot_gap_s": float(np.median([r["median_robot_gap_s"] for r in members])),
            "unreported": sum(r["unreported"] for r in members),
            "sim_h": sum(r["hours"] for r in members),
            "wall_s": sum(r["wall_s"] for r in members),
        }
    return out


def rate_cell(g: Row) -> str:
    return (
        f"{g['trials_jammed']}/{g['trials']} = {g['jam_rate']:.3f} "
        f"[{g['jam_rate_low']:.3f}, {g['jam_rate_high']:.3f}]"
    )


def group_table(groups: Mapping[tuple[Any, ...], Row], first: Sequence[str]) -> str:
    header = [
        *first,
        "trials",
        "jam rate [95% CI]",
        "jams",
        "jammed (s)",
        "escapes",
        "longest gap (s)",
        "median robot gap (s)",
        "unreported",
        "wall (s)",
    ]
    cells = [
        (
            *key,
            g["trials"],
            rate_cell(g),
            g["jams"],
            fmt(g["jammed_s"], 0),
            g["escapes"],
            fmt(g["longest_gap_s"], 0),
            fmt(g["median_robot_gap_s"], 0),
            g["unreported"],
            fmt(g["wall_s"], 0),
        )
        for key, g in groups.items()
    ]
    return markdown_table(header, cells)


def _team_order(key: tuple[Any, ...]) -> tuple[int, int]:
    arm, team = key
    return (ARMS.index(arm), int(str(team).split("-")[0]))


def verdict_lines(rows: Sequence[Row], overall: Row, s: Settings, wall_s: float) -> list[str]:
    worst = max(rows, key=lambda r: r["longest_gap_s"])
    unreported = [r for r in rows if r["unreported"]]
    over = [r for r in rows if r["robots_over_limit"]]
    kind = (
        "start to first delivery"
        if worst["gap_from_s"] == 0
        else "last delivery to the end"
        if worst["gap_to_s"] >= worst["hours"] * 3600 - 1e-6
        else "between deliveries"
    )
    return [
        f"- **{'FAIL' if unreported else 'PASS'}**: {len(unreported)} unreported jams (trials "
        f"where a robot went more than {s.max_gap_min:g} simulated minutes without a delivery "
        f"and the detector found no jam); {len(over)} trials with such a robot in all.",
        f"- Jam rate (trials with at least one detected jam): {rate_cell(overall)} "
        f"(exact {CONFIDENCE:.0%} interval); {overall['jams']} jams, "
        f"{overall['jammed_s']:.0f} s jammed in {overall['sim_h']:g} simulated hours.",
        f"- Longest gap of any robot without a delivery: {worst['longest_gap_s']:.0f} s = "
        f"{worst['longest_gap_s'] / 60:.1f} min (trial `{worst['key']}`, {worst['robots']} "
        f"robots, robot {worst['gap_robot']}, {kind}, {worst['gap_from_s']:.0f}-"
        f"{worst['gap_to_s']:.0f} s).",
        f"- Trials: {len(rows)} ({overall['sim_h']:g} simulated hours); escapes "
        f"{overall['escapes']}; steps that hit the step cap "
        f"{sum(r['capped_steps'] for r in rows)}.",
        f"- Wall time: {wall_s:.0f} s for this run; {overall['wall_s']:.0f} s of trial time in "
        "all (one core each).",
    ]


def report_body(
    rows: Sequence[Row], drawn: Mapping[str, Any], refusal: str, s: Settings, wall_s: float
) -> list[str]:
    overall = group(rows, lambda r: ())[()]
    arms = group(rows, lambda r: (r["arm"],))
    teams = dict(
        sorted(
            group(rows, lambda r: (r["arm"], team_label(r))).items(),
            key=lambda kv: _team_order(kv[0]),
        )
    )
    random_rows = [r for r in rows if r["arm"] == "random"]
    by_circuits = dict(sorted(group(random_rows, lambda r: (r["circuits"],)).items()))
    refused = ", ".join(f"{reason} {n}" for reason, n in drawn["refused"].items()) or "none"
    unreported = [r for r in rows if r["robots_over_limit"]]
    body = [
        "## What was run",
        "",
        "Every robot that must decide picks a circuit uniformly at random "
        "(`RandomAllocator` through `tavc_agents.experiments.runner.run_trial`, event-driven steps, "
        "step cap 600 s). The engine's jam detector counts a jam when no task event happened for "
        f"{JAM_WINDOW_S:g} s while no moving robot got {JAM_MOTION_M:g} m from where it stood; "
        "a trial is *jammed* if it found at least one. A robot's gap is the time between two of "
        "its deliveries, from the start of the trial to its first and from its last to the end "
        "of the trial included.",
        "",
        f"- `dahl2004`: the paper's arena with k fast ({FAST}) + k slow ({SLOW}) robots, "
        f"k = {', '.join(str(k) for k in s.teams)}; {s.hours:g} simulated hours x {s.seeds} "
        "seeds.",
        f"- `lanes`: `tavc_env.scaled_config(2, rpc)`, rpc = "
        f"{', '.join(str(n) for n in s.per_circuit)} robots per circuit; {s.hours:g} h x "
        f"{s.seeds} seeds.",
        f"- `random`: {drawn['arenas']} random valid arenas "
        f"(`tavc_agents.experiments.arenas.random_arenas`, generator seed {s.arena_seed}); "
        f"{s.random_hours:g} h x {s.random_seeds} seed(s) each. {drawn['draws']} draws, "
        f"{drawn['draws'] - drawn['arenas']} refused by the arena's validation: {refused}.",
        f"- A team of {2 * REFUSED_K} in `dahl2004` ({REFUSED_K} fast + {REFUSED_K} slow) is "
        f"refused: `{refusal}`",
        "",
        "## Verdict",
        "",
        *verdict_lines(rows, overall, s, wall_s),
        "",
        "## Per arm",
        "",
        group_table(arms, ["arm"]),
        "",
        "## Per team size",
        "",
        "Robots in the team (random arenas grouped by team size). Longest gap: of any robot in "
        "any trial of the row; median robot gap: the median over trials of the median robot's "
        "longest gap.",
        "",
        group_table(teams, ["arm", "robots"]),
        "",
        "## Random arenas by number of circuits",
        "",
        group_table(by_circuits, ["circuits"]),
        "",
        f"## Trials with a robot over {s.max_gap_min:g} min without a delivery",
        "",
    ]
    if unreported:
        header = ["trial", "robots", "jams", "robots over", "longest gap (s)", "from-to (s)"]
        cells = [
            (
                r["key"],
                r["robots"],
                r["jams"],
                r["robots_over_limit"],
                f"{r['longest_gap_s']:.0f}",
                f"{r['gap_from_s']:.0f}-{r['gap_to_s']:.0f}",
            )
            for r in unreported
        ]
        body.append(markdown_table(header, cells))
    else:
        body.append("None.")
    body += ["", "Every trial is a row of `liveness.csv`; its record is in `trials/<key>.json`."]
    return body


def summary(
    rows: Sequence[Row], drawn: Mapping[str, Any], refusal: str, s: Settings
) -> dict[str, Any]:
    def plain(groups: Mapping[tuple[Any, ...], Row]) -> list[Row]:
        return [{"group": list(key), **g} for key, g in groups.items()]

    worst = max(rows, key=lambda r: r["longest_gap_s"])
    return {
        "passed": not any(r["unreported"] for r in rows),
        "max_gap_limit_s": s.max_gap_min * 60.0,
        "overall": group(rows, lambda r: ())[()],
        "per_arm": plain(group(rows, lambda r: (r["arm"],))),
        "per_team": plain(group(rows, lambda r: (r["arm"], team_label(r)))),
        "longest_gap": {k: worst[k] for k in ("key", "robots", "longest_gap_s", "gap_robot")},
        "random_arenas": dict(drawn),
        "refused_team": {"robots": 2 * REFUSED_K, "message": refusal},
    }


def run(settings: Settings) -> Outcome:
    """Run (or resume) every trial, then write the report; the outcome lists the trials with an
    unreported jam."""
    out = settings.out_dir()
    s = settings.sized()
    jobs, drawn = trials(settings)
    done, provenance = settings.run_jobs(
        jobs,
        RUNS,
        "trials",
        wall_of=lambda result: float(result["wall_s"]),
        progress_bar=not s.quiet,
    )
    limit_s = s.max_gap_min * 60.0
    order = sorted(jobs, key=lambda t: (ARMS.index(t.arm), t.size, t.seed))
    rows = [trial_row(t, done[trial_key(t)], limit_s) for t in order]
    refusal = refused_team()
    body = report_body(rows, drawn, refusal, s, provenance["wall_time_s"])
    report = Report(
        "liveness",
        "Liveness: jams and gaps over team sizes and random arenas",
        "\n".join(body),
        rows,
        summary(rows, drawn, refusal, s),
    )
    written = report.write(out, provenance)
    start = body.index("## Verdict") + 2
    text = "\n".join([*body[start : start + 5], f"wrote {out / 'liveness.md'}"])
    return Outcome(out, written, text, failure_lines([r for r in rows if r["unreported"]]))


def failure_lines(unreported: Sequence[Row]) -> list[str]:
    """One line per trial with an unreported jam."""
    return [
        f"FAIL: trial {r['key']}: robot {r['gap_robot']} went {r['longest_gap_s'] / 60:.1f} "
        f"simulated minutes without a delivery ({r['gap_from_s']:.0f}-{r['gap_to_s']:.0f} s) "
        "and the detector found no jam"
        for r in unreported
    ]


# -- random valid arenas ------------------------------------------------------------------------
# Random valid arenas: a seeded generator of arena configurations for stress and liveness tests.
#
# An arena is drawn as plain JSON data (`draw_arena`, rounded so that it reads back exactly) and
# built with `arena_config`, which is where `tavc_env.ArenaConfig`'s validation accepts or refuses
# it. `random_arenas` draws until it has as many valid arenas as asked and counts the refused draws
# by the reason validation gave (`refusal_category`: a too-short waiting line, stations too close,
# too many robots for the floor, a physics step too long for the speed and radius, ...).
#
#     import numpy as np
#     draws = random_arenas(120, np.random.default_rng(0))
#     config = arena_config(draws.arenas[0])   # a tavc_env.ArenaConfig
#     draws.refused                            # {"waiting line too short": 57, ...}
#
# What is drawn (uniformly unless said otherwise): the floor (8-40 m x 6-30 m), 1-4 circuits, each
# with its source and sink anywhere inside the walls, a queue direction at any angle and a value in
# [1000, 2500]; 2-24 robots with top speeds in [0.1, 0.4] m/s; a robot radius in [0.15, 0.30] m;
# loading 2-25 s and unloading 1-8 s, scaled by speed in a quarter of the arenas; the physics step
# (0.05, 0.1 or 0.2 s); the waiting lines' offset and spacing (a little more than a robot diameter),
# the joining radius, the docking tolerance, the speed noise, the turn rate and the sensing range.
# The same generator state gives the same arenas.
WIDTH_M = (8.0, 40.0)
HEIGHT_M = (6.0, 30.0)
CIRCUITS = (1, 4)
ROBOTS = (2, 24)
SPEED_M_S = (0.1, 0.4)
RADIUS_M = (0.15, 0.30)
SOURCE_SERVICE_S = (2.0, 25.0)
SINK_SERVICE_S = (1.0, 8.0)
VALUE = (1000.0, 2500.0)
DTS = (0.05, 0.1, 0.2)
DT_WEIGHTS = (0.2, 0.6, 0.2)
SCALED_SERVICE_SHARE = 0.25
DRAWS_PER_ARENA = 5000  # `random_arenas` gives up after this many draws per arena asked for

# The description's scalar fields, as `ArenaConfig` names them; `speeds` and `circuits` (one
# [source x, source y, sink x, sink y, queue direction in degrees, value] each) complete it.
SCALARS = (
    "width",
    "height",
    "robot_radius",
    "dt",
    "source_service_s",
    "sink_service_s",
    "service_scales_with_speed",
    "queue_offset_m",
    "queue_spacing_m",
    "join_radius_m",
    "dock_tolerance_m",
    "speed_noise",
    "max_turn_rate",
    "sensing_range_m",
)


def _uniform(rng: np.random.Generator, bounds: tuple[float, float], digits: int) -> float:
    return round(float(rng.uniform(*bounds)), digits)


def draw_arena(
    rng: np.random.Generator, robots: int | None = None, circuits: int | None = None
) -> dict[str, Any]:
    """One candidate arena as JSON data (not yet validated: see `arena_config`), drawn from
    `rng` as the module describes; with `robots` or `circuits` given, a team or a number of
    circuits of that size."""
    width = _uniform(rng, WIDTH_M, 1)
    height = _uniform(rng, HEIGHT_M, 1)
    radius = _uniform(rng, RADIUS_M, 2)
    n_circuits = int(rng.integers(CIRCUITS[0], CIRCUITS[1] + 1)) if circuits is None else circuits
    n_robots = int(rng.integers(ROBOTS[0], ROBOTS[1] + 1)) if robots is None else robots
    margin = math.ceil((radius + WALL_CLEARANCE_M) * 100) / 100  # docks inside the walls

    def point() -> list[float]:
        return [
            round(float(rng.uniform(margin, width - margin)), 2),
            round(float(rng.uniform(margin, height - margin)), 2),
        ]

    lanes = [
        [*point(), *point(), int(rng.integers(360)), _uniform(rng, VALUE, 0)]
        for _ in range(n_circuits)
    ]
    speeds = [_uniform(rng, SPEED_M_S, 2) for _ in range(n_robots)]
    return {
        "width": width,
        "height": height,
        "robot_radius": radius,
        "dt": float(rng.choice(DTS, p=DT_WEIGHTS)),
        "source_service_s": _uniform(rng, SOURCE_SERVICE_S, 1),
        "sink_service_s": _uniform(rng, SINK_SERVICE_S, 1),
        "service_scales_with_speed": bool(rng.random() < SCALED_SERVICE_SHARE),
        "queue_offset_m": round(2 * radius + float(rng.uniform(0.1, 0.6)), 2),
        "queue_spacing_m": round(2 * radius + float(rng.uniform(0.05, 0.3)), 2),
        "join_radius_m": _uniform(rng, (1.0, 2.5), 2),
        "dock_tolerance_m": _uniform(rng, (0.08, 0.2), 2),
        "speed_noise": _uniform(rng, (0.0, 0.2), 2),
        "max_turn_rate": _uniform(rng, (1.0, 2.5), 2),
        "sensing_range_m": round(2.5 * radius + float(rng.uniform(0.2, 0.8)), 2),
        "speeds": speeds,
        "circuits": lanes,
    }


def arena_config(description: Mapping[str, Any]) -> ArenaConfig:
    """The arena `description` (from `draw_arena`) describes; a ValueError from the arena's
    validation if it is not a valid one."""
    circuits = tuple(
        Circuit(
            source=(float(sx), float(sy)),
            sink=(float(kx), float(ky)),
            value=float(value),
            queue_direction=(math.cos(math.radians(angle)), math.sin(math.radians(angle))),
        )
        for sx, sy, kx, ky, angle, value in description["circuits"]
    )
    return ArenaConfig(
        circuits=circuits,
        robots=robots_from_speeds([float(v) for v in description["speeds"]]),
        **{name: description[name] for name in SCALARS},
    )


def refusal_category(error: ValueError) -> str:
    """Why validation refused an arena, as a short category: what the message names, with
    circuit and robot indices dropped ("waiting line too short", "stations too close",
    "dt", "robots", ...)."""
    # a rule relating fields names them all ("dt, robot_radius, robots[0].speed"): the first
    name = str(error).partition(" = ")[0].split(", ")[0]
    if name.endswith("waiting line"):
        return "waiting line too short"
    if "(distance to " in name:
        return "stations too close"
    if re.fullmatch(r"circuits\[\d+\]\.(source|sink)", name):
        return "station outside the arena"
    if name == "robots":
        return "robots: too many for the floor"
    return re.sub(r"\[\d+\]", "[]", name)


@dataclass
class ArenaDraws:
    """What `random_arenas` drew: the valid arenas (descriptions, in the order drawn), how many
    draws it took, and the refused draws counted by `refusal_category`."""

    arenas: list[dict[str, Any]]
    draws: int
    refused: dict[str, int] = field(default_factory=dict)


def random_arenas(count: int, rng: np.random.Generator) -> ArenaDraws:
    """`count` valid arenas drawn from `rng`, refused draws counted by reason.

    Each arena's number of circuits and team size are drawn first (uniformly in `CIRCUITS` and
    `ROBOTS`) and kept: the rest of the arena is drawn again until validation accepts it. Many
    circuits and large teams are refused far more often (their lines need room: 4 circuits with
    20-24 robots about 1 draw in 100), so without this the valid arenas would be mostly one
    circuit and a small team. A RuntimeError if fewer than one draw in `DRAWS_PER_ARENA` is
    valid."""
    if not isinstance(count, int) or isinstance(count, bool) or count < 0:
        raise ValueError(f"count = {count!r} is invalid; allowed: an integer >= 0")
    arenas: list[dict[str, Any]] = []
    refused: Counter[str] = Counter()
    draws = 0
    while len(arenas) < count:
        circuits = int(rng.integers(CIRCUITS[0], CIRCUITS[1] + 1))
        robots = int(rng.integers(ROBOTS[0], ROBOTS[1] + 1))
        while True:
            if draws >= DRAWS_PER_ARENA * count:
                raise RuntimeError(
                    f"only {len(arenas)} valid arenas in {draws} draws (refused: {dict(refused)})"
                )
            description = draw_arena(rng, robots, circuits)
            draws += 1
            try:
                arena_config(description)
            except ValueError as error:
                refused[refusal_category(error)] += 1
                continue
            arenas.append(description)
            break
    return ArenaDraws(arenas, draws, dict(sorted(refused.items(), key=lambda kv: (-kv[1], kv[0]))))


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
