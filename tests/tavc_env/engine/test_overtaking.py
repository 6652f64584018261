"""Overtaking (`ArenaConfig.overtaking`, tavc_env.engine.navigation): the governor reacts to what
blocks the robot's own path, not to a robot it passes alongside; a robot dead ahead is passed on the
side the walls leave room on; and with stations of two bays a fast robot keeps its pace beside a
slow one (rho well above 1), which one-robot docks without overtaking never allow."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tavc_env
from tavc_env.engine.navigation import steer_all
from tavc_env.engine.simulation import Simulation


def command(
    other_at: tuple[float, float],
    *,
    governor: float,
    overtaking: bool,
    start: tuple[float, float] = (2.0, 2.0),
    target: tuple[float, float] = (6.0, 2.0),
) -> tuple[float, float]:
    """(speed, new heading) commanded to a robot at `start` heading +x toward `target`, another
    robot holding still at `other_at`."""
    pos = np.array([list(start), list(other_at)])
    heading = np.zeros(2)
    velocity = np.zeros((2, 2))
    steer_all(
        pos,
        heading,
        np.array([list(target), list(other_at)]),
        np.array([True, False]),
        np.array([0.3, 0.3]),
        np.array([True, True]),
        0.22,  # radius
        3.0,  # sensing
        governor,
        overtaking,
        1.75 * 0.1,  # turn step
        12.0,
        8.0,
        velocity,
        heading,
    )
    return float(math.hypot(*velocity[0])), float(heading[0])


def test_a_robot_alongside_governs_only_without_overtaking() -> None:
    alongside = (2.3, 2.7)  # ahead of the robot's centre, beside its path (lateral 0.7 m)
    free, _ = command(alongside, governor=0.0, overtaking=False)
    passing, _ = command(alongside, governor=2.56, overtaking=True)
    braked, _ = command(alongside, governor=2.56, overtaking=False)
    assert passing == pytest.approx(free, rel=1e-12)
    assert braked < 0.5 * free


def test_a_robot_in_the_path_still_governs_with_overtaking() -> None:
    in_path = (3.2, 2.1)
    governed, _ = command(in_path, governor=2.56, overtaking=True)
    ungoverned, _ = command(in_path, governor=0.0, overtaking=True)
    assert governed < 0.6 * ungoverned


def test_dead_ahead_is_passed_on_the_side_with_room() -> None:
    # heading +x with the wall y = 0 close on the right: the right side has no room to pass
    by_wall = {"start": (2.0, 0.5), "target": (6.0, 0.5)}
    _, keeps_right = command((2.8, 0.5), governor=0.0, overtaking=False, **by_wall)
    _, picks_left = command((2.8, 0.5), governor=0.0, overtaking=True, **by_wall)
    assert keeps_right < 0.0 < picks_left  # heading turns right (clockwise) vs left
    # in open floor both pass on the right, as robots meeting head-on do
    _, open_floor = command(
        (2.8, 4.0), governor=0.0, overtaking=True, start=(2.0, 4.0), target=(6.0, 4.0)
    )
    assert open_floor < 0.0


def pair_task_times(config: tavc_env.ArenaConfig, hours: float = 1.0) -> dict[str, float]:
    """Mean task time of robot 0 (fast) and robot 1 (slow), both serving circuit 0 for `hours`
    (tasks decided after 10 minutes), robots 2.. on circuit 1."""
    config = config.replace(
        robots=(tavc_env.Robot(0.30, "fast"), tavc_env.Robot(0.20, "slow"))
        + (tavc_env.Robot(0.25, "medium"),) * 2
    )
    circuit_of = (0, 0, 1, 1)
    sim = Simulation(config)
    sim.reset(np.random.default_rng(0))
    for robot, circuit in enumerate(circuit_of):
        sim.choose(robot, circuit)
    times: dict[int, list[float]] = {0: [], 1: []}
    decided = {robot: 0.0 for robot in range(4)}
    while sim.time_s < hours * 3600:
        for c in sim.advance(600.0).completions:
            if c.robot in times and decided[c.robot] >= 600.0:
                times[c.robot].append(c.task_time_s)
            decided[c.robot] = sim.time_s
            sim.choose(c.robot, circuit_of[c.robot])
    return {"fast": float(np.mean(times[0])), "slow": float(np.mean(times[1]))}


def test_two_bays_and_overtaking_let_a_fast_robot_keep_its_pace() -> None:
    governed = {"clearance_governor_m": 2.56, "sensing_range_m": 3.0}
    held = pair_task_times(tavc_env.make_config("dahl2004"))
    free = pair_task_times(
        tavc_env.make_config("dahl2004", **governed, station_bays=2, overtaking=True)
    )
    assert held["slow"] / held["fast"] < 1.05  # one-robot docks: the fast robot waits behind
    assert free["slow"] / free["fast"] > 1.15


def test_overtaking_is_off_by_default_and_a_boolean() -> None:
    with_it = [name for name in tavc_env.PRESETS if tavc_env.preset(name).overtaking]
    assert with_it == ["dahl2004_passing"]
    with pytest.raises(ValueError, match=r"^overtaking = 1 is invalid; allowed: True or False"):
        tavc_env.make_config("dahl2004", overtaking=1)
