"""The arena engine: physics world + navigation + task cycle, advanced tick by tick.

The physics engine every adapter (the PettingZoo env, benchmarks, renderers) drives, behind the
`Engine` protocol (`tavc_env.engine.base`) it shares with the model twin. It knows circuits, tasks
and time; it knows nothing of observations, rewards or agents' names.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol

import numpy as np

from tavc_env.config import JAM_WINDOW_S, ArenaConfig
from tavc_env.engine.base import (
    Advance,
    ScheduleEntry,
    add_repair,
    breakdown_schedule,
    run_due,
    start_allocation,
    without_repairs,
)
from tavc_env.engine.navigation import (
    ESCAPE_DISTANCE_M,
    ESCAPE_TIME_S,
    GRID_MIN_ROBOTS,
    QUIET,
    SCHEDULE,
    STUCK_PATIENCE_S,
    Navigator,
    TickArgs,
    bit_generator_calls,
    choice_entry,
    grid_scratch,
    neighbour_cell_m,
    run_ticks,
    stuck_of,
    tick_loop,
)
from tavc_env.engine.tasks import Phase, TaskCycle
from tavc_env.engine.world import World

_BROKEN = int(Phase.BROKEN)  # a plain int: no enum lookup per comparison
_GRID_FIELDS = (
    "grid_cx",
    "grid_cy",
    "grid_key",
    "grid_order",
    "grid_keys",
    "grid_others",
    "grid_held",
    "near",
    "near_start",
    "near_anchor",
    "near_present",
    "near_held",
)
JAM_MOTION_M = 1.0  # ... while no moving robot got this far from where the window began


class EngineEvent(NamedTuple):
    """Something that happened during a tick, as handed to observers: `kind` is one of
    "completion", "breakdown", "repair", "escape" or "jam"; `circuit` and `task_time_s` are set
    for a completion only."""

    time_s: float
    kind: str
    robot: int
    circuit: int = -1
    task_time_s: float = math.nan


class Observer(Protocol):
    """Instrumentation attached with `Simulation.add_observer`: called at the end of every tick,
    after the physics step and every task event of that tick. Observers read the simulation
    through its public views (`time_s`, `positions_view`, `modes`, ...) and change nothing; they
    cannot alter a trajectory."""

    def on_tick(self, sim: Simulation, events: list[EngineEvent]) -> None:
        """`events`: what happened in this tick (usually nothing)."""


@dataclass(frozen=True)
class ArenaSnapshot:
    """The arena at one moment, for drawing or recording (copies: it never changes)."""

    time_s: float
    positions: np.ndarray  # (n, 2)
    headings: np.ndarray  # (n,)
    targets: np.ndarray  # (n, 2)
    circuits: np.ndarray  # (n,) the circuit each robot serves now
    phases: np.ndarray  # (n,) `Phase` codes
    moving: np.ndarray  # (n,) bool
    broken: np.ndarray  # (n,) bool
    values: np.ndarray  # (m,) the circuits' values now


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.setflags(write=False)
    return view


def _never_reset(robot: int, circuit: int, now: float) -> None:
    raise ValueError("the simulation was never reset; allowed: call reset(rng) first")


class Simulation:
    """One arena in motion. Call `reset(rng)` before use; `rng` drives every random draw.

    The physics engine behind the `Engine` protocol (`tavc_env.engine.base`)."""

    _progress_s: float  # (set by `_reset_jam_watch`; declared for the type checker)

    def __init__(self, config: ArenaConfig, jam_window_s: float = JAM_WINDOW_S) -> None:
        """`jam_window_s`: the jam detector's window (see `jammed`); math.inf turns it off."""
        if not (isinstance(jam_window_s, (int, float)) and jam_window_s > 0):
            raise ValueError(
                f"jam_window_s = {jam_window_s!r} is invalid; allowed: a time > 0 s (math.inf: off)"
            )
        self.config = config
        self.jam_window_s = float(jam_window_s)
        self.world = World(config)
        self.nav = Navigator(config)
        self.tasks = TaskCycle(config)
        n = config.n_robots
        self.speeds = np.array([r.speed for r in config.robots], dtype=float)
        self._pos = np.zeros((n, 2))  # positions after the last physics step
        self._dt = config.dt
        self._tick_args: tuple[object, ...] = ()  # `TickArgs`, then the task rules' arrays
        self._tick_loop: Callable[..., Any] = run_ticks  # bound to them (`tick_loop`)
        self._bound: tuple[object, ...] = (None,) * 7
        # large teams find their neighbours on a grid (same commands, O(n) instead of O(n^2))
        self._grid_cell = (
            neighbour_cell_m(config.robot_radius, config.sensing_range_m)
            if n >= GRID_MIN_ROBOTS
            else 0.0
        )
        self._rng: np.random.Generator | None = None
        self._bitgen = np.zeros(0, np.int64)  # `bit_generator_calls(rng)` from `reset` on
        self._choose_leg: Callable[[int, int, float], None] = _never_reset  # (`reset` binds it)
        self._speed_noise = float(config.speed_noise)
        self._observers: list[Observer] = []
        self._clear_episode()

    def _clear_episode(self) -> None:
        """Every attribute an episode changes, as at its start (before `reset` draws anything).
        All of them, so that an arena reset after earlier episodes is the arena a new one would
        be: copying an env replays its episode on a new arena and checks that it is."""
        n = self.config.n_robots
        self.time_s = 0.0
        self.ticks = 0
        self.speed_factor = np.ones(n)
        self.top_speed = self.speeds.copy()  # speeds * speed_factor, updated at each new leg
        self.heading = np.zeros(n)
        self._hits = np.zeros(n, dtype=np.int64)  # the compiled tick's outputs (first k rows)
        self._stalled = np.zeros(n, dtype=np.int64)
        self._done = np.zeros(n, dtype=np.int64)
        self._next_service = math.inf  # earliest end of a loading / unloading
        self._anchor = np.zeros((n, 2))  # where each robot last made progress ...
        self._anchor_time = np.zeros(n)  # ... and when
        self._escape_until = np.zeros(n)  # end of a robot's escape manoeuvre (0: none)
        self._escapes_end = 0.0  # the latest of them: a scalar test in every tick, not a max
        self._escape_target = np.zeros((n, 2))
        self.escapes = 0  # escape manoeuvres started since reset
        self._schedule: list[ScheduleEntry] = []
        self._reset_jam_watch()

    # -- life cycle ----------------------------------------------------------------------------
    @property
    def rng(self) -> np.random.Generator:
        """The generator passed to `reset` (every random draw of the arena comes from it)."""
        if self._rng is None:
            raise ValueError(
                "the simulation has no random generator yet; allowed: call reset(rng) first"
            )
        return self._rng

    def reset(self, rng: np.random.Generator) -> None:
        """Rebuild the world and put robots at the sinks: on `config.start_circuits` if given,
        else spread evenly over circuits in an order drawn from `rng` (never by speed). Everyone
        starts deciding."""
        if not isinstance(rng, np.random.Generator):
            raise ValueError(
                f"rng = {rng!r} is invalid; allowed: a numpy.random.Generator "
                "(e.g. numpy.random.default_rng(seed))"
            )
        cfg = self.config
        self._rng = rng
        self._bitgen = bit_generator_calls(rng)  # how compiled code draws from it
        self.world = World(cfg)
        self.tasks = TaskCycle(cfg)
        n, m = cfg.n_robots, cfg.n_circuits
        positions = np.zeros((n, 2))
        per_circuit = [0] * m
        for i, c in start_allocation(cfg, rng):
            k = per_circuit[c]
            per_circuit[c] += 1
            sink = self.tasks.stations[self.tasks.sink_of(c)]
            positions[i] = sink.dock if k == 0 else sink.slots[k - 1]
            self.tasks.start(int(i), c)
        self.world.place(positions)
        self.world.sync_positions()
        self._pos = self.world.pos
        self._clear_episode()
        self._anchor = self._pos.copy()
        self.heading = rng.uniform(-math.pi, math.pi, size=n)
        self._schedule = breakdown_schedule(cfg)
        # (`TaskCycle.choose`, then the leg's speed, in one compiled call: the arrays it is
        # bound to are made by this reset and replaced only by the next)
        self._choose_leg = choice_entry(
            self.tasks.arrays,
            self._speed_noise,
            self.speeds,
            self.speed_factor,
            self.top_speed,
            self._bitgen,
        )

    # -- decisions and failures ----------------------------------------------------------------
    def choose(self, robot: int, circuit: int) -> None:
        """A deciding robot starts a task on `circuit`."""
        self._check_reset()
        self._choose_leg(robot, circuit, self.time_s)

    def break_down(self, robot: int) -> None:
        if self.tasks.phase[robot] == _BROKEN:
            return
        self.tasks.break_down(robot)
        self.world.remove_robot(robot)
        self._pos = self.world.pos  # the world may now keep positions in another array
        self._next_service = min(self.tasks.service_until.tolist())

    def schedule_repair(self, robot: int) -> None:
        """Repair `robot` at the end of the next tick, so the repair is a decision epoch like any
        scheduled one."""
        add_repair(self._schedule, self.time_s, robot)

    def is_broken(self, robot: int) -> bool:
        return bool(self.tasks.phase[robot] == _BROKEN)

    def repair(self, robot: int) -> None:
        if self.tasks.phase[robot] != _BROKEN:
            return
        self.world.restore_robot(robot, self.rng)
        self.world.sync_positions()
        self._pos = self.world.pos
        self.tasks.repair(robot)
        self._schedule = without_repairs(self._schedule, robot)

    # -- time ----------------------------------------------------------------------------------
    def advance(self, max_duration_s: float, stop_on_decision: bool = True) -> Advance:
        """Run ticks until a robot needs a decision (if `stop_on_decision`) or the duration ends.

        Returns at the end of the tick in which the first decision epoch happened, with every
        completion, breakdown and repair of that call.
        """
        self._check_reset()
        out = Advance()
        start = self.time_s
        n_ticks = max(1, round(max_duration_s / self.config.dt))
        done = 0
        while done < n_ticks:
            # Observers see every tick; otherwise the compiled loop runs ticks, task events
            # included, until one ends in something for Python (every decision epoch does).
            done += self._ticks(out, 1 if self._observers else n_ticks - done)
            if stop_on_decision and (out.completions or out.repaired):
                break
        out.duration_s = self.time_s - start
        return out

    def _bind(self) -> None:
        """Fix the compiled tick's arguments: the same arrays every tick (updated in place),
        rebuilt after a reset or when robots leave or re-enter the floor."""
        world, nav, tasks = self.world, self.nav, self.tasks
        self._pos = world.pos
        scatter = world.scatter()
        tick_args = TickArgs(
            c_calls=world.c_calls,
            pos=world.pos,
            heading=self.heading,  # read and written in place: each robot reads only its own
            target=tasks.target,
            moving=tasks.moving,
            top_speed=self.top_speed,
            present=world.in_space,
            radius=nav.radius,
            sensing=nav.sensing,
            governor=nav.governor,
            overtaking=nav.overtaking,
            turn_step=nav.turn_step,
            width=nav.width,
            height=nav.height,
            velocity=world.velocity_out,
            cell=self._grid_cell,
            in_order=scatter.in_order,
            robots_in=scatter.robots_in,
            slots=scatter.slots,
            positions_in=scatter.positions_in,
            velocities_in=scatter.velocities_in,
            escape_until=self._escape_until,
            escape_target=self._escape_target,
            aim=np.zeros_like(self._escape_target),
            trigger=tasks.trigger,
            anchor=self._anchor,
            anchor_time=self._anchor_time,
            patience_s=STUCK_PATIENCE_S,
            arrived=self._hits,
            stalled=self._stalled,
            done=self._done,
            speed_noise=self._speed_noise,
            speeds=self.speeds,
            speed_factor=self.speed_factor,
            bitgen=self._bitgen,
            progress_pos=self._progress_pos,
            everyone=np.arange(self.config.n_robots),
            **dict(zip(_GRID_FIELDS, grid_scratch(self.config.n_robots))),
        )
        self._tick_args = (*tick_args, *tasks.arrays)
        self._tick_loop = tick_loop(self._tick_args)
        # the world itself too: a new World starts counting versions anew, and the compiled
        # tick must never call into the C space of one that is gone
        self._bound = (
            world,
            world.version,
            tasks,
            self.heading,
            self.top_speed,
            self._anchor,
            self._progress_pos,
        )

    def _ticks(self, out: Advance, max_ticks: int) -> int:
        """Run up to `max_ticks` ticks, stopping after the first that needs Python (see
        `tavc_env.engine.navigation.run_ticks`); returns how many ran."""
        if self._observers:
            marks = (len(out.completions), len(out.broken), len(out.repaired), self.escapes)
        bound = self._bound
        if (
            bound[0] is not self.world
            or bound[1] != self.world.version
            or bound[2] is not self.tasks
            or bound[3] is not self.heading
            or bound[4] is not self.top_speed
            or bound[5] is not self._anchor
            or bound[6] is not self._progress_pos
        ):
            self._bind()
        ran, stage, n_done, n_stalled, event, progressed, next_service, progress_s = (
            self._tick_loop(
                max_ticks,
                self.ticks,
                self._dt,
                self._escapes_end,
                self._next_service,
                float(self._schedule[0].at_s) if self._schedule else math.inf,
                self._progress_s,
                self.jam_window_s,
                self.jammed,
            )
        )
        self.ticks += ran
        self.time_s = self.ticks * self._dt
        self._next_service = float(next_service)
        self._progress_s = float(progress_s)
        if stage != QUIET:
            self._end_tick(out, stage, n_done, n_stalled, event, progressed)
        if self._observers:
            self._notify(out, marks)
        return int(ran)

    def _end_tick(
        self,
        out: Advance,
        stage: int,
        n_done: int,
        n_stalled: int,
        event: bool,
        progressed: bool,
    ) -> None:
        """What the compiled tick leaves to Python at the end of a tick, in the order of the
        rules (the legs that started drew their speeds in the compiled tick, in robot order,
        from the same generator): the completions, the schedule and then the stuck check
        (`SCHEDULE`), escapes, and the jam watch."""
        tasks = self.tasks
        now = self.time_s
        for k in range(n_done):
            out.completions.append(tasks.completion(int(self._done[k]), now))
        if stage == SCHEDULE:
            self._run_schedule(now, out)
            n_stalled = stuck_of(
                self._pos,
                tasks.target,
                tasks.moving,
                self.world.in_space,
                self._anchor,
                self._anchor_time,
                now,
                STUCK_PATIENCE_S,
                self._stalled,
            )
        for k in range(n_stalled):
            self._escape(int(self._stalled[k]), now)
        # (the compiled loop found the next service end; a breakdown of the schedule updated it)
        if event:
            if not progressed:
                self._progress(now)
        elif now - self._progress_s >= self.jam_window_s:
            self._check_jam(now)

    def _notify(self, out: Advance, marks: tuple[int, int, int, int]) -> None:
        now = self.time_s
        events = [
            EngineEvent(now, "completion", c.robot, c.circuit, c.task_time_s)
            for c in out.completions[marks[0] :]
        ]
        events += [EngineEvent(now, "breakdown", r) for r in out.broken[marks[1] :]]
        events += [EngineEvent(now, "repair", r) for r in out.repaired[marks[2] :]]
        if self.escapes > marks[3]:
            started = np.flatnonzero(self._escape_until == now + ESCAPE_TIME_S)
            events += [EngineEvent(now, "escape", int(r)) for r in started]
        if self.jam_started_s == now:
            events.append(EngineEvent(now, "jam", -1))
        for observer in self._observers:
            observer.on_tick(self, events)

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
        self._escapes_end = now + ESCAPE_TIME_S
        self._anchor[robot] = pos[robot]
        self._anchor_time[robot] = now + ESCAPE_TIME_S
        self.escapes += 1

    def _run_schedule(self, now: float, out: Advance) -> None:
        run_due(self._schedule, now, self, out)

    # -- liveness ------------------------------------------------------------------------------
    def _reset_jam_watch(self) -> None:
        self._progress_s = 0.0  # time of the last task event (arrival, service end, repair ...)
        self._progress_pos: np.ndarray = self._pos.copy()  # where every robot stood then
        self.jammed: bool = False
        self.jams = 0  # jams detected since reset
        self.jammed_s = 0.0  # simulated time spent jammed since reset
        self.jam_started_s = -1.0

    def _progress(self, now: float) -> None:
        if self.jammed:
            self.jammed = False
            self.jammed_s += now - self.jam_started_s
        self._progress_s = now
        self._progress_pos[:] = self._pos

    def _check_jam(self, now: float) -> None:
        """No task event for `jam_window_s`: a jam if no moving robot got `JAM_MOTION_M` away
        from where it stood when the window began (a long, free leg is not a jam). A jam lasts
        until the next task event; a window that ends in motion starts a new one."""
        moving = self.tasks.moving & self.world.in_space
        travelled = np.hypot(*(self._pos - self._progress_pos).T)
        if moving.any() and not (travelled[moving] >= JAM_MOTION_M).any():
            if not self.jammed:
                self.jammed = True
                self.jams += 1
                self.jam_started_s = now
        elif self.jammed:
            self.jammed_s += now - self.jam_started_s
            self.jammed = False
        self._progress_s = now  # look again one window on
        self._progress_pos[:] = self._pos

    @property
    def time_jammed_s(self) -> float:
        """Simulated time spent jammed since reset (the current jam included)."""
        return self.jammed_s + (self.time_s - self.jam_started_s if self.jammed else 0.0)

    # -- instrumentation -----------------------------------------------------------------------
    def add_observer(self, observer: Observer) -> None:
        """Call `observer.on_tick(self, events)` at the end of every tick from now on (until
        `remove_observer`); it survives `reset`."""
        if not callable(getattr(observer, "on_tick", None)):
            raise ValueError(
                f"observer {observer!r} is invalid; allowed: an object with on_tick(sim, events)"
            )
        self._observers.append(observer)

    def remove_observer(self, observer: Observer) -> None:
        self._observers.remove(observer)

    # -- priorities ----------------------------------------------------------------------------
    def set_circuit_values(self, values: np.ndarray) -> None:
        """What a delivery on each circuit earns from now on (validated by the caller)."""
        self.tasks.values = np.array(values, dtype=float)

    # -- views (read-only: writing through them raises) -----------------------------------------
    def positions(self) -> np.ndarray:
        """Robot centres after the last physics step, shape (n, 2) (a copy)."""
        return self._pos.copy()

    @property
    def positions_view(self) -> np.ndarray:
        """Robot centres after the last physics step, shape (n, 2): a read-only view, valid until
        the next tick (cheaper than `positions()` for per-tick observers)."""
        return _read_only(self._pos)

    @property
    def headings(self) -> np.ndarray:
        return _read_only(self.heading)

    @property
    def modes(self) -> np.ndarray:
        """Each robot's `Mode` code (travel, queued, docking, service, idle)."""
        return _read_only(self.tasks.mode)

    @property
    def phases(self) -> np.ndarray:
        """Each robot's `Phase` code (deciding, to source, to sink, broken)."""
        return _read_only(self.tasks.phase)

    @property
    def circuits(self) -> np.ndarray:
        """The circuit each robot serves now (its last choice)."""
        return _read_only(self.tasks.circuit)

    @property
    def circuit_values(self) -> np.ndarray:
        return _read_only(self.tasks.values)

    def broken(self) -> np.ndarray:
        return self.tasks.phase == _BROKEN

    def snapshot(self) -> ArenaSnapshot:
        """The arena now, as copies (for drawing, recording or comparing)."""
        tasks = self.tasks
        return ArenaSnapshot(
            time_s=self.time_s,
            positions=self._pos.copy(),
            headings=self.heading.copy(),
            targets=tasks.target.copy(),
            circuits=tasks.circuit.copy(),
            phases=tasks.phase.copy(),
            moving=tasks.moving.copy(),
            broken=self.broken(),
            values=tasks.values.copy(),
        )

    def _check_reset(self) -> None:
        if self._rng is None:
            raise ValueError("the simulation was never reset; allowed: call reset(rng) first")
