"""Measuring the physics engine: runs with fixed allocations, an observer that counts the ticks
each robot spends in each mode of its task (`ModeTicks`, by `Mode`), one that watches the spacing
between robots (`SpacingMonitor`), and the bare-physics yardsticks of the engine's speed
(`CommandRecorder`, `compiled_floor`, `physics_replay`, `physics_floor`), the compiled tick loop's
own share of a run (`compiled_loop_timer`; the env's own speed is timed by
`benchmarks/arena_runs.py`).

Observers attach with `Simulation.add_observer` and only read the simulation's public views, so a
measured run follows exactly the trajectory of an unmeasured one. What the runs measure feeds the
interference studies and the model twin's tables (`tavc_env.twin.measure`).

    run = run_fixed(FixedAllocation(preset="dahl2004_homogeneous", circuit_of=(0, 0, 0, 1, 1, 1),
                                    seed=0, hours=1.0, warmup_s=600.0, skip_first=2))
    run.tasks      # every counted task: robot, class, circuit, task time, when decided, own/switch
    run.mode_ticks # ticks per robot and Mode within the measured window
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from tavc_env.config import JAM_WINDOW_S as JAM_WINDOW_S
from tavc_env.config import ArenaConfig, make_config
from tavc_env.engine import simulation as _simulation

# Public here, for what measures the engine from outside it: the modes ModeTicks counts, the task
# phases, the jam detector's and the stuck escape's thresholds, and whether the compiled controller
# is cached (a first run compiles it)
from tavc_env.engine.navigation import STUCK_PATIENCE_S as STUCK_PATIENCE_S
from tavc_env.engine.navigation import compiled_cache_ready as compiled_cache_ready
from tavc_env.engine.navigation import replay_commands, tick_loop
from tavc_env.engine.simulation import JAM_MOTION_M as JAM_MOTION_M
from tavc_env.engine.simulation import EngineEvent, Simulation
from tavc_env.engine.tasks import PHASE_NAMES as PHASE_NAMES
from tavc_env.engine.tasks import Mode as Mode
from tavc_env.engine.tasks import Phase as Phase
from tavc_env.engine.world import World

_EPS = 1e-9


class ModeTicks:
    """Per robot, the physics ticks spent in each `Mode` (idle, travel, queued, docking, service)
    among the ticks that began at a time in [start_s, end_s).

    A tick counts in the mode the robot moved in during it: its mode at the end of the previous
    tick, or travel if it started a task (`Simulation.choose`) between the two ticks. Create the
    counter when the robots' modes are those they move in next (after the decisions of that
    moment) and attach it with `sim.add_observer`."""

    def __init__(self, sim: Simulation, start_s: float, end_s: float) -> None:
        self.start_s = start_s
        self.end_s = end_s
        self.counts = np.zeros((sim.config.n_robots, len(Mode)))
        self._rows = np.arange(sim.config.n_robots)
        self._modes = sim.modes.copy()
        self._time_s = sim.time_s
        self._first = True

    def on_tick(self, sim: Simulation, events: list[EngineEvent]) -> None:
        began = self._time_s
        if self.start_s <= began < self.end_s:
            modes = self._modes
            if not self._first:
                started = sim.tasks.decision_time == began  # chose a task as this tick began
                modes = np.where(started, int(Mode.TRAVEL), modes)
            self.counts[self._rows, modes] += 1
        self._first = False
        self._modes = sim.modes.copy()
        self._time_s = sim.time_s


@dataclass(frozen=True, kw_only=True)
class FixedAllocation:
    """A run of the bare engine in which each robot serves the circuit it is given, task after
    task; the `switcher` (if >= 0) alternates circuits every `switch_every` tasks.

    A task counts if it was decided at or after `warmup_s` and is not among the robot's first
    `skip_first`; tasks decided up to the end (`hours`) count and are run to completion."""

    preset: str
    circuit_of: tuple[int, ...]
    """each robot's circuit (the switcher's first one)"""
    seed: int
    hours: float
    warmup_s: float
    skip_first: int
    switcher: int = -1
    switch_every: int = 3
    speeds: tuple[float, ...] | None = None
    """the robots' top speeds, if not the preset's"""
    arena: tuple[tuple[str, Any], ...] = ()
    """arena overrides (KEY, VALUE)"""

    def config(self) -> ArenaConfig:
        overrides: dict[str, Any] = dict(self.arena)
        if self.speeds is not None:
            overrides["speeds"] = list(self.speeds)
        config = make_config(self.preset, **overrides)
        if len(self.circuit_of) != config.n_robots:
            raise ValueError(
                f"circuit_of = {self.circuit_of!r} is invalid; allowed: one circuit for each of "
                f"the {config.n_robots} robots"
            )
        return config


class CountedTask(NamedTuple):
    """A task of the measured window: `kind` is "switch" if it started at the other circuit's
    sink (the switcher changed circuits), "own" otherwise."""

    robot: int
    robot_class: str
    circuit: int
    task_time_s: float
    decided_s: float
    kind: str


@dataclass
class FixedRun:
    """What a `FixedAllocation` run measured."""

    allocation: FixedAllocation
    classes: list[str]
    """each robot's speed class"""
    tasks: list[CountedTask]
    mode_ticks: np.ndarray
    """(robots, len(Mode)): ticks per mode within the measured window"""
    wall_s: float


def two_circuit_allocation(on_first: int, robots: int = 6) -> tuple[int, ...]:
    """`on_first` robots (the lowest indices) on circuit 0, the rest on circuit 1."""
    return tuple([0] * on_first + [1] * (robots - on_first))


class _Plan:
    """Who serves what next, and the task each robot has in progress: (decided at, kind,
    ordinal), or None for a task decided after the end of the run."""

    def __init__(self, sim: Simulation, alloc: FixedAllocation) -> None:
        n = len(alloc.circuit_of)
        self.sim = sim
        self.alloc = alloc
        self.end_s = alloc.hours * 3600.0
        self.current = list(alloc.circuit_of)
        self.block = [0] * n  # tasks chosen in the switcher's current block
        self.ordinal = [0] * n  # tasks chosen so far per robot
        self.pending: list[tuple[float, str, int] | None] = [None] * n

    def decide(self, i: int) -> None:
        alloc, sim = self.alloc, self.sim
        if i == alloc.switcher:
            if self.block[i] == alloc.switch_every:
                self.current[i] = 1 - self.current[i]
                self.block[i] = 0
            self.block[i] += 1
        c = self.current[i]
        kind = "switch" if c != int(sim.circuits[i]) else "own"
        now = sim.time_s
        self.pending[i] = (now, kind, self.ordinal[i]) if now <= self.end_s + _EPS else None
        self.ordinal[i] += 1
        sim.choose(i, c)

    def counts(self, i: int) -> tuple[float, str] | None:
        """The task robot i just completed, (decided at, kind), if it counts."""
        p = self.pending[i]
        alloc = self.alloc
        if p is not None and p[0] >= alloc.warmup_s - _EPS and p[2] >= alloc.skip_first:
            return p[0], p[1]
        return None

    def busy(self) -> bool:
        return any(p is not None for p in self.pending)


def run_fixed(alloc: FixedAllocation) -> FixedRun:
    """Run `alloc` (see `FixedAllocation`): every counted task, and the ticks each robot spent in
    each mode within the window [warmup, end)."""
    config = alloc.config()
    classes = [r.speed_class for r in config.robots]
    sim = Simulation(config)
    sim.reset(np.random.default_rng(alloc.seed))
    plan = _Plan(sim, alloc)
    wall0 = time.perf_counter()
    for i in range(config.n_robots):
        plan.decide(i)
    mode_ticks = ModeTicks(sim, alloc.warmup_s, plan.end_s)
    sim.add_observer(mode_ticks)
    tasks: list[CountedTask] = []
    while sim.time_s < plan.end_s or plan.busy():
        out = sim.advance(600.0)
        for comp in out.completions:
            i = comp.robot
            counted = plan.counts(i)
            if counted is not None:
                decided, kind = counted
                tasks.append(
                    CountedTask(i, classes[i], comp.circuit, comp.task_time_s, decided, kind)
                )
            plan.pending[i] = None
            plan.decide(i)
        if sim.time_s > plan.end_s + 3600.0:
            raise RuntimeError(f"{alloc}: tasks still pending an hour after the end of the run")
    return FixedRun(alloc, classes, tasks, mode_ticks.counts, time.perf_counter() - wall0)


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


# -- the engine's speed ----------------------------------------------------------------------------
# Speeds are measured in CPU seconds of the measuring process (`time.process_time`): on a shared
# machine wall time also counts the other processes' turns.


class CommandRecorder:
    """Every tick's velocity commands of a simulation (an observer: it changes nothing), for
    `physics_replay`: attach it to a run's `Simulation`, run, then take `recording(sim)`."""

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


def bare_world(config: ArenaConfig, start: np.ndarray) -> World:
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
    world = bare_world(config, recorded["start"])
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


def compiled_floor(config: ArenaConfig, recorded: dict[str, Any]) -> dict[str, Any]:
    """The compiled physics floor: the velocity commands of a recorded run
    (`random_choice_run(..., record=True)`) replayed on a bare `World` placed where the run
    began, in a compiled loop through the very Chipmunk calls the env's compiled tick makes
    (batch velocity write, `cpSpaceStep`, batch position read: `navigation.replay_commands`), with
    no Python per tick. What the env's physics costs with nothing around it: the env can only
    approach it. `exact`: the replay ended exactly where the run ended."""
    world = bare_world(config, recorded["start"])
    commands = np.ascontiguousarray(recorded["commands"], dtype=np.float64)
    if not world.scatter().in_order:
        raise ValueError("the compiled floor needs the robots in the space in index order")
    velocities_in = world.scatter().velocities_in
    replay_commands(world.c_calls, commands[:1], velocities_in, 0.0)  # compiled, untimed
    world = bare_world(config, recorded["start"])  # anew: a step of 0 s is still a step
    velocities_in = world.scatter().velocities_in
    cpu0, wall0 = time.process_time(), time.perf_counter()
    replay_commands(world.c_calls, commands, velocities_in, config.dt)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    ticks = len(commands)
    exact = bool(np.array_equal(world.positions(), recorded["end"]))
    return {
        "cpu_s": cpu,
        "wall_s": wall,
        "sim_s": ticks * config.dt,
        "ticks": ticks,
        "exact": exact,
    }


def physics_floor(config: ArenaConfig, seed: int, ticks: int, each_tick: bool) -> dict[str, float]:
    """Time the bare-physics floor: the engine's `World` (same space, walls, bodies, solver
    settings) placed as at reset, each robot's velocity set to its top speed in a random
    direction, then `ticks` pymunk steps (with the velocities set again every tick if
    `each_tick`)."""
    sim = Simulation(config)
    sim.reset(np.random.default_rng(seed))  # robots at the sinks, as at the start of a trial
    world = bare_world(config, sim.positions())
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


@contextmanager
def compiled_loop_timer() -> Iterator[list[float]]:
    """While the block runs, time every call of every arena into the compiled tick loop
    (`run_ticks`: physics, controller, task rules, called as the engine calls it: through
    `navigation.tick_loop`): yields a one-item list holding the CPU seconds
    (`time.process_time`) spent inside the loop so far. The loop's own cost beside a whole run's,
    so its ceiling (`benchmarks/throughput.py`); the trajectory is unchanged. In this process and
    thread only (the block replaces the engine's reference to `tick_loop`; arenas bound before
    it are not timed)."""
    from unittest import mock  # (a measuring tool: not loaded with the package)

    spent = [0.0]

    def timed_loop(bound: tuple[object, ...]) -> Any:
        call = tick_loop(bound)

        def timed(*scalars: Any) -> Any:
            start = time.process_time()
            try:
                return call(*scalars)
            finally:
                spent[0] += time.process_time() - start

        return timed

    with mock.patch.object(_simulation, "tick_loop", timed_loop):
        yield spent
