"""The regime map: fast minus slow time on the high-value circuit (the paper's effect), against
the crowding elasticity e of six arenas and the learner (softmax TAVC at four temperatures,
epsilon-greedy, random), with the model twin's prediction beside every physics cell.

Six arenas: the four shipped `dahl2004` variants, dahl2004_congestion and dahl2004_bays. Measures
each arena's e and twin tables, then runs 400 physics trials (15 h + 5 h) in each cell that decides
the question (softmax T = 0.005 and 0.01 on dahl2004_congestion and dahl2004), 60 in every other
cell and 100 twin trials per cell. Writes `regime_map.{md,csv,json,png}` and `provenance.json` into
a new run folder under runs/ (git ignores it), `--out`, or with `--update-reference`
benchmarks/results/regime_map/; every trial is kept as a compact record under the output folder's
trials/ as it finishes, so `--resume RUN_DIR` continues an interrupted run. The study is
`benchmarks/regime_map.py`.

    python benchmarks/arena_runs.py --workers 2     # about 3520 physics trials: many hours
    python benchmarks/arena_runs.py --quick         # smoke run (a minute or two)

The regime map: where does the paper's differentiation appear, where does it reverse, and why?

For each arena (the shipped `dahl2004` family, the congestion arena and the bays arena of the
second design search, spanning the crowding elasticity e) and each condition (softmax TAVC at T = 0.002, 0.005, 0.01, 0.02, epsilon-greedy
TAVC with epsilon 0.1, random allocation), physics trials of 15 h + 5 h report, with 95 %
intervals over trials: fast minus slow share of the measured period on the high-value circuit
(the paper's effect: > 0), the time in the state 3:0 (all three robots on the high-value circuit
fast), the learned Q gap of fast robots minus that of slow ones, and performance relative to
random allocation. Beside each cell, the model twin's prediction (`tavc_env.twin`, its tables
measured in the same arena): a what-if tool, never a substitute for the physics columns.

Each arena's e is measured first (`benchmarks/elasticity.py.measure_elasticity`, the interference
study's runs and settings), then its twin tables (`tavc_env.twin.build_tables`).
The cells that decide the question (softmax T = 0.005 and 0.01 on `dahl2004_congestion` and on
`dahl2004`) get `decisive_trials` physics trials; the congestion arena's run first, then the
twin's trials, then `dahl2004`'s decisive cells and the rest. Every other cell gets `trials`.
Trial k of every cell uses seed `seed + k`.

Every trial is kept as a compact record (its measures, about 1 KB) under `<out>/trials/` as it
finishes, so an interrupted sweep resumes where it stopped; the report is written when all
trials are in. The script is `benchmarks/arena_runs.py`.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from arena_analysis import Elasticity
from arena_runs import (
    CONDITIONS,
    DECISIVE,
    TABLES,
    TRIALS,
    Engine,
    Row,
    Settings,
    TablesJob,
    arena_config,
    cell_row,
    diff_of,
    digest,
    direction,
    measure_elasticity,
    overlap,
    physics_trials,
    softmax_condition,
    trial_key,
    twin_trials,
    welch_difference,
)
from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.study import (
    Outcome,
    run_study,
)
from tavc_agents.experiments.sweep import run_jobs, saved_results
from tavc_env import metrics


def summarise(
    records: Mapping[tuple[str, str, Engine], Sequence[Mapping[str, Any]]],
    e: Mapping[str, Elasticity],
    arenas: Sequence[str],
) -> list[Row]:
    """One row per arena and condition: the physics cell, the twin's beside it, and whether they
    agree (fast - slow: the Welch interval of their difference holds 0; performance / random: the
    two intervals overlap)."""
    rows = []
    for arena in arenas:
        for condition in CONDITIONS:
            phys = records.get((arena, condition, "physics"), [])
            if len(phys) < 2:
                continue  # an unfinished sweep's cell
            row: Row = {
                "arena": arena,
                "e": e[arena].e,
                "e_lo": e[arena].low,
                "e_hi": e[arena].high,
                "condition": condition,
                **cell_row(phys, records.get((arena, "random", "physics"), [])),
            }
            row["direction"] = direction(row)
            twin = records.get((arena, condition, "twin"), [])
            if len(twin) >= 2:
                t = cell_row(twin, records.get((arena, "random", "twin"), []))
                row.update({f"twin_{k}": v for k, v in t.items() if k != "wall_s"})
                row["twin_wall_s"] = t["wall_s"]
                dd = welch_difference(diff_of(phys), diff_of(twin))
                row.update({"physics_minus_twin": dd[0], "pmt_lo": dd[1], "pmt_hi": dd[2]})
                row["agree_fast_minus_slow"] = bool(dd[1] <= 0 <= dd[2])
                intervals = ((row["ratio_lo"], row["ratio_hi"]), (t["ratio_lo"], t["ratio_hi"]))
                known = all(math.isfinite(x) for pair in intervals for x in pair)
                # None: a random cell is missing, so there is no ratio to compare
                row["agree_ratio"] = overlap(*intervals) if known else None
            rows.append(row)
    return rows


# -- report -------------------------------------------------------------------------------------
def _ci(row: Row, key: str, lo: str, hi: str, digits: int = 3) -> str:
    return fmt_ci(row[key], row[lo], row[hi], digits)


def verdict_lines(rows: Sequence[Row]) -> list[str]:
    lines = []
    for arena, t in DECISIVE:
        row = next(
            (r for r in rows if r["arena"] == arena and r["condition"] == softmax_condition(t)),
            None,
        )
        if row is None:
            continue
        lines.append(
            f"- `{arena}` (e = {_ci(row, 'e', 'e_lo', 'e_hi')}), softmax T = {t:g}: fast - slow "
            f"= {_ci(row, 'fast_minus_slow', 'fast_minus_slow_lo', 'fast_minus_slow_hi')} over "
            f"{row['trials']} trials: **{row['direction']}** (the smallest effect {row['trials']} "
            f"trials detect with 80 % power: {row['detectable_80']:.3f})."
        )
    return lines


def cells_table(rows: Sequence[Row]) -> str:
    header = [
        "arena",
        "e",
        "condition",
        "N",
        "fast - slow (95 % CI)",
        "twin: N, fast - slow",
        "3:0 time %",
        "Q gap fast - slow",
        "perf / random",
        "twin perf / random",
    ]
    body = []
    for r in rows:
        twin = (
            f"{r['twin_trials']}, "
            + _ci(r, "twin_fast_minus_slow", "twin_fast_minus_slow_lo", "twin_fast_minus_slow_hi")
            if "twin_trials" in r
            else "-"
        )
        body.append(
            [
                r["arena"],
                f"{r['e']:.2f}",
                r["condition"],
                r["trials"],
                _ci(r, "fast_minus_slow", "fast_minus_slow_lo", "fast_minus_slow_hi"),
                twin,
                _ci(r, "time_3_0_pct", "time_3_0_lo", "time_3_0_hi", 1),
                _ci(r, "q_gap_fast_minus_slow", "q_gap_lo", "q_gap_hi", 4)
                if math.isfinite(r["q_gap_fast_minus_slow"])
                else "-",
                _ci(r, "ratio_to_random", "ratio_lo", "ratio_hi"),
                _ci(r, "twin_ratio_to_random", "twin_ratio_lo", "twin_ratio_hi")
                if "twin_trials" in r
                else "-",
            ]
        )
    return markdown_table(header, body)


def twin_table(rows: Sequence[Row]) -> str:
    header = [
        "arena",
        "condition",
        "physics - twin, fast - slow (95 % CI)",
        "agree",
        "perf / random agree",
    ]
    body = [
        [
            r["arena"],
            r["condition"],
            _ci(r, "physics_minus_twin", "pmt_lo", "pmt_hi"),
            "yes" if r["agree_fast_minus_slow"] else "**no**",
            "-" if r["agree_ratio"] is None else "yes" if r["agree_ratio"] else "**no**",
        ]
        for r in rows
        if "physics_minus_twin" in r and r["condition"] != "random"
    ]
    return markdown_table(header, body) if body else "(no twin trials)"


def wall_lines(rows: Sequence[Row], s: Settings) -> list[str]:
    phys = sum(r["wall_s"] for r in rows)
    n_phys = sum(r["trials"] for r in rows)
    twin = sum(r.get("twin_wall_s", 0.0) for r in rows)
    n_twin = sum(r.get("twin_trials", 0) for r in rows)
    per = phys / max(n_phys, 1)
    lines = [
        f"- Physics: {n_phys} trials, {phys / 3600:.2f} h of trial wall time in all, "
        f"{per:.1f} s per trial: a {s.decisive_trials}-trial cell takes about "
        f"{s.decisive_trials * per / 2 / 60:.0f} min on 2 workers.",
    ]
    if n_twin:
        lines.append(
            f"- Twin: {n_twin} trials, {twin / 3600:.2f} h, {twin / n_twin:.2f} s per trial "
            f"({per / max(twin / n_twin, 1e-9):.0f}x faster than the physics)."
        )
    return lines


def report_body(rows: Sequence[Row], s: Settings) -> str:
    agree = [r for r in rows if "agree_fast_minus_slow" in r and r["condition"] != "random"]
    n_agree = sum(bool(r["agree_fast_minus_slow"]) for r in agree)
    return "\n".join(
        [
            "## Verdict",
            "",
            *verdict_lines(rows),
            "",
            f"Twin against physics (fast - slow): {n_agree} of {len(agree)} learning cells agree "
            "(the Welch 95 % interval of physics minus twin holds 0).",
            "",
            "## Method",
            "",
            f"Arenas {', '.join(f'`{a}`' for a in s.arena_list)}; e from the interference "
            f"study's cross runs ({s.e_seeds} seeds x {s.e_hours:g} h, percentile bootstrap over "
            f"seeds). Trials of {s.convergence_h:g} h convergence + {s.measured_h:g} h measured, "
            f"trial k with seed {s.seed} + k; {s.decisive_trials} physics trials in the decisive "
            f"cells, {s.trials} in the others, {s.twin_trials} twin trials per cell (twin tables: "
            f"{s.table_seeds} seeds x {s.table_hours:g} h of fixed-allocation physics runs per "
            "arena). Fast - slow: per trial, the mean share of the measured period fast robots "
            "spend on the high-value circuit minus the slow robots'; mean and Student-t 95 % "
            "interval over trials. 3:0: % of the measured period with the three fast robots on "
            "the high-value circuit and no slow one (the paper's T, Eq. 3, for fair coins: "
            f"{metrics.combinatorial_expectation(3, 3)[(3, 0)]:.2f} %; the random rows measure it "
            "in each arena). Q gap: per robot, the mean over states of "
            "Q(high) - Q(other) in its final table; fast robots' mean minus slow robots' per "
            "trial. Perf / random: ratio of mean performance to the same engine's random cell "
            "(delta-method interval).",
            "",
            "## Cells",
            "",
            cells_table(rows),
            "",
            "## The twin against the physics",
            "",
            twin_table(rows),
            "",
            "## Wall time",
            "",
            *wall_lines(rows, s),
            "",
        ]
    )


def plot(rows: Sequence[Row], path: Path) -> None:
    """Fast - slow against e: physics points with 95 % intervals, the twin's curve, per
    condition."""

    import matplotlib

    fig, ax = subplots(figsize=(8, 5))
    learning = [c for c in CONDITIONS if c != "random"]
    colours = matplotlib.colormaps["viridis"](np.linspace(0, 0.9, len(learning)))
    for k, (condition, colour) in enumerate(zip(learning, colours)):
        pts = sorted((r for r in rows if r["condition"] == condition), key=lambda r: r["e"])
        if not pts:
            continue
        x = np.array([r["e"] for r in pts]) + (k - len(learning) / 2) * 0.012
        y = np.array([r["fast_minus_slow"] for r in pts])
        err = np.vstack(
            [y - [r["fast_minus_slow_lo"] for r in pts], [r["fast_minus_slow_hi"] for r in pts] - y]
        )
        ax.errorbar(
            x, y, yerr=err, fmt="o", color=colour, capsize=3, label=f"{condition} (physics)"
        )
        if all("twin_fast_minus_slow" in r for r in pts):
            ax.plot(
                [r["e"] for r in pts],
                [r["twin_fast_minus_slow"] for r in pts],
                "--",
                color=colour,
                linewidth=1,
            )
    ax.axhline(0, color="black", linewidth=0.8)
    ax.axvline(1, color="grey", linewidth=0.8, linestyle=":")
    ax.set_xlabel("crowding elasticity e (1: crowding costs every robot the same fraction)")
    ax.set_ylabel("fast - slow share of time on the high-value circuit")
    ax.set_title("Differentiation against e (points: physics, 95 % CI; dashed: model twin)")
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


# -- the study ----------------------------------------------------------------------------------
def run(settings: Settings) -> Outcome:
    """Measure e and the twin tables of every arena, run (or resume) every trial, then write the
    report and the figure."""
    s = settings.sized()
    out = s.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    arenas = s.arena_list
    print(f"regime map: arenas {arenas}; results in {out}", flush=True)
    e = {
        a: measure_elasticity(
            arena_config(a),
            range(s.e_seeds),
            s.e_hours,
            workers=s.workers,
            out=out / "elasticity" / a,
        )
        for a in arenas
    }
    tables: dict[str, Mapping[str, Any]] = {}
    if s.twin_trials:
        jobs = [TablesJob(a, tuple(range(s.table_seeds)), s.table_hours, digest(a)) for a in arenas]
        done = run_jobs(jobs, TABLES, out / "twin_tables", s.workers, backend=s.backend)
        tables = {job.arena: done[TABLES.key(job)] for job in jobs}
    physics = physics_trials(s)
    twin = twin_trials(s, tables) if tables else []
    # The first arena's decisive cells, then the twin (cheap: its predictions for every cell
    # early), then the other physics trials.
    first = physics[0].arena
    n_first = sum(
        1
        for j in physics
        if j.arena == first and s.trials_in(j.arena, j.condition) == s.decisive_trials
    )
    order = physics[:n_first] + twin + physics[n_first:]
    print(f"{len(physics)} physics trials, {len(twin)} twin trials", flush=True)
    if s.interim:
        results = saved_results(order, TRIALS, out / "trials")
        provenance = run_metadata(
            settings=s.recorded(), interim=True, trials_saved=len(results), trials=len(order)
        )
    else:
        results, provenance = s.run_jobs(
            order, TRIALS, "trials", wall_of=lambda result: float(result["wall_s"])
        )
    records: dict[tuple[str, str, Engine], list[dict[str, Any]]] = {}
    for job in order:
        if trial_key(job) in results:
            records.setdefault((job.arena, job.condition, job.engine), []).append(
                results[trial_key(job)]
            )
    rows = summarise(records, e, arenas)
    name = "regime_map_interim" if s.interim else "regime_map"
    body = report_body(rows, s)
    if s.interim:
        body = (
            f"**Interim report of an unfinished sweep: {len(results)} of {len(order)} trials "
            "saved so far.** Each cell states its N; the sweep resumes with the same command "
            "without `--interim`.\n\n" + body
        )
    report = Report(
        name,
        "The regime map: differentiation against crowding elasticity"
        + (" (interim)" if s.interim else ""),
        body,
        rows,
        summary={
            "elasticity": {a: {"e": v.e, "low": v.low, "high": v.high} for a, v in e.items()},
            "decisive": [
                r
                for r in rows
                if (r["arena"], r["condition"]) in {(a, softmax_condition(t)) for a, t in DECISIVE}
            ],
        },
        figures=[(f"{name}.png", lambda path: plot(rows, path))],
    )
    written = report.write(out, provenance)
    text = "\n".join([*verdict_lines(rows), f"wrote {out / (name + '.md')}"])
    return Outcome(out, written, text)


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
