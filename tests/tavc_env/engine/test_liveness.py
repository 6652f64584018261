"""The jam detector: a standing knot is reported (in infos, on the env and in trial results), a
long free leg is not, and the shipped presets never jam."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tavc_env
from agents.allocators.baselines import RandomAllocator
from agents.experiments.runner import run_trial
from tavc_env import ArenaConfig, Circuit, Robot


def run_random(env: tavc_env.TavcArenaEnv, seed: int) -> list[bool]:
    """Random choices until the episode ends; the `jammed` flag of every step."""
    rng = np.random.default_rng(seed)
    _, infos = env.reset(seed=seed)
    flags = []
    while env.agents:
        actions = {a: int(rng.integers(2)) for a in env.agents if infos[a]["action_required"]}
        _, _, _, _, infos = env.step(actions)
        if env.agents:
            flags.append(all(infos[a]["jammed"] for a in env.agents))
    return flags


def test_a_standing_knot_is_reported_as_a_jam() -> None:
    # 18 robots on dahl2004's two circuits knot at a source within the first hour (issue 12).
    robots = tuple([Robot(0.30, "fast")] * 9 + [Robot(0.20, "slow")] * 9)
    env = tavc_env.parallel_env(robots=robots, max_sim_time_s=3600.0, max_cycles=10**9)
    flags = run_random(env, seed=0)
    assert env.jams >= 1 and any(flags)
    assert env.time_jammed_s > 600.0


def test_a_long_free_leg_is_not_a_jam() -> None:
    # one slow robot on 56 m legs: minutes without any task event, but always moving
    config = ArenaConfig(
        width=60.0,
        height=8.0,
        circuits=(
            Circuit(source=(2.0, 6.5), sink=(58.0, 1.5), value=2000.0),
            Circuit(source=(58.0, 6.5), sink=(2.0, 1.5), value=2000.0, queue_direction=(-1, 0)),
        ),
        robots=(Robot(0.2, "slow"),),
    )
    env = tavc_env.parallel_env(
        config=config, jam_window_s=100.0, max_sim_time_s=3600.0, max_cycles=10**9
    )
    flags = run_random(env, seed=1)
    assert env.jams == 0 and not any(flags)


def test_the_presets_never_jam_and_trials_record_it() -> None:
    for preset in ("dahl2004", "three_circuits_three_classes"):
        result = run_trial(
            lambda agent: RandomAllocator(),
            seed=3,
            convergence_s=0.0,
            measured_s=2 * 3600.0,
            preset=preset,
        )
        assert result.jams == 0 and result.jammed_s == 0.0, preset
    robots = tuple([Robot(0.30, "fast")] * 9 + [Robot(0.20, "slow")] * 9)
    knotted = run_trial(
        lambda agent: RandomAllocator(), seed=1, convergence_s=0.0, measured_s=7200.0, robots=robots
    )
    assert knotted.jams >= 1 and knotted.jammed_s > 0


@pytest.mark.parametrize("window", [0.0, -5.0, math.nan, "600"])
def test_a_bad_window_is_refused(window: object) -> None:
    with pytest.raises(ValueError, match="jam_window_s"):
        tavc_env.parallel_env(jam_window_s=window)
