"""The design search for a congestion arena: which physical mechanisms (the clearance governor,
the loading time, station bays) give crowding elasticity e <= 1 while t(4)/t(3) >= 1.1 keeps
3 + 3 the homogeneous equilibrium? Fixed allocations only, no learning; the rules that pick the
arenas (`dahl2004_congestion`, and `dahl2004_bays` for the regime map) are in the study's
docstring (`benchmarks/congestion_design.py`).

Writes `congestion_design.{md,csv,json}` and every run (`runs/`) into a new run folder under
runs/ (git ignores it), `--out`, or with `--update-reference` benchmarks/results/congestion_design/
(congestion_design_bays/ for the second search, congestion_design_passing/ for the third);
`--resume RUN_DIR` continues an interrupted run.

    python benchmarks/congestion_design.py                 # 15 candidates x 3 seeds x 2 h
    python benchmarks/congestion_design.py --search bays   # the second search: 12 candidates
    python benchmarks/congestion_design.py --search passing  # the third: 18 candidates x 5 seeds
    python benchmarks/congestion_design.py --quick         # smoke run

Which physical arena gives crowding that costs fast and slow robots the same fraction of their
time (elasticity e <= 1) while 3 + 3 stays the homogeneous equilibrium (t(4)/t(3) >= 1.1 at
0.25 m/s)? A search over physical mechanisms only, measured with fixed allocations, no learning.
The script is `benchmarks/congestion_design.py`.

The candidates are `dahl2004` with
* the clearance governor (`clearance_governor_m`, see `tavc_env.engine.navigation`) off or over
  0.56, 1.06, 1.56 or 2.56 m of clearance, the sensing range raised to hold it (a longer-range
  laser: sensing = governor + 2 radii, at least the preset's 1 m);
* the source's loading time 4, 20 (the preset's) or 40 s: fixed handling time that every robot
  spends alike dilutes the part of a task that crowding stretches.

The rule, fixed before any candidate was measured: the arena shipped as `dahl2004_congestion` is
the candidate with the lowest e among those whose knee t(4)/t(3) is at least `knee` (point
estimates); if none of them reaches e <= 1, it is still that candidate, shipped as the closest,
and the report shows the frontier (the lowest e at each knee). No learning result enters.

The first search (`--search governor_loading`, the 15 candidates above) reached no e <= 1 and
chose `gov2.56_load40`. A second search (`--search bays`) adds the mechanism the first lacked:
stations with several bays (`station_bays`), which turn the loading time into handling time that
robots do not queue for, the one ingredient the physics-free model says gives e < 1 (fixed
handling time plus congestion in travel). Its candidates: 2 or 3 bays x governor off, 1.06 or
2.56 m x loading 20 or 40 s. Its rule, fixed before any of its candidates was measured: if a
candidate reaches e <= 1 with the knee, the lowest-e such candidate replaces the first search's
choice as `dahl2004_congestion` (which then stays in the regime map as another arena); if none
does, `dahl2004_congestion` stays, and the candidate with the lowest e, knee or not, joins the
regime map as `dahl2004_bays`: a physical point as far below e = 1 as this search reaches, to
test the model's prediction on both sides of 1.

Neither search reached e <= 1: in every candidate a fast robot sharing a circuit with a slow one
worked at the slow one's pace (one-robot docks serialise them, and the governor brakes for the
robot being overtaken), so crowding cost fast robots the larger share. The third search
(`--search passing`, 5 seeds) adds robots that can pass (`overtaking`: the governor reacts only to
robots in the robot's own path, and a robot dead ahead is passed on the side with room) to
stations with several bays. Its candidates, all with overtaking on: 2 or 3 bays x governor off,
1.06 or 2.56 m x loading 40, 80 or 120 s (18 arenas, the paper's two circuits, values and
robots). Each is measured from physics alone: e with its seed-bootstrap interval, the knee
t(4)/t(3) at 0.25 m/s, and the pace in company rho = T_slow(1,1) / T_fast(1,1) with its interval.
Its targets: **e <= 0.95 with the upper end of e's interval <= 1.0, t(4)/t(3) >= 1.1 and
rho >= 1.15** (point estimates but for e's upper end). Its rule, fixed before any of its
candidates was measured: candidates are ranked by how many of the three targets they meet (e's
counts as met only with its upper end), most first, then by e, lowest first; the first in that
order becomes `dahl2004_passing`, meeting all targets or, if none does, as the closest, with the
frontier (no other candidate has lower e, a higher knee and a higher rho) shown. It is then run
for 4 x 15 simulated hours (`benchmarks/long_run.py`); if that shows a jam or an overlap beyond
the envelope's tolerance, the next in the order takes its place. No learning result enters.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np

import arena_analysis as ia
import arena_runs
from arena_analysis import Elasticity, elasticity, seed_tables
from arena_runs import BOOT_SEED, elasticity_jobs
from tavc_agents.analysis.reports import Report, markdown_table
from tavc_agents.analysis.stats import ratio_ci
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
    replace,
    run_study,
)
from tavc_env import ArenaConfig, make_config
from tavc_env.measurement import two_circuit_allocation
from tavc_env.validation import is_number

GOVERNORS_M = (0.0, 0.56, 1.06, 1.56, 2.56)
LOADING_S = (4.0, 20.0, 40.0)
HOMOG_SPEED = 0.25
Row = dict[str, Any]


@dataclass(frozen=True)
class Candidate:
    """One arena of the search: `dahl2004` with these overrides."""

    governor_m: float
    loading_s: float
    bays: int = 1
    overtaking: bool = False

    @property
    def name(self) -> str:
        bays = f"_bays{self.bays}" if self.bays > 1 else ""
        passing = "_pass" if self.overtaking else ""
        return f"gov{self.governor_m:g}_load{self.loading_s:g}{bays}{passing}"

    def overrides(self) -> dict[str, Any]:
        out: dict[str, Any] = {"source_service_s": self.loading_s}
        if self.bays > 1:
            out["station_bays"] = self.bays
        if self.overtaking:
            out["overtaking"] = True
        if self.governor_m > 0:
            out["clearance_governor_m"] = self.governor_m
            out["sensing_range_m"] = max(1.0, round(self.governor_m + 2 * 0.22, 2))
        return out

    def config(self) -> ArenaConfig:
        return make_config("dahl2004", **self.overrides())


CANDIDATES = tuple(Candidate(g, load) for g in GOVERNORS_M for load in LOADING_S)
BAYS_CANDIDATES = tuple(
    Candidate(g, load, bays) for bays in (2, 3) for g in (0.0, 1.06, 2.56) for load in (20.0, 40.0)
)
PASSING_CANDIDATES = tuple(
    Candidate(g, load, bays, overtaking=True)
    for bays in (2, 3)
    for g in (0.0, 1.06, 2.56)
    for load in (40.0, 80.0, 120.0)
)
SEARCHES = {"governor_loading": CANDIDATES, "bays": BAYS_CANDIDATES, "passing": PASSING_CANDIDATES}
SEEDS = {"governor_loading": 3, "bays": 3, "passing": 5}
"""seeds per candidate, by search, unless --seeds says otherwise"""
E_TARGET = 0.95
"""the passing search's targets: e <= E_TARGET with its interval's upper end <= E_HIGH_TARGET, ..."""
E_HIGH_TARGET = 1.0
RHO_TARGET = 1.15
"""... and the pace in company rho >= RHO_TARGET (the knee's target is `Settings.knee`)"""


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The design search's settings (its command line)."""

    quick_reference_apart: ClassVar = False
    recorded_as_text: ClassVar = True
    recorded_fields: ClassVar = "seeds=n_seeds hours knee candidates=names quick"

    seeds: int | None = None
    """seeds per candidate (default: 3 in the first two searches, 5 in the passing search)"""
    hours: float = 2.0
    """simulated hours per run"""
    knee: float = 1.1
    """the least t(4)/t(3) a candidate must reach (3 + 3 stays the homogeneous equilibrium)"""
    search: Literal["governor_loading", "bays", "passing"] = "governor_loading"
    """which search: the first (clearance governor x loading time), the second (station bays x
    governor x loading time) or the third (overtaking robots x bays x governor x loading time)"""
    quick: bool = False
    """2 seeds x 0.4 h and three candidates (smoke run)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            (
                "seeds",
                self.seeds is None or at_least(self.seeds, 2),
                "an integer >= 2 (or None: the search's default)",
            ),
            ("hours", positive(self.hours), "> 0"),
            ("knee", is_number(self.knee) and self.knee >= 1, ">= 1"),
        ]
        refuse_invalid(self, checks)

    def sized(self) -> Settings:
        if self.quick:
            return replace(self, seeds=2, hours=0.4)
        return self if self.seeds is not None else replace(self, seeds=SEEDS[self.search])

    @property
    def n_seeds(self) -> int:
        n = self.sized().seeds
        assert n is not None
        return n

    def candidates(self) -> tuple[Candidate, ...]:
        candidates = SEARCHES[self.search]
        return candidates[::6] if self.quick else candidates

    @property
    def names(self) -> list[str]:
        """The candidates' names."""
        return [c.name for c in self.candidates()]

    def reference_name(self) -> str:
        suffix = "" if self.search == "governor_loading" else f"_{self.search}"
        return f"congestion_design{suffix}"


def knee_jobs(c: Candidate, seeds: Sequence[int], hours: float) -> list[arena_runs.Job]:
    """Homogeneous 0.25 m/s runs with 3 and 4 robots on circuit 0 (the rest on circuit 1)."""
    arena = tuple(sorted(c.overrides().items()))
    return [
        arena_runs.Job(
            experiment="t_n",
            preset="dahl2004",
            circuit_of=two_circuit_allocation(n),
            seed=seed,
            hours=hours,
            warmup_s=600.0,
            skip_first=2,
            speeds=(HOMOG_SPEED,) * 6,
            label=f"{c.name}_{ia.t_n_label(n)}",
            arena=arena,
        )
        for seed in seeds
        for n in (3, 4)
    ]


def cross_jobs(c: Candidate, seeds: Sequence[int], hours: float) -> list[arena_runs.Job]:
    jobs = elasticity_jobs(c.config(), seeds, hours, 10.0, 2)
    return [replace(j, label=f"{c.name}_{j.label}") for j in jobs]


def _t_n(rows: Sequence[Row], n: int) -> list[float]:
    """Per seed, the mean own-task time on circuit 0 with n robots there."""
    return [
        float(r["mean_task_time_s"])
        for r in rows
        if r["experiment"] == "t_n"
        and r["circuit"] == 0
        and r["n_on_circuit"] == n
        and r["robot_class"] == "all"
        and r["task_kind"] == "own"
    ]


def assess(c: Candidate, rows: Sequence[Row], seeds: Sequence[int]) -> Row:
    """A candidate's e [CI], t(3), t(4) and knee t(4)/t(3) [CI]."""
    cross = [dict(r, label=r["label"].removeprefix(f"{c.name}_")) for r in rows]
    e: Elasticity = elasticity(seed_tables(cross, seeds), np.random.default_rng(BOOT_SEED))
    t3, t4 = _t_n(rows, 3), _t_n(rows, 4)
    knee, low, high = ratio_ci(t4, t3)
    return {
        "candidate": c.name,
        "governor_m": c.governor_m,
        "sensing_m": c.config().sensing_range_m,
        "loading_s": c.loading_s,
        "bays": c.bays,
        "overtaking": c.overtaking,
        "e": e.e,
        "e_low": e.low,
        "e_high": e.high,
        "rho": e.rho,
        "rho_low": e.rho_low,
        "rho_high": e.rho_high,
        "rho_alone": e.rho_alone,
        "t3_s": float(np.mean(t3)),
        "t4_s": float(np.mean(t4)),
        "knee": knee,
        "knee_low": low,
        "knee_high": high,
    }


def choose(rows: Sequence[Row], knee: float) -> Row | None:
    """The rule of the module docstring: the lowest e among candidates with knee >= `knee`."""
    eligible = [r for r in rows if r["knee"] >= knee and math.isfinite(r["e"])]
    return min(eligible, key=lambda r: r["e"]) if eligible else None


def targets_met(row: Row, knee: float) -> dict[str, bool]:
    """Which of the passing search's three targets a candidate meets."""
    return {
        "e": row["e"] <= E_TARGET and row["e_high"] <= E_HIGH_TARGET,
        "knee": row["knee"] >= knee,
        "rho": row["rho"] >= RHO_TARGET,
    }


def passing_order(rows: Sequence[Row], knee: float) -> list[Row]:
    """The passing search's rule (module docstring): most targets met first, then lowest e."""
    finite = [r for r in rows if math.isfinite(r["e"])]
    return sorted(finite, key=lambda r: (-sum(targets_met(r, knee).values()), r["e"]))


def frontier(rows: Sequence[Row], with_rho: bool = False) -> list[Row]:
    """The candidates no other beats on every count (lower e and higher knee, and with `with_rho`
    higher rho too)."""

    def beats(o: Row, r: Row) -> bool:
        better = o["e"] < r["e"] and o["knee"] > r["knee"]
        return better and (not with_rho or o["rho"] > r["rho"])

    return sorted(
        (r for r in rows if not any(beats(o, r) for o in rows if o is not r)),
        key=lambda r: r["knee"],
    )


RULES = {
    "governor_loading": "The rule (fixed before measuring): lowest e among candidates with "
    "t(4)/t(3) >= {knee}.",
    "bays": "The rule (fixed before measuring): if candidates reach e <= 1 with t(4)/t(3) >= "
    "{knee}, the lowest-e of them becomes `dahl2004_congestion`; otherwise the lowest-e candidate "
    "joins the regime map as `dahl2004_bays`.",
    "passing": "The rule (fixed before measuring): targets e <= "
    f"{E_TARGET:g} with its interval's upper end <= {E_HIGH_TARGET:g}, t(4)/t(3) >= {{knee}} and "
    f"rho >= {RHO_TARGET:g}; candidates ranked by targets met, most first, then by e; the first "
    "becomes `dahl2004_passing` (if 4 x 15 h long runs show no jam and no overlap beyond the "
    "envelope, else the next).",
}


def _ci(r: Row, key: str) -> str:
    return f"{r[key]:.3f} [{r[key + '_low']:.3f}, {r[key + '_high']:.3f}]"


def _passing_verdict(rows: Sequence[Row], chosen: Row, knee: float) -> str:
    met = targets_met(chosen, knee)
    measured = (
        f"e = {_ci(chosen, 'e')}, t(4)/t(3) = {_ci(chosen, 'knee')}, rho = {_ci(chosen, 'rho')} "
        f"(alone {chosen['rho_alone']:.3f})"
    )
    if all(met.values()):
        return (
            f"**{chosen['candidate']} meets every target**: {measured}. By the rule it becomes "
            "`dahl2004_passing` (after its long-run health check)."
        )
    missed = ", ".join(name for name, ok in met.items() if not ok)
    return (
        f"**No candidate meets every target.** The closest by the rule, **{chosen['candidate']}**"
        f" ({measured}), misses: {missed}. It becomes `dahl2004_passing` as the closest (after "
        f"its long-run health check); {sum(any(targets_met(r, knee).values()) for r in rows)} of "
        f"{len(rows)} candidates meet at least one target. The frontier column marks the "
        "candidates no other beats on e, the knee and rho at once."
    )


def _verdict(rows: Sequence[Row], chosen: Row | None, s: Settings) -> str:
    reached = [r for r in rows if r["e"] <= 1.0 and r["knee"] >= s.knee]
    lowest = min(rows, key=lambda r: r["e"])
    if s.search == "passing":
        assert chosen is not None
        return _passing_verdict(rows, chosen, s.knee)
    if s.search == "bays" and not reached:
        return (
            f"**No candidate reaches e <= 1 together with t(4)/t(3) >= {s.knee}**, so "
            "`dahl2004_congestion` stays the first search's choice. By the rule, the lowest-e "
            f"candidate, **{lowest['candidate']}** (e = {_ci(lowest, 'e')}, t(4)/t(3) = "
            f"{_ci(lowest, 'knee')}), joins the regime map as `dahl2004_bays`."
        )
    if s.search == "bays":
        assert chosen is not None
        return (
            f"**{chosen['candidate']} reaches e <= 1 with the knee**: e = {_ci(chosen, 'e')}, "
            f"t(4)/t(3) = {_ci(chosen, 'knee')}. By the rule it becomes `dahl2004_congestion`."
        )
    if chosen is None:
        return f"No candidate reaches t(4)/t(3) >= {s.knee}; nothing is chosen."
    if reached:
        return (
            f"**Chosen: {chosen['candidate']}**, e = {_ci(chosen, 'e')}, t(4)/t(3) = "
            f"{_ci(chosen, 'knee')}: it reaches e <= 1 with the knee."
        )
    return (
        f"**No candidate reaches e <= 1 together with t(4)/t(3) >= {s.knee}.** The closest, "
        f"shipped by the rule, is **{chosen['candidate']}**: e = {_ci(chosen, 'e')}, "
        f"t(4)/t(3) = {_ci(chosen, 'knee')}. The frontier column marks the candidates no other "
        "beats on both counts."
    )


def report_body(rows: Sequence[Row], chosen: Row | None, s: Settings) -> str:
    on_frontier = frontier(rows, with_rho=s.search == "passing")
    table = markdown_table(
        [
            "candidate",
            "governor m",
            "sensing m",
            "loading s",
            "e [95% CI]",
            "rho [95% CI]",
            "rho alone",
            "t(3) s",
            "t(4) s",
            "t(4)/t(3) [95% CI]",
            "frontier",
        ],
        [
            [
                r["candidate"],
                f"{r['governor_m']:g}",
                f"{r['sensing_m']:g}",
                f"{r['loading_s']:g}",
                _ci(r, "e"),
                _ci(r, "rho"),
                f"{r['rho_alone']:.3f}",
                f"{r['t3_s']:.1f}",
                f"{r['t4_s']:.1f}",
                _ci(r, "knee"),
                "yes" if r in on_frontier else "",
            ]
            for r in rows
        ],
    )
    return "\n".join(
        [
            "## Verdict",
            "",
            _verdict(rows, chosen, s),
            "",
            "## Method",
            "",
            f"{len(rows)} candidates (`dahl2004` with the overrides named), {s.n_seeds} seeds x "
            f"{s.hours:g} h per run. e: the interference study's cross runs (f fast 0.30 m/s and "
            "s slow 0.20 m/s robots on circuit 0, the rest on circuit 1), its percentile "
            "bootstrap over seeds. rho = T_slow(1,1) / T_fast(1,1) from the same runs and "
            "bootstrap (rho alone: T_slow(0,1) / T_fast(1,0), its ceiling). Knee: homogeneous "
            "0.25 m/s runs with 3 and 4 robots on circuit 0, ratio of seed means with a "
            "delta-method interval. " + RULES[s.search].format(knee=s.knee),
            "",
            "## Candidates",
            "",
            table,
            "",
        ]
    )


def run(settings: Settings) -> Outcome:
    s = settings.sized()
    out = s.out_dir()
    seeds = list(range(s.n_seeds))
    jobs = [j for c in s.candidates() for j in knee_jobs(c, seeds, s.hours)]
    jobs += [j for c in s.candidates() for j in cross_jobs(c, seeds, s.hours)]
    results, provenance = s.run_jobs(jobs, arena_runs.RUNS, "runs", wall_of=lambda result: 0.0)
    rows = []
    for c in s.candidates():
        mine = [
            r
            for j in jobs
            if j.label.startswith(f"{c.name}_")
            for r in results[arena_runs.job_key(j)]["rows"]
        ]
        rows.append(assess(c, mine, seeds))
    chosen = passing_order(rows, s.knee)[0] if s.search == "passing" else choose(rows, s.knee)
    body = report_body(rows, chosen, s)
    report = Report(
        name="congestion_design",
        title="Congestion arena design",
        body=body,
        rows=rows,
        summary={
            "chosen": chosen,
            "frontier": [r["candidate"] for r in frontier(rows, with_rho=s.search == "passing")],
            **(
                {"order": [r["candidate"] for r in passing_order(rows, s.knee)]}
                if s.search == "passing"
                else {}
            ),
        },
    )
    written = report.write(out, provenance)
    return Outcome(out, written, body.split("## Method")[0])


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
