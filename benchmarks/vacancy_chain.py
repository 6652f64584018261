"""Vacancy chains: a breakdown, a repair and a priority change after convergence.

The lineage's claim (Dahl, Mataric & Sukhatme, ICRA 2003): TAVC beats static allocation "when
individual robots are prone to distractions or breakdowns, or when task priorities change". Each
trial of `dahl2004` runs `--convergence-h` hours (default 15), then:

1. a fast robot serving the high-value circuit (circuit 0) breaks down -- the one with the lowest
   index among those on circuit 0 at that moment (any robot on circuit 0 if no fast one is);
2. `--phase-h` hours later it is repaired;
3. `--phase-h` hours later the circuits' values swap (2200 <-> 2000);
4. the trial ends `--phase-h` hours later.

A paired control trial (same seed, no events) runs alongside; until the breakdown the two are
identical, which is how the robot to break is chosen. Measured per allocator, over trials:

* time until circuit 0 is served at full strength again (as many working robots on it as just
  before the breakdown), the first robot to move onto it (its class and where it came from: the
  head of the chain) and the moves in the chain until then;
* value lost: delivered value (sum of w / max w) per hour while the robot is broken, against the
  paired control and against the model optimum of the reduced team;
* after the swap: the model value of the allocation (new values) against the new optimum, in each
  third of the last phase.

Outputs in `benchmarks/results/vacancy_chain/`: `vacancy_chain.{md,csv,json}`, `trials.csv` (an
empty `recovery_min` means never back to full strength) and
`timeline.png` (each robot's circuit around the events, one allocator per panel, one seed).

    python benchmarks/vacancy_chain.py
    python benchmarks/vacancy_chain.py --quick
"""

from __future__ import annotations

import argparse
import itertools
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from _common import (
    RESULTS_DIR,
    add_sweep_options,
    fmt_ci,
    have_matplotlib,
    markdown_table,
    mean_ci,
    run_trials,
    write_csv,
    write_results,
)
from tavc_model import load_model

from agents.analysis.plots import allocation_timeline
from agents.experiments.runner import Event, TrialResult
from agents.experiments.sweep import TrialSpec
from agents.model import CompletionModel, SpeedClasses
from tavc_env import make_config, metrics

PRESET = "dahl2004"
SWAP_WINDOWS = 3  # the phase after the priority change, in thirds (hours with --phase-h 3)
ALLOCATORS = {  # registry name -> label
    "softmax_tavc": "softmax TAVC",
    "epsilon_tavc": "epsilon TAVC",
    "greedy": "greedy (model)",
    "auction": "auction",
    "static": "static (model optimum)",
}


def allocator_kwargs(name: str, model: CompletionModel) -> dict[str, Any]:
    if name == "softmax_tavc":
        return {"temperature": 0.005, "init": "scaled"}
    if name == "epsilon_tavc":
        return {"epsilon": 0.1, "init": "scaled"}
    return {"model": model.to_dict()}


def circuits_at(result: TrialResult, t: float) -> np.ndarray:
    """Every robot's current circuit just before time `t`."""
    current = np.array(result.initial_circuits)
    for time_s, robot, circuit in result.changes:
        if time_s >= t:
            break
        current[robot] = circuit
    return current


def robot_to_break(control: TrialResult, t: float, classes: SpeedClasses) -> int:
    """The lowest-index fast robot on circuit 0 just before `t` (else any robot on circuit 0)."""
    on_high = np.flatnonzero(circuits_at(control, t) == 0)
    fast = [int(r) for r in on_high if classes.of_robot[r] == 0]
    if fast:
        return fast[0]
    if on_high.size:
        return int(on_high[0])
    return 0


def delivered(result: TrialResult, t0: float, t1: float) -> float:
    """Delivered value (each delivery w / max configured w) per hour in `[t0, t1)`."""
    times = np.asarray(result.delivery_time_s)
    values = np.asarray(result.delivery_value)
    inside = (times >= t0) & (times < t1)
    return float(values[inside].sum() / max(result.values) / ((t1 - t0) / 3600.0))


def working_on(
    result: TrialResult, circuit: int, t0: float, t1: float, broken: int
) -> tuple[np.ndarray, np.ndarray]:
    """Segments of `[t0, t1)`: their starts and how many robots, `broken` left out, serve
    `circuit` in each."""
    durations, states = metrics.allocation_segments(result.initial_circuits, result.changes, t0, t1)
    starts = t0 + np.concatenate([[0.0], np.cumsum(durations)[:-1]])
    on = states == circuit
    on[:, broken] = False
    return starts, on.sum(axis=1)


def measure(
    result: TrialResult,
    control: TrialResult,
    model: CompletionModel,
    classes: SpeedClasses,
    broken: int,
    times: Mapping[str, float],
) -> dict[str, Any]:
    tb, tr, tv, te = times["break"], times["repair"], times["swap"], times["end"]
    # the events are applied at the first step boundary after their nominal time
    applied = {kind: t for t, kind, _ in result.events}
    tb, tr, tv = (
        applied.get("break_down", tb),
        applied.get("repair", tr),
        applied.get("set_values", tv),
    )
    # robots on circuit 0 just before the breakdown, the broken one included
    full = int((circuits_at(result, tb) == 0).sum())
    starts, count = working_on(result, 0, tb, tr, broken)
    refilled = np.flatnonzero(count >= full)
    recovery = float(starts[refilled[0]] - tb) if refilled.size else math.inf
    end_chain = tb + (recovery if math.isfinite(recovery) else tr - tb)
    chain = [(t, r, c) for t, r, c in result.changes if tb <= t <= end_chain and r != broken]
    onto = [(t, r, c) for t, r, c in chain if c == 0]
    head = onto[0] if onto else None
    team = list(classes.team)
    team[classes.of_robot[broken]] -= 1
    reduced = model.optimum(team)
    reduced_rate = 3600 * model.value_rate(reduced) / max(model.values)
    swapped = model.with_values(tuple(reversed(model.values)))
    new_best = swapped.performance(swapped.optimum())
    edges = np.linspace(tv, te, SWAP_WINDOWS + 1)
    after_swap = [
        swapped.mean_performance(result.initial_circuits, result.changes, classes, a, b) / new_best
        for a, b in itertools.pairwise(edges)
    ]
    return {
        "broken_robot": broken,
        "broken_class": classes.labels[classes.of_robot[broken]],
        "on_high_before": full,
        "recovery_min": recovery / 60.0,
        "chain_moves": len(chain),
        "head_class": None if head is None else classes.labels[classes.of_robot[head[1]]],
        "head_from": None if head is None else int(circuits_at(result, head[0])[head[1]]),
        "head_min": None if head is None else (head[0] - tb) / 60.0,
        "broken_value_per_h": delivered(result, tb, tr),
        "control_value_per_h": delivered(control, tb, tr),
        "reduced_optimum_per_h": reduced_rate,
        "lost_vs_control_per_h": delivered(control, tb, tr) - delivered(result, tb, tr),
        "repaired_value_per_h": delivered(result, tr, tv),
        "repaired_control_per_h": delivered(control, tr, tv),
        **{f"swap_w{k + 1}_fraction": v for k, v in enumerate(after_swap)},
    }


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--convergence-h", type=float, default=15.0)
    parser.add_argument("--phase-h", type=float, default=3.0)
    add_sweep_options(parser)
    parser.add_argument("--out", type=Path, default=RESULTS_DIR / "vacancy_chain")
    parser.add_argument("--quick", action="store_true", help="2 trials, 1 h + 3 x 1 h (smoke run)")
    parser.add_argument("--model", type=Path, default=None, help="default: the committed one")
    args = parser.parse_args(argv)
    if args.quick:
        args.trials, args.convergence_h, args.phase_h = 2, 1.0, 1.0
        if args.out == RESULTS_DIR / "vacancy_chain":
            args.out = RESULTS_DIR / "vacancy_chain_quick"
    if args.trials < 2 or args.convergence_h <= 0 or args.phase_h <= 0:
        parser.error("allowed: --trials >= 2, --convergence-h > 0, --phase-h > 0")

    model = load_model(PRESET, args.model)
    classes = SpeedClasses.of(make_config(PRESET))
    h = 3600.0
    times = {
        "break": args.convergence_h * h,
        "repair": (args.convergence_h + args.phase_h) * h,
        "swap": (args.convergence_h + 2 * args.phase_h) * h,
        "end": (args.convergence_h + 3 * args.phase_h) * h,
    }
    settings = {k: str(v) for k, v in vars(args).items() if k != "workers"}

    def spec(name: str, seed: int, events: tuple[Event, ...], tag: str) -> TrialSpec:
        return TrialSpec(
            key=f"{name}_{tag}_s{seed}",
            allocator=name,
            allocator_kwargs=allocator_kwargs(name, model),
            seed=seed,
            env_kwargs={"preset": PRESET},
            convergence_s=times["break"],
            measured_s=times["end"] - times["break"],
            events=events,
        )

    controls, meta = run_trials(
        [spec(n, s, (), "control") for n in ALLOCATORS for s in range(args.trials)],
        args.out / "cache",
        args.workers,
        settings,
        backend=args.backend,
    )
    broken = {
        (n, s): robot_to_break(controls[f"{n}_control_s{s}"], times["break"], classes)
        for n in ALLOCATORS
        for s in range(args.trials)
    }
    swap = tuple(reversed(model.values))
    event_specs = [
        spec(
            n,
            s,
            (
                Event(times["break"], "break_down", robot=broken[(n, s)]),
                Event(times["repair"], "repair", robot=broken[(n, s)]),
                Event(times["swap"], "set_values", values=swap),
            ),
            f"events_r{broken[(n, s)]}",
        )
        for n in ALLOCATORS
        for s in range(args.trials)
    ]
    runs, event_meta = run_trials(
        event_specs, args.out / "cache", args.workers, settings, backend=args.backend
    )
    meta["wall_time_s"] = meta["wall_time_s"] + event_meta["wall_time_s"]

    per_trial = []
    for n in ALLOCATORS:
        for s in range(args.trials):
            r = runs[f"{n}_events_r{broken[(n, s)]}_s{s}"]
            row = measure(r, controls[f"{n}_control_s{s}"], model, classes, broken[(n, s)], times)
            per_trial.append({"allocator": n, "seed": s, **row})
    summary = summarise(per_trial, args.phase_h)
    body = report(summary, model, classes, args)
    write_csv(args.out / "trials.csv", per_trial)
    write_results(
        args.out, "vacancy_chain", summary, body, meta, "Vacancy chains", {"rows": summary}
    )
    if have_matplotlib():
        allocation_timeline(
            {label: runs[f"{n}_events_r{broken[(n, 0)]}_s0"] for n, label in ALLOCATORS.items()},
            args.out / "timeline.png",
            from_h=times["break"] / 3600.0 - 1.0,
        )
    print(body)


def summarise(rows: Sequence[Mapping[str, Any]], phase_h: float) -> list[dict[str, Any]]:
    out = []
    for n, label in ALLOCATORS.items():
        mine = [r for r in rows if r["allocator"] == n]
        rec = np.array([r["recovery_min"] for r in mine])
        row: dict[str, Any] = {
            "allocator": n,
            "label": label,
            "trials": len(mine),
            "recovery_min_median": float(np.median(rec)),
            "never_recovered": int(np.isinf(rec).sum()),
            "broken_fast": sum(r["broken_class"] == "fast" for r in mine),
            "head_fast": sum(r["head_class"] == "fast" for r in mine),
            "head_slow": sum(r["head_class"] == "slow" for r in mine),
            "chain_moves_mean": float(np.mean([r["chain_moves"] for r in mine])),
            "reduced_optimum_per_h": float(np.mean([r["reduced_optimum_per_h"] for r in mine])),
        }
        keys = ["broken_value_per_h", "lost_vs_control_per_h", "repaired_value_per_h"]
        keys += [k for k in mine[0] if k.startswith("swap_w")]
        for key in keys:
            m, lo, hi, _ = mean_ci([r[key] for r in mine])
            row.update({key: m, f"{key}_low": lo, f"{key}_high": hi})
        out.append(row)
    return out


def report(
    summary: Sequence[Mapping[str, Any]],
    model: CompletionModel,
    classes: SpeedClasses,
    args: argparse.Namespace,
) -> str:
    swap_keys = [k for k in summary[0] if k.startswith("swap_w") and k.endswith("fraction")]
    lines = [
        f"`{PRESET}`, {args.trials} trials per allocator: {args.convergence_h:g} h convergence, "
        f"then breakdown, repair and value swap {args.phase_h:g} h apart. Mean [95 % CI] over "
        "trials; value = deliveries weighted w / max w, per hour for the whole team.",
        "",
        "## Breakdown",
        "",
        markdown_table(
            [
                "allocator",
                "broken: fast / slow",
                "full strength again (median min)",
                "head of chain: fast / slow",
                "moves in chain",
                "value/h while broken",
                "lost vs control / h",
                "reduced-team optimum / h",
            ],
            [
                [
                    r["label"],
                    f"{r['broken_fast']} / {r['trials'] - r['broken_fast']}",
                    _minutes(r),
                    f"{r['head_fast']} / {r['head_slow']}",
                    f"{r['chain_moves_mean']:.1f}",
                    fmt_ci(
                        r["broken_value_per_h"],
                        r["broken_value_per_h_low"],
                        r["broken_value_per_h_high"],
                        1,
                    ),
                    fmt_ci(
                        r["lost_vs_control_per_h"],
                        r["lost_vs_control_per_h_low"],
                        r["lost_vs_control_per_h_high"],
                        1,
                    ),
                    f"{r['reduced_optimum_per_h']:.1f}",
                ]
                for r in summary
            ],
        ),
        "",
        "## Priority change (values swap): model value of the allocation / new optimum, by third "
        "of the phase after it",
        "",
        markdown_table(
            ["allocator", *(f"third {k + 1}" for k in range(len(swap_keys)))],
            [
                [
                    r["label"],
                    *(fmt_ci(r[k], r[f"{k}_low"], r[f"{k}_high"], 3) for k in swap_keys),
                ]
                for r in summary
            ],
        ),
    ]
    return "\n".join(lines)


def _minutes(row: Mapping[str, Any]) -> str:
    m = row["recovery_min_median"]
    text = "never" if math.isinf(m) else f"{m:.1f}"
    if row["never_recovered"]:
        text += f" ({row['never_recovered']}/{row['trials']} never)"
    return text


if __name__ == "__main__":
    main()
