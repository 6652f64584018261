"""Scheduled events of a trial (`tavc_agents.experiments.runner.Event`) are validated in full before
the trial starts, not when they fire (issue 12, item 10: a bad priority change used to raise hours
into a run, after all that simulation was done). Every refusal is a ValueError naming the event,
the bad value and what is allowed.
"""

from __future__ import annotations

import re
from typing import Any

import pytest

from tavc_agents.allocators.baselines import RandomAllocator
from tavc_agents.experiments.runner import Event, run_trial


def run(events: Any, measured_s: float = 120.0, **env_kwargs: Any) -> list[float]:
    """Run a short random-allocation trial with `events`; the simulated times it stepped to."""
    stepped: list[float] = []
    run_trial(
        lambda agent: RandomAllocator(),
        seed=0,
        convergence_s=0.0,
        measured_s=measured_s,
        events=events,
        progress=stepped.append,
        **env_kwargs,
    )
    return stepped


def refused_before_the_start(events: Any, pattern: str, **env_kwargs: Any) -> None:
    stepped: list[float] = []
    with pytest.raises(ValueError, match=pattern) as error:
        run_trial(
            lambda agent: RandomAllocator(),
            seed=0,
            convergence_s=0.0,
            measured_s=120.0,
            events=events,
            progress=stepped.append,
            **env_kwargs,
        )
    assert "allowed" in str(error.value)
    assert stepped == [], f"the trial ran to {stepped[-1]} s before the event was refused"


# -- at the trial's start (what depends on the arena) ------------------------------------------


@pytest.mark.parametrize("values", [(1.0,), (1.0, 2.0, 3.0)])
def test_set_values_with_the_wrong_number_of_values(values: tuple[float, ...]) -> None:
    """Used to be refused only when the event fired (here after 60 simulated seconds)."""
    pattern = (
        rf"^events\[0\]\.values = {re.escape(repr(values))} is invalid; "
        r"allowed: 2 circuit values \(one per circuit\)"
    )
    refused_before_the_start([Event(60.0, "set_values", values=values)], pattern)


def test_set_values_counted_against_the_arena_of_the_trial() -> None:
    three = Event(30.0, "set_values", values=(1.0, 2.0, 3.0))
    stepped = run([three], arena="three_circuits_three_classes")
    assert stepped[-1] == pytest.approx(120.0)


@pytest.mark.parametrize("robot", [6, 99])
def test_a_robot_outside_the_team(robot: int) -> None:
    pattern = rf"^events\[1\]\.robot = {robot} is invalid; allowed: a robot index in \[0, 5\]"
    events = [Event(10.0, "break_down", robot=0), Event(20.0, "break_down", robot=robot)]
    refused_before_the_start(events, pattern)


def test_a_repair_of_a_robot_that_never_broke_down() -> None:
    """Used to raise "agent = 'robot_2' is invalid; allowed: a robot that is broken" when it
    fired."""
    events = [Event(10.0, "break_down", robot=1), Event(60.0, "repair", robot=2)]
    pattern = (
        r"^events\[1\]\.robot = 2 is invalid; allowed: a robot broken down by an earlier event "
        r"or a scheduled breakdown of the arena \(robots 1\)"
    )
    refused_before_the_start(events, pattern)


def test_a_second_repair_after_one_breakdown() -> None:
    events = [
        Event(10.0, "break_down", robot=1),
        Event(60.0, "repair", robot=1),
        Event(90.0, "repair", robot=1),
    ]
    refused_before_the_start(events, r"^events\[2\]\.robot = 1 is invalid; .*\(robots none\)")


def test_a_repair_after_a_breakdown_and_after_a_scheduled_breakdown_runs() -> None:
    from tavc_env import Breakdown

    events = [
        Event(20.0, "repair", robot=3),  # broken by the arena's own schedule at 10 s
        Event(30.0, "break_down", robot=1),
        Event(60.0, "repair", robot=1),
    ]
    stepped = run(events, arena={"breakdowns": (Breakdown(robot=3, at_s=10.0),)})
    assert stepped[-1] == pytest.approx(120.0)


def test_an_event_after_the_trial_ends() -> None:
    """Used to be dropped silently: the trial ended before it."""
    pattern = (
        r"^events\[0\]\.at_s = 500\.0 is invalid; allowed: a time within the trial, "
        r"\[0, 120\) s"
    )
    refused_before_the_start([Event(500.0, "break_down", robot=0)], pattern)
    refused_before_the_start([Event(120.0, "break_down", robot=0)], r"^events\[0\]\.at_s = 120")


@pytest.mark.parametrize("events", [Event(10.0, "break_down", robot=0), 5, "events"], ids=repr)
def test_events_that_are_not_a_sequence_of_events(events: Any) -> None:
    refused_before_the_start(events, r"^events = .* is invalid; allowed: a sequence of Event")


def test_an_element_that_is_not_an_event() -> None:
    refused_before_the_start([("break_down", 0)], r"^events\[0\] = .* is invalid; allowed: an ")


# -- at construction (what does not) -----------------------------------------------------------


@pytest.mark.parametrize(
    ("values", "shown"),
    [
        ((0.0, 1.0), r"\(0\.0, 1\.0\)"),
        ((-1.0, 1.0), r"\(-1\.0, 1\.0\)"),
        ((float("nan"), 1.0), r"\(nan, 1\.0\)"),
        ((float("inf"), 1.0), r"\(inf, 1\.0\)"),
        ((True, 1.0), r"\(True, 1\.0\)"),
        (("2200", "2000"), r"\('2200', '2000'\)"),
        (5, "5"),
        ((), r"\(\)"),
        ("ab", "'ab'"),
    ],
)
def test_set_values_that_are_not_positive_finite_numbers(values: Any, shown: str) -> None:
    """Non-positive values used to be refused only when the event fired; strings, a number and
    the empty tuple gave float()'s or tuple()'s own errors."""
    pattern = rf"^event\.values = {shown} is invalid; allowed: a non-empty sequence of finite"
    with pytest.raises(ValueError, match=pattern):
        Event(10.0, "set_values", values=values)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"at_s": -1.0, "kind": "break_down", "robot": 0}, r"^event\.at_s = -1\.0 is invalid"),
        ({"at_s": float("inf"), "kind": "repair", "robot": 0}, r"^event\.at_s = inf is invalid"),
        ({"at_s": 1.0, "kind": "explode", "robot": 0}, r"^event\.kind = 'explode' is invalid"),
        ({"at_s": 1.0, "kind": "break_down", "robot": True}, r"^event\.robot = True is invalid"),
        ({"at_s": 1.0, "kind": "break_down", "robot": -1}, r"^event\.robot = -1 is invalid"),
        ({"at_s": 1.0, "kind": "break_down"}, r"^event\.robot = None is invalid"),
        ({"at_s": 1.0, "kind": "set_values"}, r"^event\.values = None is invalid"),
    ],
)
def test_bad_event_fields(kwargs: dict[str, Any], pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        Event(**kwargs)


def test_a_numpy_integer_robot_index_is_a_robot_index() -> None:
    import numpy as np

    event = Event(10.0, "break_down", robot=np.int64(2))  # type: ignore[arg-type]
    assert event.robot == 2 and type(event.robot) is int
