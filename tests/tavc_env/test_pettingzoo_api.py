"""PettingZoo's own checkers (`pettingzoo.test`) over several configurations.

Every checker runs inside `strict_warnings()`: any warning is a failure (in particular the
missing-agent warnings "Live agent was not given ...", "... was dead last turn" and "No agents
present ..."), except the advisories PettingZoo gives for every Dict observation space.

The checkers sample actions from the agents' spaces; the spaces are seeded first (and the envs reset
with a seed), so every run here is reproducible. Cycle counts are small (each event-driven step is
about 15 simulated seconds); the one long run is the issue's must-show
`parallel_api_test(tavc_env.parallel_env(), num_cycles=1000)`.
"""

from __future__ import annotations

import functools
import types
from typing import Any

import numpy as np
import pytest
from pettingzoo.test import (
    api_test,
    max_cycles_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    seed_test,
    state_test,
)

import tavc_env
from tavc_env.env import TavcArenaEnv
from tests.helpers import CONFIGS, OBSERVATION_CONFIGS, seed_spaces, strict_warnings

CHECKED = {**CONFIGS, **OBSERVATION_CONFIGS}

# Parallel-API cycles per configuration: about the same simulated time for each (fixed-interval
# steps are 30 s; event-driven steps about 15 s, shorter with 12 robots).
PARALLEL_CYCLES = {
    "dahl2004": 60,
    "dahl2004_homogeneous": 60,
    "three_circuits_12_robots": 80,
    "fixed_interval_30s": 30,
    "paper_id_observations": 30,
    "rich_observations": 30,
    "box_observations": 30,
    "rich_box_observations": 30,
    "rich_fixed_interval": 20,
}

config_names = pytest.mark.parametrize("name", list(CHECKED))


def _seeded(factory: Any, **kwargs: Any) -> Any:
    """Build an env, reset it with a seed and seed its spaces: a checker's later unseeded
    `reset()` then continues a seeded generator, and its sampled actions are reproducible."""
    env = factory(**kwargs)
    env.reset(seed=123)
    return seed_spaces(env, 7)


def _factories(name: str) -> tuple[Any, Any]:
    kwargs = CHECKED[name]
    return (
        functools.partial(_seeded, tavc_env.parallel_env, **kwargs),
        functools.partial(_seeded, tavc_env.env, **kwargs),
    )


@pytest.mark.slow
def test_parallel_api_test_1000_cycles_default_env() -> None:
    """The issue's must-show: the default env passes PettingZoo's parallel API test over 1000
    cycles (the checker runs two episodes of 1000 steps, each about 4.5 simulated hours)."""
    with strict_warnings():
        parallel_api_test(env := tavc_env.parallel_env(), num_cycles=1000)
    # The checker set max_cycles=1000; the last episode ran all of it and was truncated.
    assert env.num_cycles == 1000
    assert env.agents == []


@config_names
def test_parallel_api_test(name: str) -> None:
    par, _ = _factories(name)
    env = par()
    with strict_warnings():
        parallel_api_test(env, num_cycles=PARALLEL_CYCLES[name])
    assert env.num_cycles == PARALLEL_CYCLES[name]
    assert env.agents == []


@config_names
def test_aec_api_test(name: str) -> None:
    _, aec = _factories(name)
    env = aec()
    with strict_warnings():
        api_test(env, num_cycles=15)
    assert isinstance(env.unwrapped, TavcArenaEnv)


@config_names
def test_parallel_seed_test(name: str) -> None:
    par, _ = _factories(name)
    with strict_warnings():
        parallel_seed_test(par, num_cycles=10)


@config_names
def test_aec_seed_test(name: str) -> None:
    _, aec = _factories(name)
    with strict_warnings():
        seed_test(aec, num_cycles=10)


def test_max_cycles_test_on_the_module() -> None:
    """`max_cycles_test` takes a module with `parallel_env` and `env`: `tavc_env` itself is one.
    (The checker resets unseeded; it only counts steps, which does not depend on the draws.)"""
    with strict_warnings():
        max_cycles_test(tavc_env)


@config_names
def test_max_cycles_test(name: str) -> None:
    par, aec = _factories(name)
    module = types.SimpleNamespace(parallel_env=par, env=aec)
    with strict_warnings():
        max_cycles_test(module)


@config_names
def test_state_test(name: str) -> None:
    par, aec = _factories(name)
    with strict_warnings():
        state_test(aec(), par(), num_cycles=8)


@pytest.mark.parametrize("name", ["dahl2004", "three_circuits_12_robots"])
def test_render_test_headless(name: str) -> None:
    """PettingZoo's render test over every advertised mode ("human" against SDL's dummy video
    driver, "rgb_array"), plus: frames have the renderer's size and are not blank."""
    _, aec = _factories(name)
    config = tavc_env.parallel_env(**CONFIGS[name]).config
    from tavc_env.render import MARGIN_PX, PANEL_PX, PIXELS_PER_M

    height = int(config.height * PIXELS_PER_M) + 2 * MARGIN_PX + PANEL_PX
    width = int(config.width * PIXELS_PER_M) + 2 * MARGIN_PX

    def frame_ok(frame: np.ndarray) -> bool:
        return (
            frame.shape == (height, width, 3)
            and len(np.unique(frame[::8, ::8].reshape(-1, 3), axis=0)) > 5
        )

    with strict_warnings():
        render_test(aec, custom_tests={"rgb_array": frame_ok, "human": lambda res: res is None})


def test_strict_warnings_turns_missing_agent_warnings_into_failures() -> None:
    """The warning filter is not vacuous: an env that leaves a live agent out of its infos makes
    `parallel_api_test` warn "Live agent was not given info", and that fails the test."""

    class DropsAnInfo(TavcArenaEnv):
        def step(self, actions: dict[str, Any]) -> Any:
            obs, rewards, terms, truncs, infos = super().step(actions)
            infos.pop("robot_0", None)
            return obs, rewards, terms, truncs, infos

    env = seed_spaces(DropsAnInfo(), 0)
    with pytest.raises(pytest.fail.Exception, match="Live agent was not given info"):  # noqa: SIM117
        with strict_warnings():
            parallel_api_test(env, num_cycles=2)
