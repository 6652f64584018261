"""The jam detector: a standing knot is reported (in infos, on the env and in trial results), a
long free leg is not, and the shipped presets never jam.

Since the waiting lines snake with an aisle and robots head for the end of a long line, no valid
arena is known to knot (the liveness study measures it), so the knot here is made certain: every
motor stalls mid-task (top speeds set to zero), and the robots keep their tasks but cannot move.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

import tavc_env
from tavc_agents.allocators.baselines import RandomAllocator
from tavc_agents.experiments.runner import run_trial
from tavc_env import ArenaConfig, Circuit, Robot


def run_random(
    env: tavc_env.TavcArenaEnv,
    seed: int,
    after_step: Callable[[tavc_env.TavcArenaEnv], None] | None = None,
) -> list[bool]:
    """Random choices until the episode ends; the `jammed` flag of every step."""
    rng = np.random.default_rng(seed)
    _, infos = env.reset(seed=seed)
    flags = []
    while env.agents:
        actions = {a: int(rng.integers(2)) for a in env.agents if infos[a]["action_required"]}
        _, _, _, _, infos = env.step(actions)
        if after_step is not None:
            after_step(env)
        if env.agents:
            flags.append(all(infos[a]["jammed"] for a in env.agents))
    return flags


def stall_motors_after(seconds: float) -> Callable[[tavc_env.TavcArenaEnv], None]:
    def stall(env: tavc_env.TavcArenaEnv) -> None:
        if env.sim.time_s >= seconds:
            env.sim.top_speed[:] = 0.0

    return stall


def test_a_standing_knot_is_reported_as_a_jam() -> None:
    env = tavc_env.parallel_env(max_sim_time_s=3600.0, max_cycles=10**9)
    flags = run_random(env, seed=0, after_step=stall_motors_after(300.0))
    assert env.jams == 1 and any(flags)
    # a window (600 s) without progress must pass before the jam is called; robots on a dock
    # still finish their service after the stall, and the windows are checked one after another
    assert 1200.0 < env.time_jammed_s <= 3600.0 - 300.0 - 600.0


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
            arena=preset,
        )
        assert result.jams == 0 and result.jammed_s == 0.0, preset
    knotted = run_trial(
        lambda agent: RandomAllocator(),
        seed=1,
        convergence_s=0.0,
        measured_s=7200.0,
        on_step=stall_motors_after(600.0),
    )
    assert knotted.jams == 1 and knotted.jammed_s > 0


@pytest.mark.parametrize("window", [0.0, -5.0, math.nan, "600"])
def test_a_bad_window_is_refused(window: object) -> None:
    with pytest.raises(ValueError, match="jam_window_s"):
        tavc_env.parallel_env(jam_window_s=window)
