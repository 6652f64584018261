"""Reproduce the paper's Table 1, Figure 2 and performance figure (the package's main job).

Three conditions, each `--trials` trials (default 15, as in the paper) of `--convergence-h` hours
(default 15, the paper's convergence period) followed by a measured stable period of `--measured-h`
hours (default 5): softmax TAVC (temperature 0.005), epsilon-greedy TAVC (epsilon 0.1) and random
allocation. Trials run in parallel over all cores and each is saved the moment it finishes, under
`<out>/trials/`; rerunning the same command resumes and never recomputes a finished trial.

Outputs in `<out>/` (default `benchmarks/results/table1_<preset>_<init>/`): `table1.{md,csv,json}`
(state-time distribution of all f:s states next to the paper's values, T of Equation 3, differences
against random and against T, performance with 95 % confidence intervals, Welch's t-tests, time
shares of fast and slow robots on the high-value circuit, learned Q(high) - Q(low), lock-in
measures), `figure2.png` and `performance.png`.

With `--preset dahl2004_homogeneous` it reports instead the distribution of the number of robots
on the high-value circuit (the paper's homogeneous result: 3 most frequent under TAVC).

    python benchmarks/table1.py                 # full size: 3 x 15 trials x 20 simulated hours
    python benchmarks/table1.py --quick         # a smoke run in seconds
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from _common import (
    RESULTS_DIR,
    add_override_option,
    add_sweep_options,
    fmt_ci,
    have_matplotlib,
    markdown_table,
    mean_ci,
    parsed_overrides,
    ratio_ci,
    run_trials,
    write_results,
)

from agents.experiments.runner import TrialResult
from agents.experiments.sweep import TrialSpec
from tavc_env import PRESETS, metrics

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


@dataclass(frozen=True)
class Condition:
    name: str
    allocator: str
    kwargs: Mapping[str, Any]
    label: str


def conditions(init: str, temperature: float, epsilon: float) -> dict[str, Condition]:
    return {
        "softmax": Condition(
            "softmax",
            "softmax_tavc",
            {"temperature": temperature, "init": init},
            f"softmax TAVC (T={temperature}, {init} init)",
        ),
        "epsilon": Condition(
            "epsilon",
            "epsilon_tavc",
            {"epsilon": epsilon, "init": init},
            f"epsilon-greedy TAVC (eps={epsilon}, {init} init)",
        ),
        "random": Condition("random", "random", {}, "random allocation"),
    }


# -- per-trial measures ------------------------------------------------------------------------
@dataclass(frozen=True)
class TrialMeasures:
    states: dict[tuple[int, int], float]
    robots_on_high: np.ndarray  # fraction of time with k robots on the high-value circuit
    performance: float
    fast_share: float
    slow_share: float
    q_gap_fast: float
    q_gap_slow: float
    never_updated: float  # mean per robot
    non_greedy_per_hour: float  # mean per robot
    settled_first_hour: float  # fraction of robots whose last circuit change came in the first hour


def measure(result: TrialResult) -> TrialMeasures:
    t0, t1 = result.measured_window
    high = int(np.argmax(result.values))
    fast = np.array([c == "fast" for c in result.speed_classes])
    slow = np.array([c == "slow" for c in result.speed_classes])
    states = metrics.state_time_distribution(
        result.initial_circuits, result.changes, fast, high, t0, t1
    )
    share = metrics.time_share(result.initial_circuits, result.changes, high, t0, t1)
    on_high = metrics.robots_on_circuit_distribution(
        result.initial_circuits, result.changes, high, t0, t1
    )
    perf = metrics.value_rate(
        result.delivery_time_s, result.delivery_circuit, result.values, len(result.agents), t0, t1
    )
    gaps = np.full(len(result.agents), math.nan)
    if result.q_snapshots:
        final = result.q_snapshots[-1]["q"]
        for i, agent in enumerate(result.agents):
            if agent in final:
                q = np.asarray(final[agent])
                low = [c for c in range(q.shape[1]) if c != high]
                gaps[i] = float(np.mean(q[:, high] - q[:, low].max(axis=1)))
    hours = result.end_s / 3600.0
    stats = result.learner_stats
    never = [s["never_updated"] for s in stats.values()]
    non_greedy = [s["non_greedy_choices"] / hours for s in stats.values()]
    return TrialMeasures(
        states=states,
        robots_on_high=on_high,
        performance=perf,
        fast_share=float(share[fast].mean()) if fast.any() else math.nan,
        slow_share=float(share[slow].mean()) if slow.any() else math.nan,
        q_gap_fast=float(np.nanmean(gaps[fast])) if fast.any() and stats else math.nan,
        q_gap_slow=float(np.nanmean(gaps[slow])) if slow.any() and stats else math.nan,
        never_updated=float(np.mean(never)) if never else math.nan,
        non_greedy_per_hour=float(np.mean(non_greedy)) if non_greedy else math.nan,
        settled_first_hour=settled_within(result, 3600.0),
    )


def settled_within(result: TrialResult, horizon_s: float) -> float:
    """Fraction of robots whose last change of circuit came before `horizon_s` (never changing
    counts as settled at 0): how early the allocation froze."""
    last = np.zeros(len(result.agents))
    for time_s, robot, _ in result.changes:
        last[robot] = max(last[robot], time_s)
    return float(np.mean(last < horizon_s))


# -- statistics --------------------------------------------------------------------------------
def welch(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """Welch's unequal-variance t-test: (t, two-sided p)."""
    from scipy import stats

    if len(a) < 2 or len(b) < 2 or (np.var(a) == 0 and np.var(b) == 0):
        return (math.nan, math.nan)
    res = stats.ttest_ind(a, b, equal_var=False)
    return (float(res.statistic), float(res.pvalue))


def msd(values: Sequence[float]) -> tuple[float, float]:
    x = np.asarray(values, dtype=float)
    return (float(x.mean()), float(x.std(ddof=1)) if len(x) > 1 else math.nan)


def fmt(x: float, digits: int = 1) -> str:
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


# -- report ------------------------------------------------------------------------------------
def state_rows(by: dict[str, list[TrialMeasures]], team: tuple[int, int]) -> list[dict[str, Any]]:
    expected = metrics.combinatorial_expectation(*team)
    rows = []
    for key in sorted(expected):
        row: dict[str, Any] = {"state": f"{key[0]}:{key[1]}", "T": expected[key]}
        for cond, ms in by.items():
            row[f"mu_{cond}"], row[f"sd_{cond}"] = msd([m.states[key] for m in ms])
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


def summary_section(
    by: dict[str, list[TrialMeasures]], labels: Mapping[str, str], heterogeneous: bool
) -> tuple[str, dict[str, Any]]:
    lines: list[str] = []
    summary: dict[str, Any] = {}
    perf_rows = []
    for cond, ms in by.items():
        m, lo, hi, n = mean_ci([x.performance for x in ms])
        summary[f"performance_{cond}"] = {"mean": m, "ci95": [lo, hi], "n": n}
        perf_rows.append([labels[cond], fmt_ci(m, lo, hi, 4), n])
    lines += ["## Performance (delivered value per robot per 10 s, 95 % CI over trials)", ""]
    lines.append(markdown_table(["condition", "value / robot / 10 s", "trials"], perf_rows))
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
    tests = []
    for other in ("random", "epsilon"):
        if "softmax" not in by or other not in by:
            continue
        pairs = [("performance", lambda x: x.performance)]
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
                    fmt(np.mean(a), 4),
                    fmt(np.mean(b), 4),
                    fmt(t, 2),
                    f"{p:.3g}" if math.isfinite(p) else "-",
                ]
            )
    lines += ["## Statistical tests (Welch's unequal-variance t-test, two-sided, over trials)", ""]
    lines.append(markdown_table(["measure", "comparison", "mean A", "mean B", "t", "p"], tests))
    lines.append("")
    if heterogeneous:
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
                    labels[cond],
                    fmt_ci(*f[:3], 3),
                    fmt_ci(*s[:3], 3),
                    fmt_ci(*d[:3], 3),
                    fmt_ci(*qf[:3], 4),
                    fmt_ci(*qs[:3], 4),
                ]
            )
        lines += [
            "## Who serves the high-value circuit (fraction of the measured period, 95 % CI)",
            "",
            "Q gap = mean over states of Q(s, high) - Q(s, low) in the final Q-tables.",
            "",
        ]
        lines.append(
            markdown_table(
                ["condition", "fast", "slow", "fast - slow", "Q gap fast", "Q gap slow"], rows
            )
        )
        lines.append("")
    rows = []
    for cond, ms in by.items():
        settled = fmt(100 * np.mean([x.settled_first_hour for x in ms]), 0)
        if math.isfinite(ms[0].never_updated):
            rows.append(
                [
                    labels[cond],
                    fmt(np.mean([x.never_updated for x in ms]), 2),
                    fmt(np.mean([x.non_greedy_per_hour for x in ms]), 1),
                    settled,
                ]
            )
        else:
            rows.append([labels[cond], "-", "-", settled])
        if math.isfinite(ms[0].never_updated):
            summary[f"lockin_{cond}"] = {
                "settled_in_first_hour": float(np.mean([x.settled_first_hour for x in ms])),
                "never_updated_entries_per_robot": float(np.mean([x.never_updated for x in ms])),
                "non_greedy_choices_per_robot_hour": float(
                    np.mean([x.non_greedy_per_hour for x in ms])
                ),
            }
    if rows:
        lines += ["## Lock-in measures (per robot, mean over trials)", ""]
        lines.append(
            markdown_table(
                [
                    "condition",
                    "Q entries never updated",
                    "non-greedy choices per hour",
                    "% of robots never changing circuit after hour 1",
                ],
                rows,
            )
        )
        lines.append("")
    return "\n".join(lines), summary


def occupancy_markdown(by: dict[str, list[TrialMeasures]], labels: Mapping[str, str]) -> str:
    n = len(next(iter(by.values()))[0].robots_on_high) - 1
    header = ["condition"] + [f"{k} on high" for k in range(n + 1)] + ["most frequent"]
    rows = []
    for cond, ms in by.items():
        dist = np.mean([m.robots_on_high for m in ms], axis=0) * 100
        rows.append([labels[cond]] + [fmt(v) for v in dist] + [int(np.argmax(dist))])
    return (
        "## Number of robots on the high-value circuit (% of the measured period)\n\n"
        + markdown_table(header, rows)
        + "\n"
    )


def plot(
    rows: list[dict[str, Any]],
    by: dict[str, list[TrialMeasures]],
    labels: Mapping[str, str],
    out: Path,
) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    if rows and "a_minus_r" in rows[0]:
        states = [r["state"] for r in rows]
        fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
        axes[0].bar(states, [r["a_minus_r"] for r in rows], color="tab:blue")
        axes[0].set_ylabel("mu_a - mu_r (% of time)")
        axes[1].bar(states, [r["a_minus_r_rel"] for r in rows], color="tab:orange")
        axes[1].set_ylabel("(mu_a - mu_r) / mu_r")
        axes[1].set_xlabel("state f:s (fast, slow robots on the high-value circuit)")
        for ax in axes:
            ax.axhline(0, color="black", linewidth=0.8)
        axes[0].set_title("Softmax TAVC against random allocation (cf. the paper's Figure 2)")
        fig.tight_layout()
        fig.savefig(out / "figure2.png", dpi=120)
        plt.close(fig)
        written.append("figure2.png")
    fig, ax = plt.subplots(figsize=(6, 4))
    names, means, errs = [], [], []
    for cond, ms in by.items():
        m, lo, hi, _ = mean_ci([x.performance for x in ms])
        names.append(labels[cond].split(" (")[0])
        means.append(m)
        errs.append([[m - lo if math.isfinite(lo) else 0], [hi - m if math.isfinite(hi) else 0]])
    err = np.array(errs).squeeze(-1).T if errs else None
    ax.bar(
        names, means, yerr=err, capsize=6, color=["tab:blue", "tab:green", "tab:gray"][: len(names)]
    )
    ax.set_ylabel("delivered value per robot per 10 s")
    ax.set_title("Performance (95 % CI over trials)")
    lo = min(means) * 0.9 if means else 0
    ax.set_ylim(bottom=lo)
    fig.tight_layout()
    fig.savefig(out / "performance.png", dpi=120)
    plt.close(fig)
    written.append("performance.png")
    return written


# -- main --------------------------------------------------------------------------------------
def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--preset", default="dahl2004", choices=sorted(PRESETS))
    ap.add_argument("--trials", type=int, default=15, help="trials per condition (default 15)")
    ap.add_argument("--convergence-h", type=float, default=15.0, help="convergence period, hours")
    ap.add_argument("--measured-h", type=float, default=5.0, help="measured stable period, hours")
    ap.add_argument("--conditions", default="softmax,epsilon,random", help="comma-separated subset")
    ap.add_argument(
        "--init", default="scaled", choices=["scaled", "paper"], help="Q-table initialisation"
    )
    ap.add_argument("--temperature", type=float, default=0.005)
    ap.add_argument("--epsilon", type=float, default=0.1)
    ap.add_argument("--seed", type=int, default=0, help="trial k uses seed + k in every condition")
    add_sweep_options(ap)
    ap.add_argument("--out", type=Path, default=None, help="output folder")
    ap.add_argument("--quick", action="store_true", help="smoke run: 2 trials of 0.3 + 0.2 hours")
    add_override_option(ap)
    args = ap.parse_args(argv)
    if args.quick:
        args.trials, args.convergence_h, args.measured_h = 2, 0.3, 0.2
    if args.trials < 1:
        ap.error(f"--trials {args.trials} is invalid; allowed: an integer >= 1")
    if args.convergence_h < 0 or args.measured_h <= 0:
        ap.error("--convergence-h must be >= 0 and --measured-h > 0")
    all_conds = conditions(args.init, args.temperature, args.epsilon)
    chosen = [c.strip() for c in args.conditions.split(",") if c.strip()]
    unknown = [c for c in chosen if c not in all_conds]
    if unknown:
        ap.error(f"--conditions {unknown} unknown; allowed: {sorted(all_conds)}")
    overrides = parsed_overrides(ap, args)
    suffix = "_quick" if args.quick else ""
    out = args.out or RESULTS_DIR / f"table1_{args.preset}_{args.init}{suffix}"
    out.mkdir(parents=True, exist_ok=True)

    env_kwargs = {"preset": args.preset, **overrides}
    specs = [
        TrialSpec(
            key=f"{cond}_seed{args.seed + k}",
            allocator=all_conds[cond].allocator,
            allocator_kwargs=dict(all_conds[cond].kwargs),
            seed=args.seed + k,
            env_kwargs=env_kwargs,
            convergence_s=args.convergence_h * 3600.0,
            measured_s=args.measured_h * 3600.0,
        )
        for k in range(args.trials)
        for cond in chosen
    ]
    print(
        f"{len(specs)} trials ({', '.join(chosen)}) x {args.convergence_h + args.measured_h:g} "
        f"simulated hours on {args.preset}; results in {out}",
        flush=True,
    )
    results, meta = run_trials(
        specs,
        out / "trials",
        args.workers,
        {
            "preset": args.preset,
            "trials": args.trials,
            "convergence_h": args.convergence_h,
            "measured_h": args.measured_h,
            "init": args.init,
            "temperature": args.temperature,
            "epsilon": args.epsilon,
            "seed": args.seed,
            "overrides": overrides,
        },
        backend=args.backend,
    )
    wall = meta["wall_time_s"]

    by: dict[str, list[TrialMeasures]] = {c: [] for c in chosen}
    for spec in specs:
        by[spec.key.rsplit("_seed", 1)[0]].append(measure(results[spec.key]))
    labels = {c: all_conds[c].label for c in chosen}
    first = results[specs[0].key]
    fast = sum(c == "fast" for c in first.speed_classes)
    slow = sum(c == "slow" for c in first.speed_classes)
    heterogeneous = fast > 0 and slow > 0 and fast + slow == len(first.agents)

    sections = [
        f"Conditions: {'; '.join(labels.values())}. {args.trials} trials each, "
        f"{args.convergence_h:g} h convergence + {args.measured_h:g} h measured (simulated). "
        f"Preset `{args.preset}`{' with ' + str(overrides) if overrides else ''}; Q-table initialisation "
        f"`{args.init}`.",
        "",
    ]
    rows: list[dict[str, Any]] = []
    if heterogeneous:
        rows = state_rows(by, (fast, slow))
        sections += [
            "## State-time distribution (% of the measured period; mu_a = softmax TAVC, mu_r = random)",
            "",
            "The paper's printed column `mu_a - mu_r` is in fact `mu_a - T` (erratum, DESIGN.md section 3);"
            " both comparisons are given.",
            "",
            state_table_markdown(rows, chosen),
            "",
        ]
    sections.append(occupancy_markdown(by, labels))
    body, summary = summary_section(by, labels, heterogeneous)
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
    write_results(
        out, "table1", csv_rows, "\n".join(sections), meta, "Table 1 reproduction", summary
    )
    figures = plot(rows, by, labels, out) if have_matplotlib() else []
    print()
    print("\n".join(sections))
    print(
        f"wall time {wall:.0f} s; wrote {out / 'table1.md'}"
        + (f", {', '.join(figures)}" if figures else "")
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
