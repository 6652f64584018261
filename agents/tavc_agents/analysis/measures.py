"""Per-trial measures of a saved trial: the state-time distribution, who serves the high-value
circuit, performance, learned Q gaps and lock-in. Studies aggregate these over trials."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tavc_agents.experiments.runner import TrialResult
from tavc_env import metrics


@dataclass(frozen=True)
class TrialMeasures:
    """What one trial's measured period shows (shares and states are fractions of that period)."""

    states: dict[tuple[int, int], float]  # % of time in each f:s state
    robots_on_high: np.ndarray  # fraction of time with k robots on the high-value circuit
    performance: float  # delivered value (w / max w per delivery) per robot per 10 s
    fast_share: float  # mean fraction of time fast robots serve the high-value circuit
    slow_share: float
    q_gap_fast: float  # mean over states of Q(s, high) - max Q(s, other), final tables
    q_gap_slow: float
    never_updated: float  # Q entries never updated, mean per robot
    non_greedy_per_hour: float  # mean per robot
    settled_first_hour: float  # fraction of robots whose last circuit change came in hour 1


def measure(result: TrialResult) -> TrialMeasures:
    """The measures of `result` over its measured window."""
    t0, t1 = result.measured_window
    high = int(np.argmax(result.values))
    fast = np.array([c == "fast" for c in result.speed_classes])
    slow = np.array([c == "slow" for c in result.speed_classes])
    states = metrics.state_time_distribution(
        result.initial_circuits, result.changes, fast.tolist(), high, t0, t1
    )
    share = metrics.time_share(result.initial_circuits, result.changes, high, t0, t1)
    on_high = metrics.robots_on_circuit_distribution(
        result.initial_circuits, result.changes, high, t0, t1
    )
    perf = metrics.value_rate(
        result.delivery_time_s, result.delivery_circuit, result.values, len(result.agents), t0, t1
    )
    gaps = q_gaps(result, high)
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


def q_gaps(result: TrialResult, high: int) -> np.ndarray:
    """Per robot, the mean over states of Q(s, high) - max over other circuits of Q(s, c) in its
    final Q-table (nan for robots without one)."""
    gaps = np.full(len(result.agents), math.nan)
    if result.q_snapshots:
        final = result.q_snapshots[-1]["q"]
        for i, agent in enumerate(result.agents):
            if agent in final:
                q = np.asarray(final[agent])
                low = [c for c in range(q.shape[1]) if c != high]
                gaps[i] = float(np.mean(q[:, high] - q[:, low].max(axis=1)))
    return gaps


def settled_within(result: TrialResult, horizon_s: float) -> float:
    """Fraction of robots whose last change of circuit came before `horizon_s` (never changing
    counts as settled at 0): how early the allocation froze."""
    last = np.zeros(len(result.agents))
    for time_s, robot, _ in result.changes:
        last[robot] = max(last[robot], time_s)
    return float(np.mean(last < horizon_s))
