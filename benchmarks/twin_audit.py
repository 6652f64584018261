"""The model twin audited under random allocation: are its tables' own-circuit cells and its switch
cost right where crowds change at every decision, and how much of its disagreement with the
physics on random allocation does the switch cost explain? The design is in the study's docstring
(`benchmarks/twin_audit.py`).

Writes `twin_audit.{md,csv,json,png}`, every run (`runs/`) and the arenas' tables (`twin_tables/`)
into a new run folder (`--update-reference`: benchmarks/results/twin_audit/); `--resume RUN_DIR`
continues an interrupted run.

    python benchmarks/twin_audit.py           # 6 arenas x (10 physics + 2 x 40 twin runs) of 4 h
    python benchmarks/twin_audit.py --quick   # smoke run

Why does the model twin disagree with the physics on random allocation in the `dahl2004` family
while it agrees on the learners? An audit of the twin's two assumptions where they are most
strained: random allocation, whose crowds change at every decision and half of whose tasks are
switches.

For each arena of the regime map, the twin's tables are measured as the regime map measures them
(`benchmarks/regime_map.py`: the same runs, so the same tables), then the physics runs random
allocation for `--hours` per seed (no breakdowns, the first `--warmup-s` not counted) and every
task is set against its cell of the tables (`tavc_env.twin.random_allocation_run`):

* own-circuit tasks: observed time over the cell's mean (1: the tables are right under random
  allocation's changing crowds);
* switch tasks: observed time over the cell's mean, the switch cost random allocation really pays,
  against the tables' `switch_cost` (measured by one robot alternating every 3 tasks in a 3 + 3
  allocation).

Then the twin runs the same random allocation twice: with the tables as measured (the regime
map's twin), and with the switch cost replaced by the one the physics runs paid. The share of the
twin's performance gap that the second closes is the share the switch cost explains; what stays is
the own-circuit tables' error. Intervals are 95 % over seeds. The script is
`benchmarks/twin_audit.py`.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import arena_runs
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
    run_study,
)
from tavc_agents.experiments.sweep import json_jobs, run_jobs
from tavc_env.twin import InterferenceTables, random_allocation_run
from tavc_env.validation import is_number

Row = dict[str, Any]
Variant = Literal["physics", "twin_tables", "twin_audited_switch"]
VARIANTS: tuple[Variant, ...] = ("physics", "twin_tables", "twin_audited_switch")


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The twin audit's settings (its command line)."""

    reference: ClassVar = "twin_audit"
    quick_sizes: ClassVar = {"seeds": 2, "twin_seeds": 2, "hours": 0.5, "warmup_s": 300.0}
    recorded_fields: ClassVar = (
        "arenas=arena_list seeds twin_seeds hours warmup_s table_seeds table_hours"
    )

    arenas: str = ",".join(arena_runs.MAPPED)
    """comma-separated subset of the regime map's arenas"""
    seeds: int = 10
    """physics runs per arena"""
    twin_seeds: int = 40
    """twin runs per arena and variant"""
    hours: float = 4.0
    """simulated hours per run"""
    warmup_s: float = 600.0
    """simulated seconds at the start of each run that are not counted"""
    quick: bool = False
    """smoke run: 2 seeds (and 2 twin seeds) of 0.5 h, tables from 2 seeds of 0.4 h"""

    def __post_init__(self) -> None:
        super().__post_init__()
        choices(self, "arenas", arena_runs.ARENAS)  # an unknown arena is refused
        checks = [
            ("seeds", at_least(self.seeds, 2), "an integer >= 2"),
            ("twin_seeds", at_least(self.twin_seeds, 2), "an integer >= 2"),
            ("hours", positive(self.hours), "a finite number > 0"),
            (
                "warmup_s",
                is_number(self.warmup_s) and 0 <= self.warmup_s < self.hours * 3600.0,
                "a number of seconds >= 0, shorter than the run",
            ),
        ]
        refuse_invalid(self, checks)

    @property
    def arena_list(self) -> list[str]:
        return choices(self, "arenas", arena_runs.ARENAS)

    @property
    def table_runs(self) -> tuple[tuple[int, ...], float]:
        """Seeds and hours of the table runs: the regime map's, so the tables are its tables."""
        if self.quick:
            return (0, 1), 0.4  # the regime map's --quick tables
        default: dict[str, Any] = {
            f.name: f.default for f in dataclasses.fields(arena_runs.Settings)
        }
        return tuple(range(default["table_seeds"])), default["table_hours"]

    @property
    def table_seeds(self) -> tuple[int, ...]:
        return self.table_runs[0]

    @property
    def table_hours(self) -> float:
        return self.table_runs[1]


# -- jobs ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AuditRun:
    """One random-allocation run of `arena`: on the physics, or on the twin with the arena's
    tables (recorded by their digest) and `switch_cost` in place of theirs if > 0."""

    arena: str
    variant: Variant
    seed: int
    hours: float
    warmup_s: float
    tables_sha256: str
    switch_cost: float = 0.0
    arena_sha: str = ""
    tables: Mapping[str, Any] | None = None


def audit_key(job: AuditRun) -> str:
    return f"{job.arena}__{job.variant}__seed{job.seed}"


def run_audit(job: AuditRun) -> dict[str, Any]:
    """The run's performance and, per (class, switch or own), its tasks: how many, their summed
    time and their cells' summed mean time (the switch cost not applied)."""
    assert job.tables is not None, "an audit run needs the arena's tables"
    tables = InterferenceTables.from_dict(job.tables)
    if job.switch_cost > 0:
        tables = dataclasses.replace(tables, switch_cost=job.switch_cost)
    run = random_allocation_run(
        arena_runs.arena_config(job.arena),
        job.seed,
        job.hours,
        job.warmup_s,
        "physics" if job.variant == "physics" else "twin",
        tables,
    )
    groups: dict[str, list[float]] = {}
    for task in run.tasks:
        cell = tables.cell(task.circuit, task.counts, task.robot_class)
        group = groups.setdefault(
            f"{task.robot_class}:{'switch' if task.switch else 'own'}", [0, 0.0, 0.0]
        )
        group[0] += 1
        group[1] += task.task_time_s
        group[2] += cell.mean_s
    return {"performance": run.performance, "tasks": groups}


AUDITS = json_jobs(run_audit, audit_key, unit="run", omit=("tables",))


# -- analysis -----------------------------------------------------------------------------------
def pooled(results: Sequence[Mapping[str, Any]], kind: str, cls: str | None = None) -> list[float]:
    """Per run, the observed time over the cells' mean time of its `kind` ("own" or "switch")
    tasks (of class `cls`, or every class)."""
    out = []
    for r in results:
        n = observed = predicted = 0.0
        for name, (count, obs, pred) in r["tasks"].items():
            robot_class, _, task_kind = name.partition(":")
            if task_kind == kind and (cls is None or robot_class == cls):
                n, observed, predicted = n + count, observed + obs, predicted + pred
        if n:
            out.append(observed / predicted)
    return out


def switch_share(results: Sequence[Mapping[str, Any]]) -> float:
    counts = {"own": 0.0, "switch": 0.0}
    for r in results:
        for name, (count, _, _) in r["tasks"].items():
            counts[name.partition(":")[2]] += count
    return counts["switch"] / max(1.0, counts["own"] + counts["switch"])


def audited_switch_cost(physics: Sequence[Mapping[str, Any]]) -> float:
    """The switch cost the physics runs paid: all their switch tasks' time over their cells'."""
    observed = predicted = 0.0
    for r in physics:
        for name, (_, obs, pred) in r["tasks"].items():
            if name.endswith(":switch"):
                observed, predicted = observed + obs, predicted + pred
    return observed / predicted


def arena_row(
    arena: str, tables: InterferenceTables, runs: Mapping[Variant, Sequence[Mapping[str, Any]]]
) -> Row:
    perf = {v: [float(r["performance"]) for r in runs[v]] for v in VARIANTS}
    row: Row = {"arena": arena, "table_switch_cost": tables.switch_cost}
    row["switch_share"] = switch_share(runs["physics"])
    for name, values in (
        ("own_ratio", pooled(runs["physics"], "own")),
        ("switch_ratio", pooled(runs["physics"], "switch")),
        *((f"switch_ratio_{c}", pooled(runs["physics"], "switch", c)) for c in tables.classes),
    ):
        m, lo, hi, n = mean_ci(values)
        row |= {name: m, f"{name}_low": lo, f"{name}_high": hi}
    for v in VARIANTS:
        m, lo, hi, n = mean_ci(perf[v])
        row |= {f"perf_{v}": m, f"perf_{v}_low": lo, f"perf_{v}_high": hi, f"n_{v}": n}
    for v in VARIANTS[1:]:
        r, lo, hi = ratio_ci(perf[v], perf["physics"])
        row |= {f"{v}_over_physics": r, f"{v}_over_physics_low": lo, f"{v}_over_physics_high": hi}
    gap = row["perf_physics"] - row["perf_twin_tables"]
    closed = row["perf_twin_audited_switch"] - row["perf_twin_tables"]
    row["gap_closed_by_switch_cost"] = closed / gap if abs(gap) > 1e-12 else math.nan
    return row


def report_body(rows: Sequence[Row], s: Settings) -> str:
    def ci(r: Row, key: str, digits: int = 3) -> str:
        return fmt_ci(r[key], r[f"{key}_low"], r[f"{key}_high"], digits)

    tasks = [
        [
            r["arena"],
            f"{100 * r['switch_share']:.0f} %",
            ci(r, "own_ratio"),
            ci(r, "switch_ratio"),
            f"{r['table_switch_cost']:.3f}",
        ]
        for r in rows
    ]
    perf = [
        [
            r["arena"],
            ci(r, "perf_physics", 4),
            ci(r, "perf_twin_tables", 4),
            ci(r, "twin_tables_over_physics"),
            ci(r, "perf_twin_audited_switch", 4),
            ci(r, "twin_audited_switch_over_physics"),
            f"{100 * r['gap_closed_by_switch_cost']:.0f} %",
        ]
        for r in rows
    ]
    return "\n".join(
        [
            f"Random allocation, {s.seeds} physics runs and {s.twin_seeds} twin runs of each kind "
            f"per arena, {s.hours:g} simulated h each (the first {s.warmup_s:g} s not counted), "
            "no breakdowns; mean [95 % CI] over runs.",
            "",
            "### The tables under random allocation (physics tasks against their cells)",
            "",
            markdown_table(
                [
                    "arena",
                    "switch tasks",
                    "own tasks: observed / cell",
                    "switch tasks: observed / cell (the switch cost paid)",
                    "tables' switch cost",
                ],
                tasks,
            ),
            "",
            "### Performance (value per robot per 10 s) of random allocation",
            "",
            markdown_table(
                [
                    "arena",
                    "physics",
                    "twin, tables as measured",
                    "ratio to physics",
                    "twin, switch cost as paid",
                    "ratio to physics",
                    "gap closed",
                ],
                perf,
            ),
            "",
            "'Gap closed': the share of the difference between the twin (tables as measured) and "
            "the physics that replacing the tables' switch cost by the one paid removes; what "
            "remains comes from the own-circuit cells.",
        ]
    )


def plot(rows: Sequence[Row], path: Path) -> None:

    fig, ax = subplots(figsize=(8, 4))
    for offset, variant, label in (
        (-0.1, "twin_tables", "twin, tables as measured"),
        (0.1, "twin_audited_switch", "twin, switch cost as paid in the physics"),
    ):
        key = f"{variant}_over_physics"
        x = [k + offset for k in range(len(rows))]
        y = [r[key] for r in rows]
        err = [[r[key] - r[f"{key}_low"] for r in rows], [r[f"{key}_high"] - r[key] for r in rows]]
        ax.errorbar(x, y, yerr=err, fmt="o", capsize=3, label=label)
    ax.axhline(1, color="black", linewidth=0.8)
    ax.set_xticks(range(len(rows)), [r["arena"] for r in rows], rotation=20, fontsize=8)
    ax.set_ylabel("twin / physics performance (random)")
    ax.set_title("Random allocation: the twin's performance against the physics' (95 % CI)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


def run(settings: Settings) -> Outcome:
    """Measure every arena's tables, run (or resume) the physics and the twin as measured, then the
    twin with the switch cost the physics paid; write the report."""
    s = settings.sized()
    out = s.out_dir()
    arenas = s.arena_list
    seeds, hours = s.table_runs
    table_jobs = [arena_runs.TablesJob(a, seeds, hours, arena_runs.digest(a)) for a in arenas]
    done = run_jobs(
        table_jobs, arena_runs.TABLES, out / "twin_tables", s.workers, backend=s.backend
    )
    tables = {job.arena: done[arena_runs.TABLES.key(job)] for job in table_jobs}

    def jobs(
        variant: Variant, n: int, switch_cost: Mapping[str, float] | None = None
    ) -> list[AuditRun]:
        return [
            AuditRun(
                a,
                variant,
                seed,
                s.hours,
                s.warmup_s,
                arena_runs.tables_digest(tables[a]),
                (switch_cost or {}).get(a, 0.0),
                arena_runs.digest(a),
                tables[a],
            )
            for a in arenas
            for seed in range(n)
        ]

    measured = jobs("physics", s.seeds) + jobs("twin_tables", s.twin_seeds)
    results, provenance = s.run_jobs(measured, AUDITS, "runs")

    def of(
        batch: Sequence[AuditRun], done: Mapping[str, Any]
    ) -> dict[str, list[Mapping[str, Any]]]:
        by: dict[str, list[Mapping[str, Any]]] = {a: [] for a in arenas}
        for job in batch:
            by[job.arena].append(done[audit_key(job)])
        return by

    physics = of([j for j in measured if j.variant == "physics"], results)
    paid = {a: audited_switch_cost(physics[a]) for a in arenas}
    audited = jobs("twin_audited_switch", s.twin_seeds, paid)
    twin_paid = of(audited, run_jobs(audited, AUDITS, out / "runs", s.workers, backend=s.backend))
    twin_tables = of([j for j in measured if j.variant == "twin_tables"], results)
    rows = [
        arena_row(
            a,
            InterferenceTables.from_dict(tables[a]),
            {
                "physics": physics[a],
                "twin_tables": twin_tables[a],
                "twin_audited_switch": twin_paid[a],
            },
        )
        for a in arenas
    ]
    body = report_body(rows, s)
    report = Report(
        "twin_audit",
        "The model twin audited under random allocation",
        body,
        rows,
        summary={"switch_cost_paid": paid},
        figures=[("twin_audit.png", lambda path: plot(rows, path))],
    )
    written = report.write(out, provenance)
    return Outcome(out, written, body)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
