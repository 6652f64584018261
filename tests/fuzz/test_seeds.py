"""Fuzzing seeds of every type: a valid seed (None, or an integer >= 0 of any width: int or numpy
integer) resets reproducibly (the same arena as its Python int); anything else (bools, floats,
strings, arrays, fractions, negative numbers) raises a ValueError naming the seed and leaves the
env as it was."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given

import tavc_env
from tavc_agents.envs.single_robot import SingleRobotEnv
from tavc_env.env import _arena_digest
from tests.fuzz.strategies import SEEDS, fuzz_settings, is_valid_seed

SEED_REFUSED = r"^seed = .* is invalid; allowed: None or an integer >= 0"


@fuzz_settings(60)
@given(seed=SEEDS)
def test_the_env_takes_every_integer_seed_and_refuses_the_rest(seed: Any) -> None:
    env = tavc_env.parallel_env()
    env.reset(seed=12)
    before = _arena_digest(env.sim)
    if not is_valid_seed(seed):
        with pytest.raises(ValueError, match=SEED_REFUSED):
            env.reset(seed=seed)
        assert _arena_digest(env.sim) == before
        return
    obs, _ = env.reset(seed=seed)
    assert set(obs) == set(env.possible_agents)
    if seed is not None:
        twin = tavc_env.parallel_env()
        twin.reset(seed=int(seed))
        assert _arena_digest(twin.sim) == _arena_digest(env.sim)
        assert np.array_equal(twin.state(), env.state())


@fuzz_settings(30)
@given(seed=SEEDS)
def test_the_single_robot_env_takes_every_integer_seed_and_refuses_the_rest(seed: Any) -> None:
    env = SingleRobotEnv(episode_s=300.0)
    if not is_valid_seed(seed):
        with pytest.raises(ValueError, match=SEED_REFUSED):
            env.reset(seed=seed)
        return
    first, _ = env.reset(seed=seed)
    if seed is not None:
        twin = SingleRobotEnv(episode_s=300.0)
        again, _ = twin.reset(seed=int(seed))
        assert np.array_equal(first, again)
        assert _arena_digest(twin.env.sim) == _arena_digest(env.env.sim)
