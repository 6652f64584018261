"""Measures of who served which circuit in a trial, against the TAVC model (`tavc_agents.model`).

A trial's allocation timeline is its robots' initial circuits and the time-ordered changes
`(time_s, robot, circuit)`. From it and the deliveries these functions give: the delivered value
(the paper's measure, or per hour for the whole team), the model value of the allocation the team
held over a window, circuit switches, how long the allocation took to settle, every robot's circuit
at a moment, and the vacancy chain after a breakdown (how long until a circuit is served at full
strength again, and which robot moved first).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tavc_agents.experiments.runner import TrialResult
from tavc_agents.model import Allocation, CompletionModel, SpeedClasses
from tavc_env import metrics

Change = tuple[float, int, int]  # (time_s, robot, new circuit)


def delivered_performance(result: TrialResult, t0: float, t1: float) -> float:
    """The paper's measure over `[t0, t1)`: delivered value (w_i / max w per delivery) per robot
    per 10 s."""
    return metrics.value_rate(
        result.delivery_time_s, result.delivery_circuit, result.values, len(result.agents), t0, t1
    )


def delivered_per_h(result: TrialResult, t0: float, t1: float) -> float:
    """Delivered value (each delivery w / max configured w, w as it was when delivered) per hour
    for the whole team in `[t0, t1)`."""
    times = np.asarray(result.delivery_time_s)
    values = np.asarray(result.delivery_value)
    inside = (times >= t0) & (times < t1)
    return float(values[inside].sum() / max(result.values) / ((t1 - t0) / 3600.0))


def held_performance(
    result: TrialResult, model: CompletionModel, classes: SpeedClasses, t0: float, t1: float
) -> float:
    """The model's performance of the allocation the team held over `[t0, t1)`, time-weighted
    (every robot counts: use it on windows without breakdowns)."""
    return model.mean_performance(result.initial_circuits, result.changes, classes, t0, t1)


def held_fractions(
    result: TrialResult,
    model: CompletionModel,
    classes: SpeedClasses,
    edges: Sequence[float],
) -> list[float]:
    """For each window between consecutive `edges`, the held allocation's model performance as a
    fraction of the model optimum's."""
    best = model.performance(model.optimum())
    return [
        held_performance(result, model, classes, a, b) / best for a, b in itertools.pairwise(edges)
    ]


def switches_per_robot_h(result: TrialResult, t0: float, t1: float) -> float:
    """Circuit switches in `[t0, t1)` per robot per hour."""
    switches = sum(1 for t, _, _ in result.changes if t0 <= t < t1)
    return switches / len(result.agents) / ((t1 - t0) / 3600.0)


def settle_time_h(
    result: TrialResult,
    model: CompletionModel,
    classes: SpeedClasses,
    target: float,
    band: float,
    window_h: int,
) -> float:
    """Hours until the allocation first comes within `band` (a fraction) of its long-run quality
    `target`: the start of the first `window_h`-hour window, on whole hours, whose held model
    performance is within `band` of it (inf if none is). A sliding window and a first entry,
    rather than "stays inside", so that the hour-to-hour noise of stochastic allocators does not
    count as drifting."""
    hours = int(result.measured_window[1] // 3600)
    for h in range(hours - window_h + 1):
        window = (h * 3600.0, (h + window_h) * 3600.0)
        value = held_performance(result, model, classes, *window)
        if abs(value - target) <= band * target:
            return float(h)
    return math.inf


def circuits_at(result: TrialResult, t: float) -> np.ndarray:
    """Every robot's current circuit just before time `t`."""
    current = np.array(result.initial_circuits)
    for time_s, robot, circuit in result.changes:
        if time_s >= t:
            break
        current[robot] = circuit
    return current


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


@dataclass(frozen=True)
class VacancyChain:
    """What followed the breakdown of a robot serving `circuit`."""

    full: int
    """robots on the circuit just before the breakdown, the broken one included"""
    recovery_s: float
    """from the breakdown until as many working robots serve the circuit again (inf: never
    before the repair)"""
    moves: list[Change]
    """circuit changes of the other robots from the breakdown until then (or the repair)"""
    head: Change | None
    """the first of those moves onto the circuit (the head of the chain), if any"""


def vacancy_chain(
    result: TrialResult, broken: int, t_break: float, t_repair: float, circuit: int = 0
) -> VacancyChain:
    """The vacancy chain after robot `broken` broke down at `t_break` (repaired at `t_repair`)."""
    full = int((circuits_at(result, t_break) == circuit).sum())
    starts, count = working_on(result, circuit, t_break, t_repair, broken)
    refilled = np.flatnonzero(count >= full)
    recovery = float(starts[refilled[0]] - t_break) if refilled.size else math.inf
    end = t_break + (recovery if math.isfinite(recovery) else t_repair - t_break)
    moves = [(t, r, c) for t, r, c in result.changes if t_break <= t <= end and r != broken]
    onto = [move for move in moves if move[2] == circuit]
    return VacancyChain(full, recovery, moves, onto[0] if onto else None)


def reduced_optimum(model: CompletionModel, classes: SpeedClasses, robot: int) -> Allocation:
    """The model optimum of the team without `robot`."""
    team = list(classes.team)
    team[classes.of_robot[robot]] -= 1
    return model.optimum(team)
