"""Vacancy chains: a breakdown, a repair and a priority change after convergence.

After 15 h on `dahl2004` a fast robot on the high-value circuit breaks down, 3 h later it is
repaired, 3 h later the circuits' values swap; a paired control trial without events runs beside
each. Reports per allocator how fast the vacancy is refilled (and by whom), the value lost, and
how well the allocation follows the priority change. Writes vacancy_chain.{md,csv,json},
trials.csv and timeline.png into benchmarks/results/vacancy_chain/ (the committed reference; a run writes into a new runs/ folder unless --update-reference or --out); trials are kept in
cache/ so `--resume RUN_DIR` continues an interrupted run. Needs the dahl2004 model of the tavc_model study. The study is
benchmarks/vacancy_chain.py.

    python benchmarks/vacancy_chain.py
    python benchmarks/vacancy_chain.py --quick

Vacancy chains: a breakdown, a repair and a priority change after convergence.

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

Outputs in `benchmarks/results/vacancy_chain/` (the committed reference; a run writes into a new `runs/` folder unless `--update-reference` or `--out`): `vacancy_chain.{md,csv,json}`,
`trials.csv` (allocator, seed and broken robot rebuild each trial; an empty `recovery_min` means
never back to full strength) and `timeline.png` (each robot's circuit around the events, one
allocator per panel, one seed). Trials are kept under `cache/` (not committed), so an interrupted
run resumes; `reproduce_rows` re-runs a sample of them against `trials.csv`.

    python benchmarks/vacancy_chain.py
    python benchmarks/vacancy_chain.py --quick
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from tavc_agents.analysis import allocation
from tavc_agents.analysis.plots import allocation_timeline
from tavc_agents.analysis.reports import Report, fmt_ci_of, markdown_table, write_csv
from tavc_agents.analysis.row_check import compare_rows, run_fresh, sample_rows
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.runner import Event, TrialResult
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import TagValue, TrialSpec
from tavc_agents.model import CompletionModel, SpeedClasses, load_model, missing_model
from tavc_env import make_config

PRESET = "dahl2004"
HIGH = 0  # the high-value circuit, where the breakdown happens
SWAP_WINDOWS = 3  # the phase after the priority change, in thirds (hours with --phase-h 3)
ALLOCATORS = {  # registry name -> label
    "softmax_tavc": "softmax TAVC",
    "epsilon_tavc": "epsilon TAVC",
    "greedy": "greedy (model)",
    "auction": "auction",
    "static": "static (model optimum)",
}


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The vacancy-chain study's settings (its command line)."""

    reference: ClassVar = "vacancy_chain"
    quick_sizes: ClassVar = {"trials": 2, "convergence_h": 1.0, "phase_h": 1.0}
    recorded_as_text: ClassVar = True
    recorded_fields: ClassVar = "trials convergence_h phase_h backend out=out_text quick model"

    trials: int = 10
    """trials per allocator (>= 2, for confidence intervals)"""
    convergence_h: float = 15.0
    """convergence period before the breakdown, simulated hours"""
    phase_h: float = 3.0
    """hours from the breakdown to the repair, to the value swap and to the end"""
    quick: bool = False
    """smoke run: 2 trials, 1 h + 3 x 1 h"""
    model: Path | None = None
    """model.json of dahl2004 (default: the committed one)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        checks = [
            ("trials", at_least(self.trials, 2), "an integer >= 2"),
            ("convergence_h", positive(self.convergence_h), "> 0"),
            ("phase_h", positive(self.phase_h), "> 0"),
        ]
        refuse_invalid(self, checks)
        problem = missing_model(PRESET, self.model)
        if problem is not None:
            raise ValueError(
                f"model = {self.model!r} is invalid; allowed: a model.json ({problem})"
            )

    def times(self) -> dict[str, float]:
        """Nominal times (s) of the breakdown, the repair, the value swap and the end."""
        s, h = self.sized(), 3600.0
        return {
            "break": s.convergence_h * h,
            "repair": (s.convergence_h + s.phase_h) * h,
            "swap": (s.convergence_h + 2 * s.phase_h) * h,
            "end": (s.convergence_h + 3 * s.phase_h) * h,
        }


def allocator_kwargs(name: str, model: CompletionModel) -> dict[str, Any]:
    if name == "softmax_tavc":
        return {"temperature": 0.005, "init": "scaled"}
    if name == "epsilon_tavc":
        return {"epsilon": 0.1, "init": "scaled"}
    return {"model": model.to_dict()}


# -- trials --------------------------------------------------------------------------------------
def trial_key(tags: Mapping[str, TagValue]) -> str:
    if tags["arm"] == "control":
        return f"{tags['allocator']}_control_s{tags['seed']}"
    return f"{tags['allocator']}_events_r{tags['broken_robot']}_s{tags['seed']}"


def control_spec(settings: Settings, model: CompletionModel, name: str, seed: int) -> TrialSpec:
    """The control trial of allocator `name` with `seed`: no events."""
    return _spec(settings, model, {"allocator": name, "arm": "control", "seed": seed}, ())


def events_spec(
    settings: Settings, model: CompletionModel, name: str, seed: int, broken: int
) -> TrialSpec:
    """The trial with the breakdown of robot `broken`, its repair and the value swap."""
    times = settings.times()
    events = (
        Event(times["break"], "break_down", robot=broken),
        Event(times["repair"], "repair", robot=broken),
        Event(times["swap"], "set_values", values=tuple(reversed(model.values))),
    )
    tags: dict[str, TagValue] = {
        "allocator": name,
        "arm": "events",
        "seed": seed,
        "broken_robot": broken,
    }
    return _spec(settings, model, tags, events)


def _spec(
    settings: Settings,
    model: CompletionModel,
    tags: dict[str, TagValue],
    events: tuple[Event, ...],
) -> TrialSpec:
    times = settings.times()
    name = str(tags["allocator"])
    seed = tags["seed"]
    assert isinstance(seed, int)
    return TrialSpec(
        key=trial_key(tags),
        allocator=name,
        allocator_kwargs=allocator_kwargs(name, model),
        seed=seed,
        env_kwargs={"preset": PRESET},
        convergence_s=times["break"],
        measured_s=times["end"] - times["break"],
        events=events,
        tags=tags,
    )


def robot_to_break(control: TrialResult, t: float, classes: SpeedClasses) -> int:
    """The lowest-index fast robot on the high-value circuit just before `t` (else any robot on
    it, else robot 0)."""
    on_high = np.flatnonzero(allocation.circuits_at(control, t) == HIGH)
    fast = [int(r) for r in on_high if classes.of_robot[r] == 0]
    if fast:
        return fast[0]
    if on_high.size:
        return int(on_high[0])
    return 0


def paired_specs(
    settings: Settings,
    model: CompletionModel,
    control_specs: Sequence[TrialSpec],
    controls: Mapping[str, TrialResult],
) -> list[TrialSpec]:
    """The events trial of every control trial, breaking the robot its control picks."""
    classes = SpeedClasses.of(make_config(PRESET))
    t_break = settings.times()["break"]
    out = []
    for spec in control_specs:
        broken = robot_to_break(controls[spec.key], t_break, classes)
        name, seed = str(spec.tags["allocator"]), spec.seed
        out.append(events_spec(settings, model, name, seed, broken))
    return out


def run(settings: Settings) -> Outcome:
    """Run (or resume) the control trials, then the trials with events; write the report."""
    out = settings.out_dir()
    model = load_model(PRESET, settings.model)
    trials = settings.sized().trials
    control_specs = [control_spec(settings, model, n, s) for n in ALLOCATORS for s in range(trials)]
    controls, meta = settings.run_trials(control_specs, Path("cache", "control"))
    event_specs = paired_specs(settings, model, control_specs, controls)
    runs, event_meta = settings.run_trials(event_specs, Path("cache", "events"))
    provenance = combined(meta, event_meta)
    per_trial = [
        trial_row(spec, runs[spec.key], controls[control.key], model, settings)
        for spec, control in zip(event_specs, control_specs)
    ]
    summary = summarise(per_trial)
    body = report_body(summary, settings)
    write_csv(out / "trials.csv", per_trial)
    first = {str(s.tags["allocator"]): runs[s.key] for s in event_specs if s.tags["seed"] == 0}
    from_h = settings.times()["break"] / 3600.0 - 1.0
    figure = {ALLOCATORS[n]: r for n, r in first.items()}
    report = Report(
        "vacancy_chain",
        "Vacancy chains",
        body,
        summary,
        {"rows": summary},
        figures=[("timeline.png", lambda path: allocation_timeline(figure, path, from_h=from_h))],
    )
    written = [out / "trials.csv", *report.write(out, provenance)]
    return Outcome(out, written, body)


def combined(first: Mapping[str, Any], second: Mapping[str, Any]) -> dict[str, Any]:
    """The provenance of two sweeps run one after the other: the first's, with the wall time
    and trial counts of both."""
    meta = dict(first)
    for key in ("wall_time_s", "trials_resumed", "trials_run", "trial_wall_s_total"):
        if key in first and key in second:
            meta[key] = first[key] + second[key]
    return meta


# -- measures ------------------------------------------------------------------------------------
def applied_times(result: TrialResult, times: Mapping[str, float]) -> tuple[float, float, float]:
    """When the breakdown, the repair and the value swap took effect: the events are applied at
    the first step boundary after their nominal time."""
    applied = {kind: t for t, kind, _ in result.events}
    return (
        applied.get("break_down", times["break"]),
        applied.get("repair", times["repair"]),
        applied.get("set_values", times["swap"]),
    )


def measure(
    result: TrialResult,
    control: TrialResult,
    model: CompletionModel,
    classes: SpeedClasses,
    broken: int,
    times: Mapping[str, float],
) -> dict[str, Any]:
    """One trial's measures (with its paired control)."""
    tb, tr, tv = applied_times(result, times)
    chain = allocation.vacancy_chain(result, broken, tb, tr, HIGH)
    head = chain.head
    reduced = allocation.reduced_optimum(model, classes, broken)
    swapped = model.with_values(tuple(reversed(model.values)))
    edges = np.linspace(tv, times["end"], SWAP_WINDOWS + 1)
    after_swap = allocation.held_fractions(result, swapped, classes, list(edges))
    label = classes.labels
    return {
        "broken_robot": broken,
        "broken_class": label[classes.of_robot[broken]],
        "on_high_before": chain.full,
        "recovery_min": chain.recovery_s / 60.0,
        "chain_moves": len(chain.moves),
        "head_class": None if head is None else label[classes.of_robot[head[1]]],
        "head_from": None
        if head is None
        else int(allocation.circuits_at(result, head[0])[head[1]]),
        "head_min": None if head is None else (head[0] - tb) / 60.0,
        "broken_value_per_h": allocation.delivered_per_h(result, tb, tr),
        "control_value_per_h": allocation.delivered_per_h(control, tb, tr),
        "reduced_optimum_per_h": 3600 * model.value_rate(reduced) / max(model.values),
        "lost_vs_control_per_h": allocation.delivered_per_h(control, tb, tr)
        - allocation.delivered_per_h(result, tb, tr),
        "repaired_value_per_h": allocation.delivered_per_h(result, tr, tv),
        "repaired_control_per_h": allocation.delivered_per_h(control, tr, tv),
        **{f"swap_w{k + 1}_fraction": v for k, v in enumerate(after_swap)},
    }


def trial_row(
    spec: TrialSpec,
    result: TrialResult,
    control: TrialResult,
    model: CompletionModel,
    settings: Settings,
) -> dict[str, Any]:
    """A trial's row of `trials.csv`: allocator, seed, then its measures (the broken robot
    first)."""
    classes = SpeedClasses.of(make_config(PRESET))
    broken = spec.tags["broken_robot"]
    assert isinstance(broken, int)
    row = measure(result, control, model, classes, broken, settings.times())
    return {"allocator": spec.tags["allocator"], "seed": spec.tags["seed"], **row}


def summarise(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per allocator: recovery, chain heads and moves, and every value's mean and 95 % interval."""
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


# -- the report ----------------------------------------------------------------------------------
def breakdown_table(summary: Sequence[Mapping[str, Any]]) -> str:
    header = [
        "allocator",
        "broken: fast / slow",
        "full strength again (median min)",
        "head of chain: fast / slow",
        "moves in chain",
        "value/h while broken",
        "lost vs control / h",
        "reduced-team optimum / h",
    ]
    rows = [
        [
            r["label"],
            f"{r['broken_fast']} / {r['trials'] - r['broken_fast']}",
            minutes_text(r),
            f"{r['head_fast']} / {r['head_slow']}",
            f"{r['chain_moves_mean']:.1f}",
            fmt_ci_of(r, "broken_value_per_h", 1),
            fmt_ci_of(r, "lost_vs_control_per_h", 1),
            f"{r['reduced_optimum_per_h']:.1f}",
        ]
        for r in summary
    ]
    return markdown_table(header, rows)


def swap_table(summary: Sequence[Mapping[str, Any]]) -> str:
    keys = [k for k in summary[0] if k.startswith("swap_w") and k.endswith("fraction")]
    return markdown_table(
        ["allocator", *(f"third {k + 1}" for k in range(len(keys)))],
        [[r["label"], *(fmt_ci_of(r, k, 3) for k in keys)] for r in summary],
    )


def report_body(summary: Sequence[Mapping[str, Any]], settings: Settings) -> str:
    s = settings.sized()
    lines = [
        f"`{PRESET}`, {s.trials} trials per allocator: {s.convergence_h:g} h convergence, "
        f"then breakdown, repair and value swap {s.phase_h:g} h apart. Mean [95 % CI] over "
        "trials; value = deliveries weighted w / max w, per hour for the whole team.",
        "",
        "## Breakdown",
        "",
        breakdown_table(summary),
        "",
        "## Priority change (values swap): model value of the allocation / new optimum, by third "
        "of the phase after it",
        "",
        swap_table(summary),
    ]
    return "\n".join(lines)


def minutes_text(row: Mapping[str, Any]) -> str:
    m = row["recovery_min_median"]
    text = "never" if math.isinf(m) else f"{m:.1f}"
    if row["never_recovered"]:
        text += f" ({row['never_recovered']}/{row['trials']} never)"
    return text


# -- reproduction ----------------------------------------------------------------------------------
def reproduce_rows(settings: Settings, sample: int, seed: int) -> list[tuple[str, bool]]:
    """Re-run `sample` trials drawn at random (with `seed`) from the `trials.csv` in the settings'
    output folder, from scratch -- each control trial, then the trial with events breaking the
    robot that control picks -- and compare each fresh row with the saved row, cell by cell as
    written: (events trial key, identical) per trial."""
    saved = sample_rows(settings.out_dir() / "trials.csv", sample, seed)
    model = load_model(PRESET, settings.model)
    chosen = [control_spec(settings, model, r["allocator"], int(r["seed"])) for r in saved]
    controls = run_fresh(chosen, settings.workers)
    event_specs = paired_specs(settings, model, chosen, controls)
    runs = run_fresh(event_specs, settings.workers)
    rows = [
        trial_row(spec, runs[spec.key], controls[control.key], model, settings)
        for spec, control in zip(event_specs, chosen)
    ]
    return [(s.key, same) for s, same in zip(event_specs, compare_rows(rows, saved))]


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
