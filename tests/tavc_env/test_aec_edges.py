"""The AEC view's edges (issue 28, item 3): calls before `reset`, an unknown agent, a step after
the end and `agent_iter` without a step each raise the package's ValueError naming the call, the
value and what is allowed (PettingZoo's own wrapper: a bare AssertionError, a KeyError, or only a
warning), and a refused call changes nothing. The same for every AEC factory (arena, scenario, v0)."""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable
from typing import Any

import pytest

import tavc_env
from tavc_env import scenarios, v0
from tavc_env.env import OrderCheckingWrapper

FACTORIES: dict[str, Callable[..., Any]] = {
    "arena": tavc_env.env,
    "scenario": lambda **kw: scenarios.env("dahl2004", **kw),
    "v0": v0.env,
}
factories = pytest.mark.parametrize("make", list(FACTORIES.values()), ids=list(FACTORIES))
BEFORE = r"called before reset\(\); allowed: call reset\(\) first"
ENDED = r"called after the episode ended \(every agent is done\); allowed: call reset\(\) first"


def _finished(make: Callable[..., Any]) -> Any:
    aec = make(max_cycles=2)
    aec.reset(seed=0)
    for _ in aec.agent_iter():
        _, _, terminated, truncated, _ = aec.last()
        aec.step(None if terminated or truncated else 0)
    assert aec.agents == []
    return aec


@factories
def test_every_call_before_reset_is_the_packages_error(make: Callable[..., Any]) -> None:
    aec = make()
    assert isinstance(aec, OrderCheckingWrapper)
    calls: list[tuple[str, Callable[[], Any]]] = [
        ("step(0)", lambda: aec.step(0)),
        ("observe('robot_0')", lambda: aec.observe("robot_0")),
        ("last()", aec.last),
        ("agent_iter()", aec.agent_iter),
        ("state()", aec.state),
    ]
    for name, call in calls:
        with pytest.raises(ValueError, match=f"^{re.escape(name)} {BEFORE}$"):
            call()
    aec.reset(seed=0)  # and the env still works
    assert aec.agent_selection == "robot_0"


@factories
def test_an_unknown_agent_is_named_with_the_allowed_ones(make: Callable[..., Any]) -> None:
    aec = make()
    aec.reset(seed=0)
    for agent in ("robot_99", 5, None, ("robot_0",)):
        with pytest.raises(ValueError, match=r"^agent .* is unknown; allowed: \['robot_0', "):
            aec.observe(agent)
    assert set(aec.observe("robot_5")) == {"observation", "action_mask"}


@factories
def test_a_step_or_last_after_the_end_is_refused(make: Callable[..., Any]) -> None:
    aec = _finished(make)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not PettingZoo's warning: the package's error
        for action in (0, None):
            with pytest.raises(ValueError, match=f"^step\\({action}\\) {ENDED}$"):
                aec.step(action)
        with pytest.raises(ValueError, match=f"^last\\(\\) {ENDED}$"):
            aec.last()
    assert list(aec.agent_iter()) == []  # the loop is simply over
    # an agent's last observation stays readable; a new episode starts with reset
    assert set(aec.observe("robot_0")) == {"observation", "action_mask"}
    aec.reset(seed=1)
    assert len(aec.agents) == 6


def test_agent_iter_without_a_step_between_is_refused_and_a_refused_step_is_not_a_step() -> None:
    aec = tavc_env.env()
    aec.reset(seed=0)
    loop = iter(aec.agent_iter())
    assert next(loop) == "robot_0"
    with pytest.raises(
        ValueError, match=r"before step\(\) of robot_0; allowed: call step\(\) once"
    ):
        next(loop)
    with pytest.raises(ValueError, match=r"action of robot_0 = 7 is invalid"):
        aec.step(7)  # refused: still robot_0's turn, and still no step taken
    with pytest.raises(ValueError, match="before step"):
        next(loop)
    aec.step(1)
    assert next(loop) == "robot_1"
    for bad in (-1, 1.5, "all"):
        with pytest.raises(
            ValueError, match=r"^max_iter = .* is invalid; allowed: an integer >= 0"
        ):
            aec.agent_iter(bad)  # type: ignore[arg-type]


def test_the_scenarios_and_v0_use_the_same_checked_view() -> None:
    for make in FACTORIES.values():
        assert type(make()) is OrderCheckingWrapper
