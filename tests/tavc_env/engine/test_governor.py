"""The clearance governor (tavc_env.engine.navigation): speed scales with the free space to the
nearest robot in front, as a fraction of each robot's own top speed, and it is off by default."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tavc_env
from tavc_env.engine.navigation import steer_all


def command_speed(top_speed: float, other_at: tuple[float, float], governor: float) -> float:
    """The commanded speed of a robot at (2, 2) heading +x toward (6, 2), another robot holding
    still at `other_at` (outside its path, so no braking)."""
    pos = np.array([[2.0, 2.0], list(other_at)])
    heading = np.zeros(2)
    velocity = np.zeros((2, 2))
    steer_all(
        pos,
        heading,
        np.array([[6.0, 2.0], list(other_at)]),
        np.array([True, False]),
        np.array([top_speed, top_speed]),
        np.array([True, True]),
        0.22,  # radius
        1.5,  # sensing
        governor,
        False,  # overtaking
        1.75 * 0.1,  # turn step
        12.0,
        8.0,
        velocity,
        heading,
    )
    return float(math.hypot(*velocity[0]))


@pytest.mark.parametrize("clearance", [0.1, 0.3, 0.5])
def test_fast_and_slow_robots_lose_the_same_fraction_of_their_speed(clearance: float) -> None:
    # the other robot sits ahead and to the side, beyond the corridor: only the governor acts
    lateral = 0.7
    ahead = math.sqrt((clearance + 0.44) ** 2 - lateral**2) if clearance + 0.44 > lateral else 0.0
    other = (2.0 + ahead, 2.0 + lateral) if ahead > 0 else (2.0 + 0.3, 2.0 + clearance + 0.44)
    gap = math.hypot(other[0] - 2.0, other[1] - 2.0) - 0.44
    fractions = []
    for top in (0.3, 0.2):
        free = command_speed(top, other, governor=0.0)
        governed = command_speed(top, other, governor=0.8)
        assert free == pytest.approx(top, rel=0.05)
        fractions.append(governed / free)
    assert fractions[0] == pytest.approx(fractions[1], rel=1e-12)
    assert fractions[0] == pytest.approx(min(1.0, gap / 0.8), rel=1e-9)


def test_a_robot_behind_is_ignored_and_a_clear_path_is_full_speed() -> None:
    behind = command_speed(0.3, (1.3, 2.3), governor=0.8)
    far = command_speed(0.3, (5.0, 7.0), governor=0.8)
    assert behind == pytest.approx(command_speed(0.3, (1.3, 2.3), governor=0.0))
    assert far == pytest.approx(command_speed(0.3, (5.0, 7.0), governor=0.0))


def test_off_by_default_and_bounded_by_what_a_robot_senses() -> None:
    assert tavc_env.preset("dahl2004").clearance_governor_m == 0.0
    tavc_env.make_config("dahl2004", sensing_range_m=1.5, clearance_governor_m=1.06)
    for bad in (-0.1, 1.2, math.nan, "0.5"):
        # on its own (a number >= 0), or with the fields it relates to (within the range sensed)
        named = r"^clearance_governor_m(, sensing_range_m, robot_radius)? = "
        with pytest.raises(ValueError, match=named + r".* is invalid; allowed: 0"):
            tavc_env.make_config("dahl2004", sensing_range_m=1.5, clearance_governor_m=bad)


def test_a_governed_arena_runs_slower_but_delivers() -> None:
    deliveries = []
    for governor in (0.0, 0.5):
        env = tavc_env.parallel_env(
            clearance_governor_m=governor, max_sim_time_s=1800.0, max_cycles=10**9
        )
        _, infos = env.reset(seed=0)
        rng = np.random.default_rng(0)
        done = 0
        while env.agents:
            actions = {a: int(rng.integers(2)) for a in env.agents if infos[a]["action_required"]}
            _, rewards, _, _, infos = env.step(actions)
            done += sum(1 for r in rewards.values() if r > 0)
        deliveries.append(done)
    assert 0 < deliveries[1] < deliveries[0]
