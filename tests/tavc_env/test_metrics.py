"""Measures of an allocation over time (tavc_env.metrics, DESIGN.md section 3) on hand-built
timelines with known answers: the time-weighted f:s distribution, per-robot time shares, the
distribution of the number of robots on a circuit, the delivered-value rate and the paper's
combinatorial expectation (Equation 3, the T column of Table 1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tavc_env import metrics

# 3 fast robots (0, 1, 2) and 3 slow ones (3, 4, 5); circuit 0 is the high-value one.
FAST = [True, True, True, False, False, False]
HIGH = 0
INITIAL = [1, 1, 1, 1, 1, 1]  # state 0:0
CHANGES = [
    (0.0, 0, 0),  # before the window: at t0 robot 0 (fast) is already on high
    (10.0, 3, 0),  # exactly at t0: counts from t0 -> 1:1 from 10
    (30.0, 1, 0),
    (30.0, 4, 0),  # two changes at the same time: 2:2 from 30, no zero-length 2:1
    (55.0, 0, 1),  # 1:2 from 55
    (70.0, 0, 1),  # a change to the circuit it already has: nothing changes
    (90.0, 2, 0),  # 2:2 from 90
    (110.0, 5, 0),  # exactly at t1: outside [t0, t1)
    (150.0, 1, 1),  # after the window
]
T0, T1 = 10.0, 110.0  # 100 s: seconds are percent
# Segments: [10, 30) 1:1 (20 %), [30, 55) 2:2 (25 %), [55, 90) 1:2 (35 %), [90, 110) 2:2 (20 %).
EXPECTED = {(1, 1): 20.0, (2, 2): 45.0, (1, 2): 35.0}

# Paper, Table 1, column T (one decimal as printed), rows f:s.
PAPER_T = {
    (0, 0): 1.5,
    (0, 1): 4.7,
    (0, 2): 4.7,
    (0, 3): 1.5,
    (1, 0): 4.7,
    (1, 1): 14.1,
    (1, 2): 14.1,
    (1, 3): 4.7,
    (2, 0): 4.7,
    (2, 1): 14.1,
    (2, 2): 14.1,
    (2, 3): 4.7,
    (3, 0): 1.5,
    (3, 1): 4.7,
    (3, 2): 4.7,
    (3, 3): 1.5,
}


def all_states(g: int = 3, h: int = 3) -> set[tuple[int, int]]:
    return {(f, s) for f in range(g + 1) for s in range(h + 1)}


# -- f:s distribution --------------------------------------------------------------------------


def test_state_time_distribution_hand_built_timeline() -> None:
    dist = metrics.state_time_distribution(INITIAL, CHANGES, FAST, HIGH, T0, T1)
    assert set(dist) == all_states()  # all 16 states appear, unvisited ones with 0
    for state in all_states():
        assert dist[state] == pytest.approx(EXPECTED.get(state, 0.0), abs=1e-12), state
    assert sum(dist.values()) == pytest.approx(100.0, abs=1e-12)


def test_state_time_distribution_window_cuts_segments() -> None:
    # [40, 80): the 2:2 segment [30, 55) is cut at 40, the 1:2 segment [55, 90) at 80.
    dist = metrics.state_time_distribution(INITIAL, CHANGES, FAST, HIGH, 40.0, 80.0)
    expected = {(2, 2): 37.5, (1, 2): 62.5}
    for state in all_states():
        assert dist[state] == pytest.approx(expected.get(state, 0.0), abs=1e-12), state


def test_state_time_distribution_window_inside_one_segment() -> None:
    dist = metrics.state_time_distribution(INITIAL, CHANGES, FAST, HIGH, 31.0, 32.0)
    assert dist[(2, 2)] == pytest.approx(100.0)
    assert sum(v for k, v in dist.items() if k != (2, 2)) == 0.0


def test_state_time_distribution_changes_all_before_or_after_the_window() -> None:
    before = [(1.0, 0, 0), (2.0, 3, 0), (3.0, 4, 0)]
    dist = metrics.state_time_distribution(INITIAL, before, FAST, HIGH, 100.0, 200.0)
    assert dist[(1, 2)] == pytest.approx(100.0)
    after = [(300.0, 0, 0)]
    dist = metrics.state_time_distribution(INITIAL, after, FAST, HIGH, 100.0, 200.0)
    assert dist[(0, 0)] == pytest.approx(100.0)
    dist = metrics.state_time_distribution([0] * 6, [], FAST, HIGH, 0.0, 5.0)
    assert dist[(3, 3)] == pytest.approx(100.0)


def test_state_time_distribution_speed_classes_are_taken_from_the_mask() -> None:
    # The same timeline with fast and slow robots interleaved: f and s swap roles per robot.
    fast = [False, True, False, True, False, True]
    initial = [0, 0, 1, 1, 1, 1]  # robot 0 (slow) and robot 1 (fast) on high: 1:1
    changes = [(5.0, 3, 0), (7.5, 0, 1)]  # 2:1 from 5, 2:0 from 7.5
    dist = metrics.state_time_distribution(initial, changes, fast, HIGH, 0.0, 10.0)
    assert dist[(1, 1)] == pytest.approx(50.0)
    assert dist[(2, 1)] == pytest.approx(25.0)
    assert dist[(2, 0)] == pytest.approx(25.0)


def test_state_time_distribution_high_circuit_is_a_parameter() -> None:
    # With circuit 1 as the high-value one, robots off circuit 0 count.
    dist = metrics.state_time_distribution(INITIAL, CHANGES, FAST, 1, T0, T1)
    mirrored = {(3 - f, 3 - s): v for (f, s), v in EXPECTED.items()}
    for state in all_states():
        assert dist[state] == pytest.approx(mirrored.get(state, 0.0), abs=1e-12), state


def test_state_time_distribution_other_team_sizes() -> None:
    dist = metrics.state_time_distribution([0, 1, 1], [(2.0, 1, 0)], [True, False, False], 0, 0, 4)
    assert set(dist) == all_states(1, 2)
    assert dist[(1, 0)] == pytest.approx(50.0)
    assert dist[(1, 1)] == pytest.approx(50.0)


def test_out_of_order_changes_raise() -> None:
    with pytest.raises(ValueError, match="not in time order at time 20"):
        metrics.state_time_distribution(INITIAL, [(50.0, 0, 0), (20.0, 1, 0)], FAST, HIGH, 0, 100)
    # also when both lie before the window
    with pytest.raises(ValueError, match="not in time order"):
        metrics.time_share(INITIAL, [(5.0, 0, 0), (3.0, 1, 0)], HIGH, 10, 100)


def test_out_of_order_change_after_a_change_beyond_the_window_raises() -> None:
    with pytest.raises(ValueError, match="not in time order"):
        metrics.state_time_distribution(
            INITIAL, [(200.0, 0, 0), (50.0, 1, 0)], FAST, HIGH, 0.0, 100.0
        )


@pytest.mark.parametrize(("t0", "t1"), [(10.0, 10.0), (10.0, 5.0)])
def test_empty_window_raises(t0: float, t1: float) -> None:
    with pytest.raises(ValueError, match="is empty"):
        metrics.state_time_distribution(INITIAL, CHANGES, FAST, HIGH, t0, t1)


# -- time shares and occupancy -----------------------------------------------------------------


def test_time_share_per_robot() -> None:
    share = metrics.time_share(INITIAL, CHANGES, HIGH, T0, T1)
    # robot 0: on high until 55; 1: from 30; 2: from 90; 3: from 10; 4: from 30; 5: never
    np.testing.assert_allclose(share, [0.45, 0.8, 0.2, 1.0, 0.8, 0.0], atol=1e-12)
    other = metrics.time_share(INITIAL, CHANGES, 1, T0, T1)
    np.testing.assert_allclose(share + other, np.ones(6), atol=1e-12)
    # consistent with the f:s distribution: mean fast share = mean f / 3 over time
    dist = metrics.state_time_distribution(INITIAL, CHANGES, FAST, HIGH, T0, T1)
    mean_f = sum(f * v / 100 for (f, _), v in dist.items())
    assert share[:3].sum() == pytest.approx(mean_f)


def test_robots_on_circuit_distribution() -> None:
    dist = metrics.robots_on_circuit_distribution(INITIAL, CHANGES, HIGH, T0, T1)
    # [10, 30): robots 0, 3 -> 2; [30, 55): 0, 1, 3, 4 -> 4; [55, 90): 1, 3, 4 -> 3;
    # [90, 110): 1, 2, 3, 4 -> 4
    np.testing.assert_allclose(dist, [0, 0, 0.2, 0.35, 0.45, 0, 0], atol=1e-12)
    assert len(dist) == 7
    low = metrics.robots_on_circuit_distribution(INITIAL, CHANGES, 1, T0, T1)
    np.testing.assert_allclose(low, dist[::-1], atol=1e-12)  # k on high = 6 - k on low


def test_value_rate_hand_computed() -> None:
    times = [5.0, 10.0, 20.0, 50.0, 109.9, 110.0, 200.0]
    circuits = [0, 0, 1, 0, 1, 0, 0]
    # Inside [10, 110): t=10 (w 2200 -> 1), 20 (2000 -> 10/11), 50 (1), 109.9 (10/11) = 42/11;
    # per robot (2): 21/11; per 10 s over 100 s: 21/110.
    rate = metrics.value_rate(times, circuits, [2200.0, 2000.0], 2, 10.0, 110.0)
    assert rate == pytest.approx(21 / 110, rel=1e-12)
    # the maximum value need not be circuit 0's
    rate = metrics.value_rate([1.0, 2.0], [0, 1], [1000.0, 4000.0], 1, 0.0, 10.0)
    assert rate == pytest.approx(1.25, rel=1e-12)
    assert metrics.value_rate([], [], [2200.0, 2000.0], 6, 0.0, 3600.0) == 0.0


# -- Equation 3 --------------------------------------------------------------------------------


def test_combinatorial_expectation_is_equation_3() -> None:
    t = metrics.combinatorial_expectation(3, 3)
    assert set(t) == all_states()
    for (f, s), value in t.items():
        assert value == pytest.approx(100 * math.comb(3, f) * math.comb(3, s) / 2**6, abs=1e-12)
    assert t[(1, 1)] == 14.0625
    assert t[(0, 0)] == 1.5625
    assert t[(3, 0)] == 1.5625
    assert t[(2, 1)] == 14.0625
    assert t[(0, 1)] == 4.6875
    assert sum(t.values()) == pytest.approx(100.0, abs=1e-12)


def test_combinatorial_expectation_matches_papers_t_column() -> None:
    t = metrics.combinatorial_expectation(3, 3)
    for state, printed in PAPER_T.items():
        # To the printed precision (one unit of the last digit: the paper prints 1.5625 as 1.5).
        assert abs(t[state] - printed) < 0.1, (state, t[state], printed)
        if printed != 1.5:
            assert round(t[state], 1) == printed


@pytest.mark.parametrize(("g", "h"), [(0, 6), (1, 1), (2, 4), (6, 0)])
def test_combinatorial_expectation_other_teams(g: int, h: int) -> None:
    t = metrics.combinatorial_expectation(g, h)
    assert set(t) == all_states(g, h)
    assert sum(t.values()) == pytest.approx(100.0, abs=1e-12)
    # agrees with the f:s distribution of a fair-coin allocation enumerated exhaustively
    n = g + h
    fast = [True] * g + [False] * h
    counts: dict[tuple[int, int], float] = dict.fromkeys(t, 0.0)
    for bits in range(2**n):
        on_high = [(bits >> k) & 1 == 0 for k in range(n)]
        initial = [0 if x else 1 for x in on_high]
        dist = metrics.state_time_distribution(initial, [], fast, 0, 0.0, 1.0)
        for k, v in dist.items():
            counts[k] += v / 2**n
    for k in t:
        assert counts[k] == pytest.approx(t[k], abs=1e-9)
