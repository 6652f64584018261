"""The model twin's engine: the arena's decision process with task times drawn from its
`InterferenceTables` (lognormal, see `tavc_env.twin`), behind the same `Engine` protocol as the
physics (`tavc_env.engine.base`)."""

from __future__ import annotations

import heapq
import math

import numpy as np

from tavc_env.config import ArenaConfig
from tavc_env.engine.base import (
    Advance,
    ScheduleEntry,
    add_repair,
    breakdown_schedule,
    next_due_s,
    run_due,
    start_allocation,
    without_repairs,
)
from tavc_env.engine.tasks import Completion, Phase
from tavc_env.twin.tables import InterferenceTables
from tavc_env.validation import require

_EPS = 1e-9  # completions within this of an event happen at it (times are sums of floats)
# the phases the twin uses, as plain ints (an enum member's lookup costs more than a whole step)
_DECIDING, _WORKING, _BROKEN = int(Phase.DECIDING), int(Phase.TO_SOURCE), int(Phase.BROKEN)


class TwinTasks:
    """Per-robot task state, as the env adapter reads it (`tavc_env.engine.base.TaskView`: the
    subset of `tavc_env.engine.tasks.TaskCycle` that the env uses). Plain lists, not arrays: the
    adapter reads them one robot at a time, and a list's items are several times faster to get."""

    def __init__(self, config: ArenaConfig) -> None:
        n = config.n_robots
        self.phase = [_DECIDING] * n  # `Phase` codes: DECIDING, TO_SOURCE (working) or BROKEN
        self.circuit = [0] * n  # the circuit of the current or last task
        self.decision_time = [0.0] * n
        self.completed = [0] * n
        self.values = np.array([c.value for c in config.circuits], dtype=float)

    def needs_decision(self) -> np.ndarray:
        return np.array([p == _DECIDING for p in self.phase])


class TaskTimeProcess:
    """The twin's engine: the event-driven decision process with task times from the tables
    (see `tavc_env.twin`), an `Engine` (`tavc_env.engine.base`) like the physics: `reset`,
    `choose`, `advance`, `break_down`, `schedule_repair`, `broken`, `set_circuit_values`, `tasks`,
    `time_s`, `rng` and the (always quiet) jam and escape counters."""

    def __init__(self, config: ArenaConfig, tables: InterferenceTables) -> None:
        tables.check_team(config)
        self.config = config
        self.tables = tables
        self.jam_window_s = math.inf
        self.jammed = False
        self.jams = 0
        self.time_jammed_s = 0.0
        self.escapes = 0
        self.time_s = 0.0
        self.tasks = TwinTasks(config)
        self.classes = tables.classes
        self.robot_class = [tables.classes.index(r.speed_class) for r in config.robots]
        # (switch, circuit, counts, class index) -> (mean, mu, sigma) of the lognormal: a task
        # after the first (switch False: the switch cost is applied on top), or a first task
        self._law: dict[tuple[bool, int, tuple[int, ...], int], tuple[float, float, float]] = {}
        self._first_law: dict[
            tuple[bool, int, tuple[int, ...], int], tuple[float, float, float]
        ] = {}
        for law, switch, cells in (
            (self._law, False, tables.cells),
            (self._first_law, False, tables.first_own_cells),
            (self._first_law, True, tables.first_switch_cells),
        ):
            for cell in cells:
                key = (switch, cell.circuit, cell.counts, tables.classes.index(cell.robot_class))
                law[key] = (cell.mean_s, *cell.lognormal())
        self._switch_cost = [tables.class_switch_cost(c) for c in tables.classes]
        self._rng: np.random.Generator | None = None
        self._clear()

    def _clear(self) -> None:
        n, m = self.config.n_robots, self.config.n_circuits
        self._committed = [[0] * len(self.classes) for _ in range(m)]
        self._due: list[tuple[float, int, int]] = []  # heap of (completion time, robot, token)
        self._token = [0] * n  # a robot's current task; older heap entries are stale
        self._duration = [0.0] * n
        self._undrawn: list[tuple[int, bool]] = []  # (robot, switch) chosen, time not drawn yet
        self._first = [bool(self._first_law)] * n  # whose next draw is a first task's
        self._schedule: list[ScheduleEntry] = []

    @property
    def rng(self) -> np.random.Generator:
        """The generator passed to `reset` (every draw of the twin comes from it)."""
        if self._rng is None:
            raise ValueError("the twin has no random generator yet; allowed: call reset(rng) first")
        return self._rng

    def reset(self, rng: np.random.Generator) -> None:
        """Robots on their start circuits (`tavc_env.engine.base.start_allocation`, as in the
        physics); everyone decides."""
        require(
            isinstance(rng, np.random.Generator),
            "rng",
            rng,
            "a numpy.random.Generator (e.g. numpy.random.default_rng(seed))",
        )
        cfg = self.config
        self._rng = rng
        self.time_s = 0.0
        self.tasks = TwinTasks(cfg)
        self._clear()
        for i, c in start_allocation(cfg, rng):
            self.tasks.circuit[i] = c
        self._schedule = breakdown_schedule(cfg)

    # -- decisions and failures ----------------------------------------------------------------
    def choose(self, robot: int, circuit: int) -> None:
        """Deciding robot `robot` commits to `circuit`; its task time is drawn at the next
        `advance`, once every robot deciding now has chosen."""
        tasks = self.tasks
        if tasks.phase[robot] != _DECIDING:
            raise ValueError(
                f"robot = {robot!r} is invalid; allowed: a robot that is deciding (its info's "
                "action_required)"
            )
        switch = tasks.circuit[robot] != circuit
        tasks.phase[robot] = _WORKING
        tasks.circuit[robot] = circuit
        tasks.decision_time[robot] = self.time_s
        self._committed[circuit][self.robot_class[robot]] += 1
        self._token[robot] += 1
        self._undrawn.append((robot, switch))

    def _draw(self) -> None:
        rng = self.rng
        tasks = self.tasks
        for i, switch in self._undrawn:
            k = tasks.circuit[i]
            t = self.task_time(
                self.robot_class[i], k, tuple(self._committed[k]), switch, self._first[i], rng
            )
            self._first[i] = False
            self._duration[i] = t
            heapq.heappush(self._due, (tasks.decision_time[i] + t, i, self._token[i]))
        self._undrawn = []

    def task_time(
        self,
        robot_class: int,
        circuit: int,
        counts: tuple[int, ...],
        switch: bool,
        first: bool,
        rng: np.random.Generator,
    ) -> float:
        """A task time drawn from the tables: a robot of class index `robot_class` working on
        `circuit` with `counts` robots of each class there (itself included), that `switch`ed
        circuits, on its `first` task (which has cells of its own when the tables do) or not (the
        class's switch cost then multiplies a switching task)."""
        first = first and bool(self._first_law)
        law = self._first_law if first else self._law
        mean, mu, sigma = law[(switch and first, circuit, counts, robot_class)]
        t = math.exp(mu + sigma * rng.standard_normal()) if sigma > 0 else mean
        if switch and not first:
            t *= self._switch_cost[robot_class]
        return t

    def break_down(self, robot: int) -> None:
        """`robot` stops: its task (if any) is abandoned and it no longer counts on its circuit."""
        tasks = self.tasks
        if tasks.phase[robot] == _BROKEN:
            return
        if tasks.phase[robot] == _WORKING:
            self._committed[tasks.circuit[robot]][self.robot_class[robot]] -= 1
            self._token[robot] += 1
            self._undrawn = [(i, s) for i, s in self._undrawn if i != robot]
        tasks.phase[robot] = _BROKEN

    def schedule_repair(self, robot: int) -> None:
        """Repair `robot` in the next `advance`, a decision epoch like a scheduled repair."""
        add_repair(self._schedule, self.time_s, robot)

    def is_broken(self, robot: int) -> bool:
        return self.tasks.phase[robot] == _BROKEN

    def repair(self, robot: int) -> None:
        if self.tasks.phase[robot] != _BROKEN:
            return
        self.tasks.phase[robot] = _DECIDING
        self._schedule = without_repairs(self._schedule, robot)

    def broken(self) -> np.ndarray:
        return np.array([p == _BROKEN for p in self.tasks.phase])

    def set_circuit_values(self, values: np.ndarray) -> None:
        self.tasks.values = np.asarray(values, dtype=float).copy()

    def committed(self) -> np.ndarray:
        """(circuits, classes): robots of each class working on each circuit now."""
        return np.array(self._committed, dtype=np.int64)

    # -- time ----------------------------------------------------------------------------------
    def advance(self, max_duration_s: float, stop_on_decision: bool = True) -> Advance:
        """Jump from event to event (completions, scheduled breakdowns and repairs) until a robot
        must decide (if `stop_on_decision`) or `max_duration_s` has passed."""
        self._draw()
        out = Advance()
        start = self.time_s
        end = start + max_duration_s
        due, token, tasks = self._due, self._token, self.tasks
        while True:
            while due and due[0][2] != token[due[0][1]]:
                heapq.heappop(due)  # an abandoned task
            t_next = due[0][0] if due else math.inf
            t_next = min(t_next, next_due_s(self._schedule))
            if t_next > end + _EPS:
                self.time_s = end
                break
            now = max(t_next, self.time_s)
            self.time_s = now
            while due and due[0][0] <= now + _EPS:
                _, i, tok = heapq.heappop(due)
                if tok != token[i]:
                    continue
                k = tasks.circuit[i]
                tasks.phase[i] = _DECIDING
                tasks.completed[i] += 1
                self._committed[k][self.robot_class[i]] -= 1
                out.completions.append(Completion(i, k, self._duration[i], now))
            run_due(self._schedule, now, self, out)
            if stop_on_decision and (out.completions or out.repaired):
                break
        out.duration_s = self.time_s - start
        return out
