"""The allocation-timeline measures of `tavc_agents.analysis.allocation`, on hand-made trials whose
answers can be worked out on paper: circuits at a moment, switches, delivered value, the model
value of the held allocation, settle time and the vacancy chain after a breakdown."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from tavc_agents.analysis import allocation
from tavc_agents.experiments.runner import TrialResult
from tavc_agents.model import CompletionModel, SpeedClasses
from tavc_env import Robot

CLASSES = SpeedClasses(
    labels=("fast", "slow"), robots=(Robot(0.3, "fast"), Robot(0.2, "slow")), of_robot=(0, 0, 1, 1)
)


def trial(**fields: Any) -> TrialResult:
    """A four-robot trial (robots 0, 1 fast; 2, 3 slow) of 2 h + 2 h on two circuits."""
    base: dict[str, Any] = {
        "seed": 0,
        "label": "hand-made",
        "env_kwargs": {},
        "agents": [f"robot_{i}" for i in range(4)],
        "speed_classes": ["fast", "fast", "slow", "slow"],
        "speeds": [0.3, 0.3, 0.2, 0.2],
        "values": [2.0, 1.0],
        "convergence_s": 7200.0,
        "measured_s": 7200.0,
        "end_s": 14400.0,
        "initial_circuits": [0, 0, 1, 1],
    }
    base.update(fields)
    return TrialResult(**base)


def model() -> CompletionModel:
    """c_{i,(f,s)} = f + s/2 tasks per second on circuit 0 and half that on circuit 1 (linear,
    so the optimum puts everyone on circuit 0, the high-value one)."""
    rates = np.zeros((2, 3, 3))
    for f in range(3):
        for s in range(3):
            rates[0, f, s] = f + s / 2
            rates[1, f, s] = (f + s / 2) / 2
    return CompletionModel(("fast", "slow"), (2, 2), (2.0, 1.0), rates)


def test_circuits_at_applies_changes_strictly_before_the_moment() -> None:
    r = trial(changes=[(10.0, 0, 1), (20.0, 2, 0)])
    assert allocation.circuits_at(r, 10.0).tolist() == [0, 0, 1, 1]
    assert allocation.circuits_at(r, 15.0).tolist() == [1, 0, 1, 1]
    assert allocation.circuits_at(r, 1e9).tolist() == [1, 0, 0, 1]


def test_switches_per_robot_hour_count_only_the_window() -> None:
    r = trial(changes=[(100.0, 0, 1), (7300.0, 1, 1), (7400.0, 1, 0), (14400.0, 2, 0)])
    # two switches in [7200, 14400): 2 / 4 robots / 2 h
    assert allocation.switches_per_robot_h(r, 7200.0, 14400.0) == 0.25


def test_delivered_value_per_hour_and_per_robot_per_10_s() -> None:
    r = trial(
        delivery_time_s=[100.0, 7300.0, 7400.0, 9000.0],
        delivery_robot=[0, 0, 2, 1],
        delivery_circuit=[0, 0, 1, 0],
        delivery_value=[2.0, 2.0, 1.0, 1.0],  # the last after a value change
    )
    # in [7200, 14400): w / max w = 1 + 0.5 + 0.5 = 2 over 2 h
    assert allocation.delivered_per_h(r, 7200.0, 14400.0) == 1.0
    # the paper's measure weighs by the configured values: 1 + 0.5 + 1 = 2.5 per 4 robots per 720
    assert allocation.delivered_performance(r, 7200.0, 14400.0) == pytest.approx(2.5 / 4 / 720)


def test_held_performance_is_time_weighted() -> None:
    m = model()
    # first hour: 2 fast on c0, 2 slow on c1 -> 2 * 2 + 1 * 0.5 = 4.5 per s;
    # second hour: everyone on c0 -> 2 * 3 = 6 per s
    r = trial(changes=[(3600.0, 2, 0), (3600.0, 3, 0)])
    first = 4.5 / 2.0 / 4 * 10.0
    second = 6.0 / 2.0 / 4 * 10.0
    assert allocation.held_performance(r, m, CLASSES, 0.0, 3600.0) == pytest.approx(first)
    assert allocation.held_performance(r, m, CLASSES, 0.0, 7200.0) == pytest.approx(
        (first + second) / 2
    )
    # the optimum is everyone on circuit 0: the second hour is at 100 %
    fractions = allocation.held_fractions(r, m, CLASSES, [0.0, 3600.0, 7200.0])
    assert fractions == pytest.approx([first / second, 1.0])


def test_settle_time_is_the_first_window_within_the_band() -> None:
    m = model()
    best = m.performance(m.optimum())
    r = trial(changes=[(2 * 3600.0, 2, 0), (2 * 3600.0, 3, 0)])  # optimum from hour 2
    # the trial ends at 4 h; 2-hour windows: [0, 2) off, [1, 3) half off, [2, 4) on
    assert allocation.settle_time_h(r, m, CLASSES, best, 0.03, 2) == 2.0
    assert allocation.settle_time_h(r, m, CLASSES, best, 0.03, 1) == 2.0
    # off, the allocation is at 75 % of the optimum; within 20 % the window [1, 3) (87.5 %) counts
    assert allocation.settle_time_h(r, m, CLASSES, best, 0.2, 2) == 1.0
    late = trial(changes=[(3 * 3600.0, 2, 0), (3 * 3600.0, 3, 0)])  # [2, 4) half off: never
    assert math.isinf(allocation.settle_time_h(late, m, CLASSES, best, 0.03, 2))
    never = trial()
    assert math.isinf(allocation.settle_time_h(never, m, CLASSES, best, 0.03, 2))


def test_vacancy_chain_refilled_by_the_first_robot_onto_the_circuit() -> None:
    # robot 0 (fast, circuit 0) breaks at 100 s; robot 3 moves 1 -> 0 at 130 s, then robot 2
    # moves 1 -> 0 at 160 s; circuit 0 had 2 robots, so it is full again at 130 s
    r = trial(changes=[(100.0, 0, 0), (130.0, 3, 0), (160.0, 2, 0), (500.0, 1, 1)])
    chain = allocation.vacancy_chain(r, broken=0, t_break=100.0, t_repair=1000.0)
    assert chain.full == 2
    assert chain.recovery_s == 30.0
    assert chain.moves == [(130.0, 3, 0)]  # the broken robot's own change does not count
    assert chain.head == (130.0, 3, 0)


def test_vacancy_chain_never_refilled() -> None:
    r = trial(changes=[(200.0, 2, 0), (300.0, 2, 1)])
    chain = allocation.vacancy_chain(r, broken=1, t_break=100.0, t_repair=1000.0)
    # robot 2 fills the place for 100 s: full strength again after 100 s
    assert chain.recovery_s == 100.0 and chain.head == (200.0, 2, 0)
    lonely = trial(changes=[(400.0, 3, 1)])
    chain = allocation.vacancy_chain(lonely, broken=1, t_break=100.0, t_repair=1000.0)
    assert math.isinf(chain.recovery_s)
    assert chain.head is None and chain.moves == [(400.0, 3, 1)]  # moves until the repair
    starts, count = allocation.working_on(lonely, 0, 100.0, 1000.0, broken=1)
    assert starts.tolist() == [100.0, 400.0] and count.tolist() == [1, 1]


def test_reduced_optimum_leaves_the_robot_out() -> None:
    m = model()
    assert m.optimum() == ((2, 2), (0, 0))
    assert allocation.reduced_optimum(m, CLASSES, 0) == ((1, 2), (0, 0))
    assert allocation.reduced_optimum(m, CLASSES, 3) == ((2, 1), (0, 0))
