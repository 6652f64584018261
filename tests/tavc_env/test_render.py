"""Rendering beyond PettingZoo's render test (which runs in test_pettingzoo_api.py): frames follow
the simulation, rendering without a mode warns and returns None, close() can be repeated.
SDL's dummy video driver is selected in conftest.py, so nothing opens a window."""

from __future__ import annotations

import numpy as np
import pytest

import tavc_env


def test_rgb_frames_follow_the_simulation() -> None:
    env = tavc_env.parallel_env(render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    assert isinstance(first, np.ndarray) and first.dtype == np.uint8 and first.shape[2] == 3
    assert np.array_equal(env.render(), first), "same state, same frame"
    env.step(dict.fromkeys(env.agents, 0))
    moved = env.render()
    assert moved.shape == first.shape and not np.array_equal(moved, first)
    env.break_down("robot_0")
    assert not np.array_equal(env.render(), moved), "a broken robot is drawn differently"
    env.close()
    env.close()
    assert env.render().shape == first.shape, "render works again after close"
    env.close()


def test_render_without_a_mode_warns_and_returns_none() -> None:
    env = tavc_env.parallel_env()
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None
    env.close()


def test_human_mode_returns_none() -> None:
    env = tavc_env.parallel_env(render_mode="human")
    env.reset(seed=0)
    assert env.render() is None
    env.close()
