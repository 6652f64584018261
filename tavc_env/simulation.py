"""The arena engine: physics world + navigation + task cycle, advanced tick by tick.

This is the one engine every adapter (the PettingZoo env, benchmarks, renderers) drives. It knows
circuits, tasks and time; it knows nothing of observations, rewards or agents' names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tavc_env.config import ArenaConfig
from tavc_env.navigation import (
    ESCAPE_DISTANCE_M,
    ESCAPE_TIME_S,
    GRID_MIN_ROBOTS,
    STUCK_PATIENCE_S,
    Navigator,
    after_step,
    neighbour_cell_m,
    steer_all,
    steer_all_grid,
    stuck,
)
from tavc_env.tasks import Completion, Mode, Phase, TaskCycle
from tavc_env.world import World


@dataclass
class Advance:
    """What happened during one call to `Simulation.advance`."""

    completions: list[Completion] = field(default_factory=list)
    repaired: list[int] = field(default_factory=list)
    broken: list[int] = field(default_factory=list)
    duration_s: float = 0.0


class Simulation:
    """One arena in motion. Call `reset(rng)` before use; `rng` drives every random draw."""

    def __init__(self, config: ArenaConfig) -> None:
        self.config = config
        self.world = World(config)
        self.nav = Navigator(config)
        self.tasks = TaskCycle(config)
        n = config.n_robots
        self.speeds = np.array([r.speed for r in config.robots], dtype=float)
        self.speed_factor = np.ones(n)
        self.top_speed = self.speeds.copy()  # speeds * speed_factor, updated at each new leg
        self.heading = np.zeros(n)
        self._pos = np.zeros((n, 2))  # positions after the last physics step
        self._hits = np.zeros(n, dtype=np.int64)
        self._stalled = np.zeros(n, dtype=np.int64)
        self._dt = config.dt
        self._steer = steer_all
        self._steer_args: tuple[object, ...] = ()
        self._bound: tuple[object, ...] = (None,) * 4
        self._next_service = math.inf  # earliest end of a loading / unloading
        # large teams find their neighbours on a grid (same commands, O(n) instead of O(n^2))
        self._grid_cell = (
            neighbour_cell_m(config.robot_radius, config.sensing_range_m)
            if n >= GRID_MIN_ROBOTS
            else 0.0
        )
        self._anchor = np.zeros((n, 2))  # where each robot last made progress ...
        self._anchor_time = np.zeros(n)  # ... and when
        self._escape_until = np.zeros(n)  # end of a robot's escape manoeuvre (0: none)
        self._escape_target = np.zeros((n, 2))
        self.escapes = 0  # escape manoeuvres started since reset
        self.time_s = 0.0
        self.ticks = 0
        self.rng = np.random.default_rng(0)
        # (time, kind 0 = break / 1 = repair, robot, repair delay after a break or -1 for none)
        self._schedule: list[tuple[float, int, int, float]] = []

    # -- life cycle ----------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> None:
        """Rebuild the world and put robots at the sinks, spread evenly over circuits in an order
        drawn from `rng` (never by speed). Everyone starts deciding."""
        cfg = self.config
        self.rng = rng
        self.world = World(cfg)
        self.tasks = TaskCycle(cfg)
        self.time_s = 0.0
        self.ticks = 0
        n, m = cfg.n_robots, cfg.n_circuits
        order = rng.permutation(n)
        positions = np.zeros((n, 2))
        per_circuit = [0] * m
        for rank, i in enumerate(order):
            c = rank % m
            k = per_circuit[c]
            per_circuit[c] += 1
            sink = self.tasks.stations[self.tasks.sink_of(c)]
            positions[i] = sink.dock if k == 0 else sink.slots[k - 1]
            self.tasks.start(int(i), c)
        self.world.place(positions)
        self.world.sync_positions()
        self._pos = self.world.pos
        self._anchor = self._pos.copy()
        self._anchor_time = np.zeros(n)
        self._escape_until = np.zeros(n)
        self.escapes = 0
        self.heading = rng.uniform(-math.pi, math.pi, size=n)
        self.speed_factor = np.ones(n)
        self.top_speed = self.speeds.copy()
        self._schedule = sorted(
            (b.at_s, 0, b.robot, -1.0 if b.repair_after_s is None else b.repair_after_s)
            for b in cfg.breakdowns
        )
        self._next_service = math.inf

    # -- decisions and failures ----------------------------------------------------------------
    def choose(self, robot: int, circuit: int) -> None:
        """A deciding robot starts a task on `circuit`."""
        self.tasks.choose(robot, circuit, self.time_s)
        self._new_leg(robot)

    def _new_leg(self, robot: int) -> None:
        noise = self.config.speed_noise
        if noise > 0:
            self.speed_factor[robot] = float(
                np.clip(1.0 + noise * self.rng.standard_normal(), 0.5, 1.5)
            )
            self.top_speed[robot] = self.speeds[robot] * self.speed_factor[robot]

    def break_down(self, robot: int) -> None:
        if self.tasks.phase[robot] == Phase.BROKEN:
            return
        self.tasks.break_down(robot)
        self.world.remove_robot(robot)
        self._pos = self.world.pos  # the world may now keep positions in another array
        self._next_service = float(self.tasks.service_until.min())

    def schedule_repair(self, robot: int) -> None:
        """Repair `robot` at the end of the next tick, so the repair is a decision epoch like any
        scheduled one."""
        self._schedule.append((self.time_s, 1, robot, -1.0))
        self._schedule.sort()

    def repair(self, robot: int) -> None:
        if self.tasks.phase[robot] != Phase.BROKEN:
            return
        self.world.restore_robot(robot, self.rng)
        self.world.sync_positions()
        self._pos = self.world.pos
        self.tasks.repair(robot)
        # Any other repair still scheduled for this robot belongs to a breakdown that is over.
        self._schedule = [e for e in self._schedule if not (e[1] == 1 and e[2] == robot)]

    # -- time ----------------------------------------------------------------------------------
    def advance(self, max_duration_s: float, stop_on_decision: bool = True) -> Advance:
        """Run ticks until a robot needs a decision (if `stop_on_decision`) or the duration ends.

        Returns at the end of the tick in which the first decision epoch happened, with every
        completion, breakdown and repair of that call.
        """
        out = Advance()
        start = self.time_s
        dt = self.config.dt
        n_ticks = max(1, round(max_duration_s / dt))
        for _ in range(n_ticks):
            self._tick(out)
            if stop_on_decision and (out.completions or out.repaired):
                break
        out.duration_s = self.time_s - start
        return out

    def _bind(self) -> None:
        """Fix the steering call's arguments: the same arrays every tick (updated in place),
        rebuilt after a reset or when robots leave or re-enter the floor."""
        world, nav, tasks = self.world, self.nav, self.tasks
        self._pos = world.pos
        args = (
            world.pos,
            self.heading,  # read and written in place: each robot reads only its own
            tasks.target,
            tasks.moving,
            self.top_speed,
            world.in_space,
            nav.radius,
            nav.sensing,
            nav.turn_step,
            nav.width,
            nav.height,
            world.velocity_out,
            self.heading,
        )
        if self._grid_cell > 0:
            self._steer, self._steer_args = steer_all_grid, (*args, self._grid_cell)
        else:
            self._steer, self._steer_args = steer_all, args
        self._bound = (world.version, tasks, self.heading, self.top_speed)

    def _tick(self, out: Advance) -> None:
        world, tasks = self.world, self.tasks
        bound = self._bound
        if (
            bound[0] != world.version
            or bound[1] is not tasks
            or bound[2] is not self.heading
            or bound[3] is not self.top_speed
        ):
            self._bind()
        if self.escapes and self._escape_until.max() > self.time_s:
            escaping = (self._escape_until > self.time_s)[:, None]
            args = list(self._steer_args)
            args[2] = np.where(escaping, self._escape_target, tasks.target)
            self._steer(*args)
        else:
            self._steer(*self._steer_args)
        world.push_velocities()
        world.step(self._dt)
        world.sync_positions()
        self.ticks += 1
        self.time_s = self.ticks * self._dt
        now = self.time_s

        # Most ticks nothing happens: one compiled call checks arrivals and stuck robots. When
        # something does, the checks run in the order events change the task state.
        services_due = self._next_service <= now + 1e-9
        schedule_due = bool(self._schedule) and self._schedule[0][0] <= now + 1e-9
        if services_due:
            for i in np.flatnonzero(tasks.service_until <= now + 1e-9):
                completion = tasks.finish_service(int(i), now)
                if completion is None:
                    self._new_leg(int(i))
                else:
                    out.completions.append(completion)
        n_arrived, n_stalled = after_step(
            self._pos,
            tasks.target,
            tasks.trigger,
            tasks.moving,
            self.world.in_space,
            self._anchor,
            self._anchor_time,
            now,
            STUCK_PATIENCE_S,
            not schedule_due,
            self._hits,
            self._stalled,
        )
        for k in range(n_arrived):
            tasks.arrive(int(self._hits[k]), now)
        if schedule_due:
            self._run_schedule(now, out)
        if n_stalled < 0:
            active = tasks.moving & self.world.in_space
            n_stalled = stuck(
                self._pos,
                tasks.target,
                active,
                self._anchor,
                self._anchor_time,
                now,
                STUCK_PATIENCE_S,
                self._stalled,
            )
        for k in range(n_stalled):
            self._escape(int(self._stalled[k]), now)
        if services_due or n_arrived or schedule_due:
            self._next_service = float(tasks.service_until.min())

    def _escape(self, robot: int, now: float) -> None:
        """Start robot's escape: away from the robots around it, in a direction jittered by the
        rng so that knotted robots do not all pick mirror-image moves."""
        pos = self._pos
        others = np.flatnonzero(self.world.in_space)
        others = others[others != robot]
        offsets = pos[robot] - pos[others]
        dist = np.hypot(offsets[:, 0], offsets[:, 1])
        near = dist < 1.5
        away = (offsets[near] / np.maximum(dist[near], 1e-9)[:, None]).sum(axis=0)
        angle = math.atan2(away[1], away[0]) if np.any(away) else 0.0
        angle += self.rng.uniform(-math.pi / 2, math.pi / 2)
        cfg = self.config
        margin = cfg.robot_radius + 0.3
        goal = pos[robot] + ESCAPE_DISTANCE_M * np.array([math.cos(angle), math.sin(angle)])
        self._escape_target[robot] = np.clip(
            goal, [margin, margin], [cfg.width - margin, cfg.height - margin]
        )
        self._escape_until[robot] = now + ESCAPE_TIME_S
        self._anchor[robot] = pos[robot]
        self._anchor_time[robot] = now + ESCAPE_TIME_S
        self.escapes += 1

    def _run_schedule(self, now: float, out: Advance) -> None:
        while self._schedule and self._schedule[0][0] <= now + 1e-9:
            _, kind, robot, after = self._schedule.pop(0)
            if kind == 0:
                if self.tasks.phase[robot] != Phase.BROKEN:
                    self.break_down(robot)
                    out.broken.append(robot)
                    if after > 0:
                        self._schedule.append((now + after, 1, robot, -1.0))
                        self._schedule.sort()
            elif self.tasks.phase[robot] == Phase.BROKEN:
                self.repair(robot)
                out.repaired.append(robot)

    # -- views ---------------------------------------------------------------------------------
    def positions(self) -> np.ndarray:
        """Robot centres after the last physics step, shape (n, 2) (a copy)."""
        return self._pos.copy()

    def broken(self) -> np.ndarray:
        return self.tasks.phase == Phase.BROKEN

    def idle(self) -> np.ndarray:
        return self.tasks.mode == Mode.IDLE
