"""Measuring the engine: the spacing between robots tick by tick, and the speed of the env and of
the bare physics.

The runs with fixed allocations and the mode counter (`FixedAllocation`, `run_fixed`, `ModeTicks`,
...) live in `tavc_env.measurement` (the model twin's tables are measured with them); they are
importable from here too.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

import tavc_env
from tavc_env.config import ArenaConfig
from tavc_env.engine.simulation import EngineEvent, Simulation
from tavc_env.engine.world import World
from tavc_env.measurement import CountedTask as CountedTask
from tavc_env.measurement import FixedAllocation as FixedAllocation
from tavc_env.measurement import FixedRun as FixedRun
from tavc_env.measurement import ModeTicks as ModeTicks
from tavc_env.measurement import run_fixed as run_fixed
from tavc_env.measurement import two_circuit_allocation as two_circuit_allocation


class SpacingMonitor:
    """The closest approach of two robots (centre to centre) and of a robot to a wall, and the
    ticks with two robots more than 1 cm into each other, sampled after every physics tick."""

    def __init__(self, config: ArenaConfig) -> None:
        self.radius = config.robot_radius
        self.width = config.width
        self.height = config.height
        self.dt = config.dt
        self.iu = np.triu_indices(config.n_robots, 1)
        self.ticks = 0
        self.min_dist = math.inf
        self.min_dist_at: dict[str, Any] = {}
        self.min_wall = math.inf
        self.min_wall_at: dict[str, Any] = {}
        self.overlap_ticks = 0

    def on_tick(self, sim: Simulation, events: list[EngineEvent]) -> None:
        self.ticks += 1
        present = ~sim.broken()
        pos = sim.positions_view
        d = pos[:, None, :] - pos[None, :, :]
        dist = np.hypot(d[..., 0], d[..., 1])[self.iu]
        both = (present[:, None] & present[None, :])[self.iu]
        dist = np.where(both, dist, np.inf)
        k = int(np.argmin(dist))
        dmin = float(dist[k])
        if dmin < 2 * self.radius - 0.01:
            self.overlap_ticks += 1
        if dmin < self.min_dist:
            self.min_dist = dmin
            i, j = int(self.iu[0][k]), int(self.iu[1][k])
            self.min_dist_at = {
                "time_s": round(self.ticks * self.dt, 1),
                "pair": (i, j),
                "where": tuple(round(v, 2) for v in (pos[i] + pos[j]) / 2),
            }
        x, y = pos[present, 0], pos[present, 1]
        clear = np.minimum(np.minimum(x, self.width - x), np.minimum(y, self.height - y))
        c = float(clear.min()) - self.radius if clear.size else math.inf
        if c < self.min_wall:
            self.min_wall = c
            self.min_wall_at = {"time_s": round(self.ticks * self.dt, 1)}


# -- speed --------------------------------------------------------------------------------------
# Speeds are measured in CPU seconds of the measuring process (`time.process_time`): on a shared
# machine wall time also counts the other processes' turns.


def random_choice_run(
    config: ArenaConfig,
    seed: int,
    sim_s: float,
    decision_interval_s: float | None = None,
    record: bool = False,
) -> dict[str, Any]:
    """Time `sim_s` simulated seconds of the PettingZoo parallel env (event-driven stepping, or
    every `decision_interval_s`), every robot that must decide picking a circuit uniformly at
    random (numpy Generator seeded [seed, 1]): CPU and wall seconds, simulated seconds, physics
    ticks and decisions. With `record`, also the run's physics (untimed: an observer reads every
    tick): `start` (positions after reset), `commands` (ticks, n, 2: every tick's velocity
    commands) and `end` (positions at the end), for `physics_replay`."""
    env = tavc_env.parallel_env(
        config=config,
        max_sim_time_s=sim_s,
        max_cycles=10**9,
        decision_interval_s=decision_interval_s,
    )
    m = config.n_circuits
    rng = np.random.default_rng([seed, 1])
    _, infos = env.reset(seed=seed)
    recorder = _CommandRecorder(env.sim) if record else None
    decisions = 0
    cpu0, wall0 = time.process_time(), time.perf_counter()
    while env.agents:
        actions = {a: int(rng.integers(m)) for a in env.agents if infos[a]["action_required"]}
        decisions += len(actions)
        _, _, _, _, infos = env.step(actions)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    found: dict[str, Any] = {
        "cpu_s": cpu,
        "wall_s": wall,
        "sim_s": env.sim_time_s,
        "ticks": env.sim.ticks,
        "decisions": decisions,
    }
    if recorder is not None:
        found.update(recorder.recording(env.sim))
    return found


class _CommandRecorder:
    """Every tick's velocity commands of a simulation (an observer: it changes nothing)."""

    def __init__(self, sim: Simulation) -> None:
        self.start = sim.positions()
        self.commands: list[np.ndarray] = []
        sim.add_observer(self)

    def on_tick(self, sim: Simulation, events: list[EngineEvent]) -> None:
        if not sim.world.in_space.all():
            raise ValueError("a replay of the physics needs every robot on the floor throughout")
        self.commands.append(sim.world.velocity_out.copy())

    def recording(self, sim: Simulation) -> dict[str, np.ndarray]:
        sim.remove_observer(self)
        commands = np.array(self.commands).reshape(-1, sim.config.n_robots, 2)
        return {"start": self.start, "commands": commands, "end": sim.positions()}


def _bare_world(config: ArenaConfig, start: np.ndarray) -> World:
    """The engine's `World` (same space, walls, bodies, solver settings) with its robots at
    `start`, as a reset leaves them."""
    world = World(config)
    world.place(start)
    return world


def physics_replay(config: ArenaConfig, recorded: dict[str, Any]) -> dict[str, Any]:
    """Time the env's own physics without the env: the velocity commands of a recorded run
    (`random_choice_run(..., record=True)`) set tick after tick on a bare `World` placed where the
    run began (pymunk's batch velocity write, the cheapest pymunk offers, and `space.step`).
    `exact`: the replay ended exactly where the run ended."""
    world = _bare_world(config, recorded["start"])
    commands = recorded["commands"]
    space, dt = world.space, config.dt
    cpu0, wall0 = time.process_time(), time.perf_counter()
    for velocity in commands:
        world.set_velocities(velocity)
        space.step(dt)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    ticks = len(commands)
    exact = bool(np.array_equal(world.positions(), recorded["end"]))
    return {"cpu_s": cpu, "wall_s": wall, "sim_s": ticks * dt, "ticks": ticks, "exact": exact}


def physics_floor(config: ArenaConfig, seed: int, ticks: int, each_tick: bool) -> dict[str, float]:
    """Time the bare-physics floor: the engine's `World` (same space, walls, bodies, solver
    settings) placed as at reset, each robot's velocity set to its top speed in a random
    direction, then `ticks` pymunk steps (with the velocities set again every tick if
    `each_tick`)."""
    sim = Simulation(config)
    sim.reset(np.random.default_rng(seed))  # robots at the sinks, as at the start of a trial
    world = _bare_world(config, sim.positions())
    rng = np.random.default_rng([seed, 2])
    angle = rng.uniform(-math.pi, math.pi, config.n_robots)
    speed = np.array([r.speed for r in config.robots])
    velocity = np.stack([speed * np.cos(angle), speed * np.sin(angle)], axis=1)
    world.set_velocities(velocity)
    space, dt = world.space, config.dt
    cpu0, wall0 = time.process_time(), time.perf_counter()
    if each_tick:
        for _ in range(ticks):
            world.set_velocities(velocity)
            space.step(dt)
    else:
        for _ in range(ticks):
            space.step(dt)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    return {"cpu_s": cpu, "wall_s": wall, "sim_s": ticks * dt, "ticks": ticks, "decisions": 0}


TEAM_SIZES = {6: None, 24: 8, 96: 32, 384: 128}
"""The team sizes the throughput benchmarks time: robots -> lanes of `tavc_env.scaled_config`
(None: the `dahl2004` preset)."""


def team_config(robots: int, dt: float | None = None) -> ArenaConfig:
    """`dahl2004` for 6 robots, `scaled_config(lanes, 3)` for more (`TEAM_SIZES`); with step `dt`
    if given."""
    if robots not in TEAM_SIZES:
        raise ValueError(f"robots = {robots!r} is invalid; allowed: one of {list(TEAM_SIZES)}")
    lanes = TEAM_SIZES[robots]
    config = tavc_env.make_config("dahl2004") if lanes is None else tavc_env.scaled_config(lanes, 3)
    return config if dt is None else config.replace(dt=dt)
