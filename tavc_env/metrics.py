"""Measures of an allocation over time: the paper's f:s states, time shares and delivered value.

An allocation timeline is the initial circuit of every robot plus a time-ordered list of changes
`(time_s, robot, circuit)`; a robot's current circuit is the one it chose last (DESIGN.md section 3).
All measures are time-weighted over a window `[t0, t1)`.
"""

from __future__ import annotations

from collections.abc import Sequence
from math import comb

import numpy as np

Change = tuple[float, int, int]


def allocation_segments(
    initial: Sequence[int], changes: Sequence[Change], t0: float, t1: float
) -> tuple[np.ndarray, np.ndarray]:
    """Piecewise-constant allocation over `[t0, t1)`: segment durations (k,) and the circuit of
    every robot in each segment (k, n_robots). Changes must be in time order."""
    if t1 <= t0:
        raise ValueError(f"window [{t0}, {t1}) is empty; allowed: t1 > t0")
    times = [c[0] for c in changes]
    for k in range(1, len(times)):
        if times[k] < times[k - 1]:
            raise ValueError(
                f"changes are not in time order at time {times[k]} (after {times[k - 1]}); "
                "allowed: changes sorted by time"
            )
    current = np.array(initial, dtype=np.int64)
    durations: list[float] = []
    states: list[np.ndarray] = []
    t = t0
    for time_s, robot, circuit in changes:
        if time_s > t:
            end = min(time_s, t1)
            if end > t:
                durations.append(end - t)
                states.append(current.copy())
                t = end
        if time_s >= t1:
            break
        current[robot] = circuit
    if t < t1:
        durations.append(t1 - t)
        states.append(current.copy())
    return np.array(durations), np.array(states).reshape(len(states), len(current))


def state_time_distribution(
    initial: Sequence[int],
    changes: Sequence[Change],
    fast: Sequence[bool],
    high_circuit: int,
    t0: float,
    t1: float,
) -> dict[tuple[int, int], float]:
    """Percent of `[t0, t1)` spent in each `f:s` state: f fast and s slow robots whose current
    circuit is `high_circuit`. Every state of the team appears (zero if never visited)."""
    fast_mask = np.asarray(fast, dtype=bool)
    durations, states = allocation_segments(initial, changes, t0, t1)
    on_high = states == high_circuit
    f = on_high[:, fast_mask].sum(axis=1)
    s = on_high[:, ~fast_mask].sum(axis=1)
    g, h = int(fast_mask.sum()), int((~fast_mask).sum())
    total = durations.sum()
    table = {(i, j): 0.0 for i in range(g + 1) for j in range(h + 1)}
    for fi, si, d in zip(f, s, durations):
        table[(int(fi), int(si))] += 100.0 * d / total
    return table


def combinatorial_expectation(g: int, h: int) -> dict[tuple[int, int], float]:
    """The paper's Equation 3: percent of time in `f:s` if every robot picked a circuit by a fair
    coin, `T = 100 C(g, f) C(h, s) / 2^(g + h)`."""
    return {
        (f, s): 100.0 * comb(g, f) * comb(h, s) / 2 ** (g + h)
        for f in range(g + 1)
        for s in range(h + 1)
    }


def time_share(
    initial: Sequence[int], changes: Sequence[Change], circuit: int, t0: float, t1: float
) -> np.ndarray:
    """Per robot, the fraction of `[t0, t1)` whose current circuit is `circuit`."""
    durations, states = allocation_segments(initial, changes, t0, t1)
    return (durations[:, None] * (states == circuit)).sum(axis=0) / durations.sum()


def robots_on_circuit_distribution(
    initial: Sequence[int], changes: Sequence[Change], circuit: int, t0: float, t1: float
) -> np.ndarray:
    """Fraction of `[t0, t1)` with exactly k robots on `circuit`, for k = 0..n_robots."""
    durations, states = allocation_segments(initial, changes, t0, t1)
    counts = (states == circuit).sum(axis=1)
    out = np.zeros(states.shape[1] + 1)
    np.add.at(out, counts, durations)
    return out / durations.sum()


def value_rate(
    delivery_times: Sequence[float],
    delivery_circuits: Sequence[int],
    values: Sequence[float],
    n_robots: int,
    t0: float,
    t1: float,
) -> float:
    """The paper's performance measure: delivered value per robot per 10 s of simulated time,
    each delivery on circuit i counting `w_i / max(w)`, over deliveries completed in `[t0, t1)`."""
    times = np.asarray(delivery_times, dtype=float)
    circuits = np.asarray(delivery_circuits, dtype=np.int64)
    w = np.asarray(values, dtype=float)
    inside = (times >= t0) & (times < t1)
    delivered = (w[circuits[inside]] / w.max()).sum()
    return float(delivered / n_robots / ((t1 - t0) / 10.0))
