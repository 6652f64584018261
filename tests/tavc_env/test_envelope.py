"""The physics envelope (issue 12, item 4): the configuration refuses what the physics cannot do,
naming the bound it crossed, and inside the envelope a crowded arena runs without robots
interpenetrating beyond a small tolerance.

* Speed x step against the radius: a robot that moves more than `MAX_STEP_OVER_RADIUS` radii per
  physics step drives into its neighbours before pymunk pushes them apart (at 2 radii per step it
  drives through them). The bound comes from the measurement in `tavc_env/config.py`; re-measure
  with `python -m tests.tavc_env.test_envelope` (about 10 minutes on one core).
* Sensing range against the body: at `sensing_range_m == 2 * robot_radius` the avoidance weight of
  `navigation._steer_one` divides by zero (a ZeroDivisionError mid-run); it must be at least
  `MIN_SENSING_OVER_RADIUS` radii.
* Arena size: the neighbour grid used to allocate every cell of the arena each tick (MemoryError
  in a 1e5 m arena with 24 robots); it is sparse now, and sides are bounded by what a float
  resolves (`MAX_ARENA_SIDE_M`).
"""

from __future__ import annotations

import re
import sys
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_env.config import (
    MAX_ARENA_SIDE_M,
    MAX_STEP_OVER_RADIUS,
    MIN_SENSING_OVER_RADIUS,
    OVERLAP_TOLERANCE,
)
from tavc_env.engine.navigation import steer_all
from tavc_env.engine.simulation import EngineEvent, Simulation
from tavc_env.engine.world import WALL_THICKNESS_M


class DeepestOverlap:
    """Observer: the deepest overlap (m) of two robots, or of a robot and a wall, over a run."""

    def __init__(self, config: tavc_env.ArenaConfig) -> None:
        self.r, self.w, self.h = config.robot_radius, config.width, config.height
        self.deepest = 0.0

    def on_tick(self, sim: Simulation, events: list[EngineEvent]) -> None:
        p = sim.positions_view[sim.world.in_space]
        gaps = np.sqrt(((p[:, None, :] - p[None, :, :]) ** 2).sum(-1))
        np.fill_diagonal(gaps, np.inf)
        wall = self.r + WALL_THICKNESS_M
        self.deepest = max(
            self.deepest,
            2 * self.r - float(gaps.min()),
            wall - float(p.min()),
            float(p[:, 0].max()) - (self.w - wall),
            float(p[:, 1].max()) - (self.h - wall),
        )


def deepest_overlap(config: tavc_env.ArenaConfig, seconds: float, seed: int = 0) -> float:
    """Run `config` for `seconds` with random circuit choices; the deepest overlap in radii."""
    env = tavc_env.parallel_env(config=config, max_sim_time_s=seconds)
    env.reset(seed=seed)
    probe = DeepestOverlap(config)
    env.sim.add_observer(probe)
    rng = np.random.default_rng(seed)
    while env.agents:
        actions = {a: int(rng.integers(config.n_circuits)) for a in env.agents}
        env.step(actions)
    return probe.deepest / config.robot_radius


def crowd_robots(ratio: float, n: int, radius: float, dt: float) -> tuple[tavc_env.Robot, ...]:
    """`n` robots, fast and slow in turn, the fast ones moving `ratio` radii per physics step
    (nominal speed; the speed noise adds up to 50 % on a leg)."""
    fast = ratio * radius / dt
    return tavc_env.robots_from_speeds([fast, fast * 2 / 3] * (n // 2))


def crowd(
    ratio: float, n: int = 24, radius: float = 0.22, dt: float = 0.1, **kw: Any
) -> tavc_env.ArenaConfig:
    """dahl2004's lanes in an arena 12 m tall (the least whose waiting lines hold 24 robots) with
    `crowd_robots`; above the envelope's bound, built with the robots of a valid ratio and then
    given the fast ones without validation (to show what it prevents)."""
    robots = crowd_robots(ratio, n, radius, dt)
    if ratio <= MAX_STEP_OVER_RADIUS:
        lanes = tavc_env.lane_circuits(2, height=12.0, values=(2200.0, 2000.0))
        return tavc_env.make_config(
            robots=robots, dt=dt, robot_radius=radius, height=12.0, circuits=lanes, **kw
        )
    config = crowd(MAX_STEP_OVER_RADIUS, n, radius, dt, **kw)
    object.__setattr__(config, "robots", robots)
    return config


# -- speed x dt against the radius -------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "top"),
    [
        ({"dt": 0.5}, 0.3),  # dahl2004 at dt 0.5: 0.68 radii per step
        ({"speeds": [2.0] * 6}, 2.0),  # 0.91 radii per step
        ({"speeds": [0.3] * 6, "robot_radius": 0.08, "dt": 0.1}, 0.3),  # small robots: 0.375
    ],
)
def test_a_step_longer_than_the_envelope_is_refused_with_the_bound(
    kwargs: dict[str, Any], top: float
) -> None:
    """Used to be accepted: with 2 m/s robots at dt 0.1 crowded robots overlapped by 0.3 radii."""
    radius = kwargs.get("robot_radius", 0.22)
    longest = MAX_STEP_OVER_RADIUS * radius / top
    dt = kwargs.get("dt", 0.1)
    pattern = (
        rf"^dt, robot_radius, robots\[\d+\]\.speed = {re.escape(repr(dt))}, "
        rf"{re.escape(repr(radius))}, {re.escape(repr(top))} is invalid; allowed: a physics step "
        "of at most "
        rf"{MAX_STEP_OVER_RADIUS:g} x robot_radius / the top speed = {longest:.4g} s"
    )
    with pytest.raises(ValueError, match=pattern) as error:
        tavc_env.parallel_env(**kwargs)
    assert "interpenetrate" in str(error.value)


def test_the_shipped_presets_and_steps_of_the_dt_study_are_inside_the_envelope() -> None:
    for name in tavc_env.PRESETS:
        config = tavc_env.preset(name)
        top = max(r.speed for r in config.robots)
        assert top * config.dt / config.robot_radius < MAX_STEP_OVER_RADIUS / 2
    for dt in (0.05, 0.1, 0.2, 0.25):  # benchmarks/dt_fidelity.py
        tavc_env.make_config("dahl2004", dt=dt)


def test_at_the_bound_a_crowded_arena_stays_within_the_overlap_tolerance() -> None:
    """24 robots on two circuits at the largest step the envelope allows, speed noise 0.3."""
    config = crowd(MAX_STEP_OVER_RADIUS, speed_noise=0.3)
    assert config.max_time_s > 600.0
    assert deepest_overlap(config, 600.0) <= OVERLAP_TOLERANCE


def test_past_the_bound_robots_interpenetrate() -> None:
    """Why the bound exists: the same crowd at 0.9 radii per step (validation bypassed)."""
    assert deepest_overlap(crowd(0.9, speed_noise=0.3), 300.0) > 2 * OVERLAP_TOLERANCE


# -- sensing range against the body ------------------------------------------------------------


@pytest.mark.parametrize("factor", [1.0, 2.0, 2.2, 2.49])
def test_a_sensing_range_not_beyond_contact_is_refused(factor: float) -> None:
    """`sensing_range_m == 2 * robot_radius` used to be accepted and divided by zero mid-run."""
    value = factor * 0.22
    pattern = (
        rf"^sensing_range_m, robot_radius = {re.escape(repr(value))}, 0\.22 is invalid; "
        "allowed: a range of at least "
        rf"{MIN_SENSING_OVER_RADIUS:g} x robot_radius = 0\.55 m"
    )
    with pytest.raises(ValueError, match=pattern):
        tavc_env.parallel_env(sensing_range_m=value)


def test_the_smallest_sensing_range_allowed_runs() -> None:
    env = tavc_env.parallel_env(sensing_range_m=MIN_SENSING_OVER_RADIUS * 0.22)
    obs, _ = env.reset(seed=0)
    for _ in range(10):
        obs, *_ = env.step(dict.fromkeys(obs, 0))


def test_where_a_sensing_range_of_two_radii_divided_by_zero() -> None:
    """`navigation._steer_one`: w = (sensing - dist) / (sensing - contact) for a robot ahead,
    closer than the sensing range: two robots a hair into contact, sensing == 2 radii."""
    pos = np.array([[1.0, 1.0], [1.43, 1.0]])
    args = (
        pos,
        np.zeros(2),
        np.array([[3.0, 1.0], [5.0, 1.0]]),
        np.ones(2, bool),
        np.full(2, 0.3),
        np.ones(2, bool),
        0.22,
    )
    out = (12.0, 8.0, np.zeros((2, 2)), np.zeros(2))
    with pytest.raises(ZeroDivisionError):
        steer_all(*args, 0.44, 0.0, False, 0.175, *out)
    steer_all(*args, MIN_SENSING_OVER_RADIUS * 0.22, 0.0, False, 0.175, *out)


# -- arena size --------------------------------------------------------------------------------


def test_a_huge_arena_with_a_large_team_runs() -> None:
    """A 1e5 m arena with 24 robots died with MemoryError: the neighbour grid allocated all
    ~1e10 of its cells every tick. The grid is sparse now."""
    env = tavc_env.parallel_env(
        width=1e5,
        height=1e5,
        circuits=tavc_env.lane_circuits(2, width=1e5, height=1e5),
        speeds=[0.3, 0.2] * 12,
    )
    assert env.sim._grid_cell > 0  # 24 robots: the grid is in use
    obs, _ = env.reset(seed=0)
    for _ in range(3):
        obs, *_ = env.step(dict.fromkeys(obs, 0))
    assert env.sim.time_s > 0


@pytest.mark.parametrize("name", ["width", "height"])
def test_an_arena_side_beyond_what_a_float_resolves_is_refused(name: str) -> None:
    value = 10 * MAX_ARENA_SIDE_M
    pattern = rf"^{name} = {re.escape(repr(value))} is invalid; allowed: a side of at most 1e\+06 m"
    with pytest.raises(ValueError, match=pattern):
        tavc_env.parallel_env(**{name: value})


# -- the measurement ---------------------------------------------------------------------------

MEASURED_CASES = ((0.22, 0.1), (0.22, 0.2), (0.22, 0.25), (0.1, 0.05))  # (radius m, dt s)
MEASURED_RATIOS = (0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5)


def measure(seconds: float = 900.0, seeds: int = 1) -> None:
    """Print the deepest overlap against max speed x dt / radius (validation bypassed above the
    bound), for the comment in `tavc_env/config.py`."""
    for radius, dt in MEASURED_CASES:
        for ratio in MEASURED_RATIOS:
            worst = 0.0
            for n in (6, 16, 24):
                for noise in (0.1, 0.3):
                    config = crowd(ratio, n, radius, dt, speed_noise=noise)
                    for seed in range(seeds):
                        worst = max(worst, deepest_overlap(config, seconds, seed))
            print(f"radius {radius} m, dt {dt} s, ratio {ratio}: deepest overlap {worst:.3f} r")
            sys.stdout.flush()


if __name__ == "__main__":
    measure()
