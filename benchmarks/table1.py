"""Reproduce the paper's Table 1, Figure 2 and performance figure (the package's main job).

Softmax TAVC, epsilon-greedy TAVC and random allocation, 15 trials each of 15 simulated hours of
convergence and a 5-hour measured period, in parallel over all cores, each trial saved as it
finishes (`--resume RUN_DIR` continues an interrupted run). Writes table1.{md,csv,json}, figure2.png and performance.png into
benchmarks/results/table1_<preset>_<init>/ (the committed reference; a run writes into a new runs/ folder unless --update-reference or --out).

    python benchmarks/table1.py                 # full size: 3 x 15 trials x 20 simulated hours
    python benchmarks/table1.py --init paper    # the paper's literal Q initialisation
    python benchmarks/table1.py --quick         # a smoke run in seconds

Reproduce the paper's Table 1, Figure 2 and performance figure (the package's main job).

Three conditions, each `--trials` trials (default 15, as in the paper) of `--convergence-h` hours
(default 15, the paper's convergence period) followed by a measured stable period of `--measured-h`
hours (default 5): softmax TAVC (temperature 0.005), epsilon-greedy TAVC (epsilon 0.1) and random
allocation. Trials run in parallel over all cores and each is saved the moment it finishes, under
`<out>/trials/`; `--resume RUN_DIR` continues an interrupted run and never recomputes a finished
trial.

Outputs in the run folder (by default a new `runs/table1_<preset>_<init>-<time>/`; the committed
reference is `benchmarks/results/table1_<preset>_<init>/`, written with `--update-reference`):
`table1.{md,csv,json}` (state-time distribution of all f:s states next to the paper's values, T of Equation 3, differences
against random and against T, performance with 95 % confidence intervals, Welch's t-tests, time
shares of fast and slow robots on the high-value circuit, learned Q(high) - Q(low), lock-in
measures), `figure2.png` and `performance.png`.

With `--preset dahl2004_homogeneous` it reports instead the distribution of the number of robots
on the high-value circuit (the paper's homogeneous result: 3 most frequent under TAVC).

    python benchmarks/table1.py                 # full size: 3 x 15 trials x 20 simulated hours
    python benchmarks/table1.py --quick         # a smoke run in seconds
"""

from __future__ import annotations

import dataclasses
import json
import math
import shlex
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

from tavc_agents.analysis.measures import TrialMeasures, measure
from tavc_agents.analysis.plots import subplots
from tavc_agents.analysis.reports import Report, fmt, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci, mean_sd, ratio_ci, welch
from tavc_agents.experiments.files import atomic_path, read_csv
from tavc_agents.experiments.packs import is_saved
from tavc_agents.experiments.provenance import PROVENANCE_FILE
from tavc_agents.experiments.study import (
    Outcome,
    Overrides,
    StudySettings,
    arena_overrides,
    at_least,
    choices,
    compare_tables,
    differing_cells,
    positive,
    recorded_settings,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import TRIALS, TagValue, TrialSpec, saved_results
from tavc_env import PRESETS, make_config, metrics
from tavc_env.validation import is_number, require

# The paper's Table 1 (mu_a, s_a: modified TAVC; mu_r, s_r: random; T: Equation 3).
PAPER_TABLE1: dict[tuple[int, int], tuple[float, float, float, float, float]] = {
    (0, 0): (0.2, 0.2, 1.4, 0.5, 1.5),
    (0, 1): (1.5, 1.2, 3.4, 1.7, 4.7),
    (0, 2): (2.0, 2.6, 5.0, 1.4, 4.7),
    (0, 3): (0.5, 0.7, 2.0, 1.1, 1.5),
    (1, 0): (2.9, 1.6, 3.6, 1.4, 4.7),
    (1, 1): (12.1, 4.9, 13.5, 3.3, 14.1),
    (1, 2): (14.4, 6.1, 14.4, 2.4, 14.1),
    (1, 3): (4.1, 2.7, 4.0, 1.4, 4.7),
    (2, 0): (7.0, 5.0, 5.1, 1.2, 4.7),
    (2, 1): (19.4, 7.4, 15.7, 2.3, 14.1),
    (2, 2): (18.5, 5.0, 14.7, 3.0, 14.1),
    (2, 3): (5.7, 3.6, 4.4, 2.4, 4.7),
    (3, 0): (2.7, 4.1, 1.7, 0.6, 1.5),
    (3, 1): (5.2, 4.6, 5.2, 1.6, 4.7),
    (3, 2): (3.3, 2.6, 4.2, 1.2, 4.7),
    (3, 3): (0.7, 0.7, 1.5, 0.8, 1.5),
}
PAPER_PERFORMANCE = {"softmax": 0.081, "random": 0.078}
CONDITION_ORDER = ("softmax", "epsilon", "random")


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The Table 1 reproduction's settings (its command line)."""

    quick_sizes: ClassVar = {"trials": 2, "convergence_h": 0.3, "measured_h": 0.2}
    recorded_fields: ClassVar = (
        "preset trials convergence_h measured_h init temperature epsilon seed overrides"
    )

    preset: str = "dahl2004"
    """arena preset"""
    trials: int = 15
    """trials per condition"""
    convergence_h: float = 15.0
    """convergence period, simulated hours"""
    measured_h: float = 5.0
    """measured stable period, simulated hours"""
    conditions: str = "softmax,epsilon,random"
    """comma-separated subset of softmax, epsilon, random"""
    init: Literal["scaled", "paper"] = "scaled"
    """Q-table initialisation"""
    temperature: float = 0.005
    """softmax temperature"""
    epsilon: float = 0.1
    """epsilon of epsilon-greedy TAVC"""
    seed: int = 0
    """trial k uses seed + k in every condition"""
    quick: bool = False
    """smoke run: 2 trials of 0.3 + 0.2 hours"""
    set: Overrides = ()
    """arena override KEY=VALUE for every trial, e.g. --set source_service_s=15 (repeatable)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            ("preset", self.preset in PRESETS, f"one of {sorted(PRESETS)}"),
            ("trials", at_least(self.trials, 1), "an integer >= 1"),
            ("convergence_h", is_number(self.convergence_h) and self.convergence_h >= 0, ">= 0"),
            ("measured_h", positive(self.measured_h), "> 0"),
            ("temperature", positive(self.temperature), "> 0"),
            ("epsilon", is_number(self.epsilon) and 0 <= self.epsilon <= 1, "in [0, 1]"),
        ]
        refuse_invalid(self, checks)
        choices(self, "conditions", CONDITION_ORDER)  # an unknown condition is refused
        make_config(self.preset, **self.overrides)  # a bad arena is refused before any trial

    @property
    def chosen(self) -> list[str]:
        return choices(self, "conditions", CONDITION_ORDER)

    @property
    def overrides(self) -> dict[str, Any]:
        return arena_overrides(self.set)

    def reference_name(self) -> str:
        return f"table1_{self.preset}_{self.init}"


def labels(settings: Settings) -> dict[str, str]:
    """A readable name for each condition."""
    return {
        "softmax": f"softmax TAVC (T={settings.temperature}, {settings.init} init)",
        "epsilon": f"epsilon-greedy TAVC (eps={settings.epsilon}, {settings.init} init)",
        "random": "random allocation",
    }


def allocator_of(condition: str, settings: Settings) -> tuple[str, dict[str, Any]]:
    if condition == "softmax":
        return "softmax_tavc", {"temperature": settings.temperature, "init": settings.init}
    if condition == "epsilon":
        return "epsilon_tavc", {"epsilon": settings.epsilon, "init": settings.init}
    return "random", {}


def trial_key(tags: Mapping[str, TagValue]) -> str:
    return f"{tags['condition']}_seed{tags['seed']}"


def specs(settings: Settings) -> list[TrialSpec]:
    """Every trial of the study, tagged with its condition and seed."""
    s = settings.sized()
    env_kwargs = {"preset": s.preset, **s.overrides}
    out = []
    for k in range(s.trials):
        for condition in s.chosen:
            allocator, kwargs = allocator_of(condition, s)
            tags: dict[str, TagValue] = {"condition": condition, "seed": s.seed + k}
            out.append(
                TrialSpec(
                    key=trial_key(tags),
                    allocator=allocator,
                    allocator_kwargs=kwargs,
                    seed=s.seed + k,
                    env_kwargs=env_kwargs,
                    convergence_s=s.convergence_h * 3600.0,
                    measured_s=s.measured_h * 3600.0,
                    tags=tags,
                )
            )
    return out


def run(settings: Settings) -> Outcome:
    """Run (or resume) the trials, then write the report and figures."""
    out = settings.out_dir()
    out.mkdir(parents=True, exist_ok=True)
    trial_specs = specs(settings)
    s = settings.sized()
    print(
        f"{len(trial_specs)} trials ({', '.join(s.chosen)}) x "
        f"{s.convergence_h + s.measured_h:g} simulated hours on {s.preset}; results in {out}",
        flush=True,
    )
    results, provenance = settings.run_trials(trial_specs)
    by: dict[str, list[TrialMeasures]] = {c: [] for c in s.chosen}
    for spec in trial_specs:
        by[str(spec.tags["condition"])].append(measure(results[spec.key]))
    report = build_report(by, s, results[trial_specs[0].key].speed_classes)
    written = report.write(out, provenance)
    figures = [p.name for p in written[3:]]
    text = (
        f"\n{report.body}\nwall time {provenance['wall_time_s']:.0f} s; wrote {out / 'table1.md'}"
        + (f", {', '.join(figures)}" if figures else "")
    )
    return Outcome(out, written, text)


def settings_from_provenance(meta: Mapping[str, Any], out: Path) -> Settings:
    """The settings that made the results in `out` (as its provenance records them), with the
    conditions whose trials are saved there: rerunning them loads every trial and redraws."""
    recorded = meta.get("settings") if isinstance(meta, Mapping) else None
    fields = ("preset", "trials", "convergence_h", "measured_h", "init", "temperature", "epsilon")
    needed = (*fields, "seed")
    if not isinstance(recorded, dict) or any(name not in recorded for name in needed):
        missing = [n for n in needed if not isinstance(recorded, dict) or n not in recorded]
        raise ValueError(
            f"{out / PROVENANCE_FILE} records no settings {', '.join(missing)}: not the provenance "
            "of a table1 run; allowed: a table1 output folder"
        )
    overrides = recorded.get("overrides", {})
    if not isinstance(overrides, dict):
        raise ValueError(
            f"{out / PROVENANCE_FILE} records overrides = {overrides!r}; allowed: a JSON object"
        )
    base = Settings(
        **{name: recorded[name] for name in fields},
        seed=recorded["seed"],
        set=tuple(f"{k}={json.dumps(v)}" for k, v in overrides.items()),
        out=out,
    )
    saved = [
        c
        for c in CONDITION_ORDER
        if is_saved(out / "trials" / f"{trial_key({'condition': c, 'seed': base.seed})}.json")
    ]
    if not saved:
        raise ValueError(f"{out}/trials holds no saved trials; allowed: a table1 output folder")
    return dataclasses.replace(base, conditions=",".join(saved))


def resume_command(settings: Settings, folder: Path) -> str:
    """The command that finishes the trials of `settings` (sized) in `folder`."""
    s = settings
    options = [
        f"--preset {s.preset}",
        f"--trials {s.trials}",
        f"--convergence-h {s.convergence_h}",
        f"--measured-h {s.measured_h}",
        f"--conditions {s.conditions}",
        f"--init {s.init}",
        f"--temperature {s.temperature}",
        f"--epsilon {s.epsilon}",
        f"--seed {s.seed}",
        *(f"--set {shlex.quote(entry)}" for entry in s.set),
    ]
    return f"python benchmarks/table1.py --resume {shlex.quote(str(folder))} {' '.join(options)}"


FIGURES = ("figure2.png", "performance.png")


def draw_figure(folder: Path, figure: str, path: Path) -> None:
    """Draw one of Table 1's figures (`FIGURES`) from the trials saved in the output folder
    `folder`, into `path`, and write nothing else (no report, no other figure)."""
    from tavc_agents.experiments.provenance import load_provenance

    require(figure in FIGURES, "figure", figure, f"one of {list(FIGURES)}")
    meta = load_provenance(folder)
    require(meta is not None, "folder", str(folder), "an output folder of the table1 study")
    assert meta is not None
    s = settings_from_provenance(meta, folder).sized()
    trial_specs = specs(s)
    # A redraw never computes: the trials are read, and any not saved are named, not run.
    results = saved_results(trial_specs, TRIALS, folder / "trials")
    missing = [t.key for t in trial_specs if t.key not in results]
    if missing:
        raise ValueError(
            f"{folder} holds {len(results)} of the {len(trial_specs)} trials its provenance "
            f"records ({len(missing)} missing, e.g. {missing[0]}); a redraw computes nothing: "
            f"finish them with `{resume_command(s, folder)}`, then redraw"
        )
    by: dict[str, list[TrialMeasures]] = {c: [] for c in s.chosen}
    for spec in trial_specs:
        by[str(spec.tags["condition"])].append(measure(results[spec.key]))
    report = build_report(by, s, results[trial_specs[0].key].speed_classes)
    drawers = dict(report.figures)
    require(
        figure in drawers,
        "figure",
        figure,
        f"one of those these trials have: {sorted(drawers)} (Figure 2 needs the softmax and random "
        "conditions of a team of two speed classes)",
    )
    with atomic_path(path) as tmp:
        drawers[figure](tmp)


# -- the report ----------------------------------------------------------------------------------
def build_report(
    by: dict[str, list[TrialMeasures]], settings: Settings, speed_classes: Sequence[str]
) -> Report:
    names = {c: labels(settings)[c] for c in by}
    fast = sum(c == "fast" for c in speed_classes)
    slow = sum(c == "slow" for c in speed_classes)
    heterogeneous = fast > 0 and slow > 0 and fast + slow == len(speed_classes)
    overrides = settings.overrides
    sections = [
        f"Conditions: {'; '.join(names.values())}. {settings.trials} trials each, "
        f"{settings.convergence_h:g} h convergence + {settings.measured_h:g} h measured "
        f"(simulated). Preset `{settings.preset}`{' with ' + str(overrides) if overrides else ''}; "
        f"Q-table initialisation `{settings.init}`.",
        "",
    ]
    rows: list[dict[str, Any]] = []
    if heterogeneous:
        rows = state_rows(by, (fast, slow))
        sections += [
            "## State-time distribution (% of the measured period; mu_a = softmax TAVC, "
            "mu_r = random)",
            "",
            "The paper's printed column `mu_a - mu_r` is in fact `mu_a - T` (erratum, DESIGN.md "
            "section 3); both comparisons are given.",
            "",
            state_table_markdown(rows, list(by)),
            "",
        ]
    sections.append(occupancy_markdown(by, names))
    body, summary = summary_section(by, names, heterogeneous)
    sections.append(body)
    csv_rows = rows or [
        {
            "condition": c,
            **{
                f"on_high_{k}": v
                for k, v in enumerate(np.mean([m.robots_on_high for m in ms], axis=0))
            },
        }
        for c, ms in by.items()
    ]
    figures = []
    if rows and "a_minus_r" in rows[0]:
        figures.append(("figure2.png", lambda path: plot_figure2(rows, path)))
    figures.append(("performance.png", lambda path: plot_performance(by, names, path)))
    return Report(
        "table1", "Table 1 reproduction", "\n".join(sections), csv_rows, summary, figures=figures
    )


def state_rows(by: dict[str, list[TrialMeasures]], team: tuple[int, int]) -> list[dict[str, Any]]:
    """One row per f:s state: each condition's mean and sd, T, and the differences."""
    expected = metrics.combinatorial_expectation(*team)
    rows = []
    for key in sorted(expected):
        row: dict[str, Any] = {"state": f"{key[0]}:{key[1]}", "T": expected[key]}
        for cond, ms in by.items():
            row[f"mu_{cond}"], row[f"sd_{cond}"] = mean_sd([m.states[key] for m in ms])
        if "softmax" in by and "random" in by:
            mu_a, mu_r, t = row["mu_softmax"], row["mu_random"], expected[key]
            row["a_minus_r"] = mu_a - mu_r
            row["a_minus_r_rel"] = (mu_a - mu_r) / mu_r if mu_r > 0 else math.nan
            row["a_minus_T"] = mu_a - t
            row["a_minus_T_rel"] = (mu_a - t) / t
        if key in PAPER_TABLE1 and team == (3, 3):
            pa, psa, pr, psr, pt = PAPER_TABLE1[key]
            row.update(paper_mu_a=pa, paper_sd_a=psa, paper_mu_r=pr, paper_sd_r=psr)
            row["paper_a_minus_T_rel"] = (pa - pt) / pt
        rows.append(row)
    return rows


def state_table_markdown(rows: list[dict[str, Any]], conds: Sequence[str]) -> str:
    header = ["f:s"]
    for c in conds:
        header += [f"mu {c}", f"sd {c}"]
    header += ["T", "mu_a - mu_r", "(mu_a - mu_r)/mu_r", "mu_a - T", "(mu_a - T)/T"]
    paper = "paper_mu_a" in rows[0]
    if paper:
        header += ["paper mu_a (sd)", "paper mu_r (sd)", "paper (mu_a - T)/T"]
    body = []
    for r in rows:
        line = [r["state"]]
        for c in conds:
            line += [fmt(r[f"mu_{c}"]), fmt(r[f"sd_{c}"])]
        line += [
            fmt(r["T"]),
            fmt(r.get("a_minus_r", math.nan)),
            fmt(r.get("a_minus_r_rel", math.nan), 2),
            fmt(r.get("a_minus_T", math.nan)),
            fmt(r.get("a_minus_T_rel", math.nan), 2),
        ]
        if paper:
            line += [
                f"{r['paper_mu_a']} ({r['paper_sd_a']})",
                f"{r['paper_mu_r']} ({r['paper_sd_r']})",
                fmt(r["paper_a_minus_T_rel"], 2),
            ]
        body.append(line)
    return markdown_table(header, body)


def performance_section(
    by: dict[str, list[TrialMeasures]], names: Mapping[str, str], summary: dict[str, Any]
) -> list[str]:
    rows = []
    for cond, ms in by.items():
        m, lo, hi, n = mean_ci([x.performance for x in ms])
        summary[f"performance_{cond}"] = {"mean": m, "ci95": [lo, hi], "n": n}
        rows.append([names[cond], fmt_ci(m, lo, hi, 4), n])
    lines = ["## Performance (delivered value per robot per 10 s, 95 % CI over trials)", ""]
    lines.append(markdown_table(["condition", "value / robot / 10 s", "trials"], rows))
    lines.append("")
    lines.append(
        f"Paper: softmax TAVC {PAPER_PERFORMANCE['softmax']}, random {PAPER_PERFORMANCE['random']}"
        f" (ratio {PAPER_PERFORMANCE['softmax'] / PAPER_PERFORMANCE['random']:.3f})."
    )
    for other in ("random", "epsilon"):
        if "softmax" in by and other in by and by[other]:
            r, lo, hi = ratio_ci(
                [x.performance for x in by["softmax"]], [x.performance for x in by[other]]
            )
            summary[f"performance_ratio_softmax_{other}"] = {"ratio": r, "ci95": [lo, hi]}
            lines.append(f"- softmax / {other} performance ratio: {fmt_ci(r, lo, hi, 3)}")
    lines.append("")
    return lines


def tests_section(
    by: dict[str, list[TrialMeasures]], heterogeneous: bool, summary: dict[str, Any]
) -> list[str]:
    tests = []
    for other in ("random", "epsilon"):
        if "softmax" not in by or other not in by:
            continue
        pairs: list[tuple[str, Callable[[TrialMeasures], float]]] = [
            ("performance", lambda x: x.performance)
        ]
        if heterogeneous:
            pairs.insert(0, ("time in 3:0 (%)", lambda x: x.states[(3, 0)]))
        for what, get in pairs:
            a = [get(x) for x in by["softmax"]]
            b = [get(x) for x in by[other]]
            t, p = welch(a, b)
            summary[f"welch_{what.split()[0]}_softmax_vs_{other}"] = {"t": t, "p": p}
            tests.append(
                [
                    what,
                    f"softmax vs {other}",
                    fmt(float(np.mean(a)), 4),
                    fmt(float(np.mean(b)), 4),
                    fmt(t, 2),
                    f"{p:.3g}" if math.isfinite(p) else "-",
                ]
            )
    lines = ["## Statistical tests (Welch's unequal-variance t-test, two-sided, over trials)", ""]
    lines.append(markdown_table(["measure", "comparison", "mean A", "mean B", "t", "p"], tests))
    lines.append("")
    return lines


def shares_section(
    by: dict[str, list[TrialMeasures]], names: Mapping[str, str], summary: dict[str, Any]
) -> list[str]:
    rows = []
    for cond, ms in by.items():
        f = mean_ci([x.fast_share for x in ms])
        s = mean_ci([x.slow_share for x in ms])
        d = mean_ci([x.fast_share - x.slow_share for x in ms])
        qf = mean_ci([x.q_gap_fast for x in ms])
        qs = mean_ci([x.q_gap_slow for x in ms])
        summary[f"shares_{cond}"] = {
            "fast": f[:3],
            "slow": s[:3],
            "fast_minus_slow": d[:3],
            "q_gap_fast": qf[:3],
            "q_gap_slow": qs[:3],
        }
        rows.append(
            [
                names[cond],
                fmt_ci(*f[:3], 3),
                fmt_ci(*s[:3], 3),
                fmt_ci(*d[:3], 3),
                fmt_ci(*qf[:3], 4),
                fmt_ci(*qs[:3], 4),
            ]
        )
    lines = [
        "## Who serves the high-value circuit (fraction of the measured period, 95 % CI)",
        "",
        "Q gap = mean over states of Q(s, high) - Q(s, low) in the final Q-tables.",
        "",
    ]
    header = ["condition", "fast", "slow", "fast - slow", "Q gap fast", "Q gap slow"]
    lines.append(markdown_table(header, rows))
    lines.append("")
    return lines


def lockin_section(
    by: dict[str, list[TrialMeasures]], names: Mapping[str, str], summary: dict[str, Any]
) -> list[str]:
    rows = []
    for cond, ms in by.items():
        settled = fmt(100 * float(np.mean([x.settled_first_hour for x in ms])), 0)
        if not math.isfinite(ms[0].never_updated):
            rows.append([names[cond], "-", "-", settled])
            continue
        never = float(np.mean([x.never_updated for x in ms]))
        non_greedy = float(np.mean([x.non_greedy_per_hour for x in ms]))
        rows.append([names[cond], fmt(never, 2), fmt(non_greedy, 1), settled])
        summary[f"lockin_{cond}"] = {
            "settled_in_first_hour": float(np.mean([x.settled_first_hour for x in ms])),
            "never_updated_entries_per_robot": never,
            "non_greedy_choices_per_robot_hour": non_greedy,
        }
    if not rows:
        return []
    header = [
        "condition",
        "Q entries never updated",
        "non-greedy choices per hour",
        "% of robots never changing circuit after hour 1",
    ]
    return [
        "## Lock-in measures (per robot, mean over trials)",
        "",
        markdown_table(header, rows),
        "",
    ]


def summary_section(
    by: dict[str, list[TrialMeasures]], names: Mapping[str, str], heterogeneous: bool
) -> tuple[str, dict[str, Any]]:
    summary: dict[str, Any] = {}
    lines = performance_section(by, names, summary)
    lines += tests_section(by, heterogeneous, summary)
    if heterogeneous:
        lines += shares_section(by, names, summary)
    lines += lockin_section(by, names, summary)
    return "\n".join(lines), summary


def occupancy_markdown(by: dict[str, list[TrialMeasures]], names: Mapping[str, str]) -> str:
    n = len(next(iter(by.values()))[0].robots_on_high) - 1
    header = ["condition"] + [f"{k} on high" for k in range(n + 1)] + ["most frequent"]
    rows = []
    for cond, ms in by.items():
        dist = np.mean([m.robots_on_high for m in ms], axis=0) * 100
        rows.append([names[cond]] + [fmt(v) for v in dist] + [int(np.argmax(dist))])
    return (
        "## Number of robots on the high-value circuit (% of the measured period)\n\n"
        + markdown_table(header, rows)
        + "\n"
    )


# -- figures -------------------------------------------------------------------------------------
def plot_figure2(rows: list[dict[str, Any]], path: Path) -> None:
    """The paper's Figure 2: softmax TAVC minus random per state, absolute and relative."""

    states = [r["state"] for r in rows]
    fig, axes = subplots(2, 1, figsize=(9, 6), sharex=True)
    axes[0].bar(states, [r["a_minus_r"] for r in rows], color="tab:blue")
    axes[0].set_ylabel("mu_a - mu_r (% of time)")
    axes[1].bar(states, [r["a_minus_r_rel"] for r in rows], color="tab:orange")
    axes[1].set_ylabel("(mu_a - mu_r) / mu_r")
    axes[1].set_xlabel("state f:s (fast, slow robots on the high-value circuit)")
    for ax in axes:
        ax.axhline(0, color="black", linewidth=0.8)
    axes[0].set_title("Softmax TAVC against random allocation (cf. the paper's Figure 2)")
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


def plot_performance(
    by: dict[str, list[TrialMeasures]], names: Mapping[str, str], path: Path
) -> None:
    """Performance per condition with 95 % intervals."""

    fig, ax = subplots(figsize=(6, 4))
    labels_, means, errs = [], [], []
    for cond, ms in by.items():
        m, lo, hi, _ = mean_ci([x.performance for x in ms])
        labels_.append(names[cond].split(" (")[0])
        means.append(m)
        errs.append([[m - lo if math.isfinite(lo) else 0], [hi - m if math.isfinite(hi) else 0]])
    err = np.array(errs).squeeze(-1).T if errs else None
    colours = ["tab:blue", "tab:green", "tab:gray"][: len(labels_)]
    ax.bar(labels_, means, yerr=err, capsize=6, color=colours)
    ax.set_ylabel("delivered value per robot per 10 s")
    ax.set_title("Performance (95 % CI over trials)")
    ax.set_ylim(bottom=0)  # zero-based: bar heights compare as ratios
    fig.tight_layout()
    fig.savefig(path, dpi=120, format="png")


# -- agreement with the committed reference ----------------------------------------------------------
def agreement(out: Path, reference: Path) -> list[str]:
    """Whether this run's Table 1 agrees with the committed reference: bit-identical where the
    seeds and the code match; otherwise, cell by cell (state x condition), whether the two means
    lie within each other's noise (|difference| <= 1.96 standard errors of the difference)."""
    lines = compare_tables(out, reference)
    fresh, ref = out / "table1.csv", reference / "table1.csv"
    settings = recorded_settings(fresh)
    comparable = settings is not None and settings == recorded_settings(ref)
    if not comparable or differing_cells(fresh, ref)[0] == 0:
        return lines  # (not comparable, or identical: compare_tables said which)
    assert settings is not None
    n = int(settings["trials"])
    new, old = _rows(fresh), _rows(ref)
    within = total = 0
    for state in new.keys() & old.keys():
        for condition in ("softmax", "epsilon", "random"):
            mu, sd = f"mu_{condition}", f"sd_{condition}"
            if mu not in new[state] or mu not in old[state]:
                continue
            se = math.hypot(float(new[state][sd]), float(old[state][sd])) / math.sqrt(n)
            total += 1
            within += abs(float(new[state][mu]) - float(old[state][mu])) <= 1.96 * se + 1e-12
    return [
        *lines,
        f"Table 1: {within} of {total} cells (state x condition) agree with the reference within "
        "1.96 standard errors of the difference (with 95 % intervals about 1 in 20 cells may "
        "fall outside by chance)",
    ]


def _rows(path: Path) -> dict[str, dict[str, str]]:
    return {row["state"]: row for row in read_csv(path)}


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
