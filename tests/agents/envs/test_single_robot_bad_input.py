"""`SingleRobotEnv` refuses bad input with a ValueError naming it (issue 12, item 10): an action
that is not an integer circuit index (a float used to be floored silently: 1.5 served circuit 1),
and a seed that is not an integer >= 0 (numpy integers are seeds; bool and float are not)."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest

from tavc_agents.allocators.baselines import FixedAllocator
from tavc_agents.envs.single_robot import SingleRobotEnv


def make() -> SingleRobotEnv:
    return SingleRobotEnv(episode_s=1800.0, others=lambda agent: FixedAllocator(1))


@pytest.mark.parametrize(
    "bad", [1.5, 0.9, 1.0, np.float64(1.0), True, np.bool_(False), "0", None, [0], 2, -1], ids=repr
)
def test_an_action_that_is_not_a_circuit_index_is_refused_and_changes_nothing(bad: Any) -> None:
    env, twin = make(), make()
    env.reset(seed=2)
    twin.reset(seed=2)
    time_before = env.env.sim_time_s
    pattern = rf"^action = {re.escape(repr(bad))} is invalid; allowed: a circuit index in \[0, 1\] \(an int"
    with pytest.raises(ValueError, match=pattern):
        env.step(bad)
    assert env.env.sim_time_s == time_before
    for action in (0, 1, 0):
        a, b = env.step(action), twin.step(action)
        assert repr(a) == repr(b)


@pytest.mark.parametrize("action", [np.int64(1), np.int8(1), np.array(1)], ids=repr)
def test_numpy_integer_actions_are_circuit_indices(action: Any) -> None:
    env, twin = make(), make()
    env.reset(seed=2)
    twin.reset(seed=2)
    assert repr(env.step(action)) == repr(twin.step(1))


def test_a_numpy_integer_seed_is_the_same_seed() -> None:
    env, twin = make(), make()
    assert repr(env.reset(seed=np.int64(7))) == repr(twin.reset(seed=7))
    assert repr(env.step(0)) == repr(twin.step(0))


@pytest.mark.parametrize("seed", [True, 3.0, "3", -1, np.float32(2.0)], ids=repr)
def test_a_seed_that_is_not_an_integer_is_refused(seed: Any) -> None:
    with pytest.raises(ValueError, match=rf"^seed = {re.escape(repr(seed))} is invalid; allowed"):
        make().reset(seed=seed)


def test_reset_options_that_are_not_a_mapping_are_refused() -> None:
    """issue 35: `reset(options='x')` was silently ignored."""
    with pytest.raises(ValueError, match=r"^options = 'x' is invalid; allowed: None or a mapping"):
        make().reset(seed=0, options="x")  # type: ignore[arg-type]
