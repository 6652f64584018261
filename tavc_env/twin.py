"""The model twin of the arena: the decision process alone, with task times drawn from an arena's
measured interference tables instead of simulated by physics.

A research tool, for fast what-if studies and power analyses; never a replacement for the physics
(`tavc_env.parallel_env`), whose results are the ones to report.

## tavc_twin_v0

The same PettingZoo `ParallelEnv` as `tavc_arena_v1` (`TavcArenaEnv`, which `TwinArenaEnv`
subclasses: same agents, observation and action spaces, rewards `w_i / t` in the same time unit,
info keys, truncation, `max_cycles`, stepping modes, breakdowns and repairs, priority changes,
copying), with the physics engine replaced by `TaskTimeProcess`, an event-driven model:

* at reset the robots stand at the circuits' sinks, spread evenly over the circuits in an order
  drawn from the env's generator (as in the physics), and all decide;
* when a robot chooses circuit `k`, it commits to `k`. Once every robot deciding at that moment has
  chosen, each draws its task time from the cell of `InterferenceTables` for its speed class and
  the numbers of robots of each class committed to `k` (itself and the others deciding at the same
  moment included), times `switch_cost` if `k` differs from the circuit of its last task;
* time jumps to the next completion (or scheduled breakdown or repair); the robot is paid
  `w_k / t` and decides again.

## Distribution

Task times are lognormal with the cell's mean and standard deviation (moments matched:
`sigma^2 = ln(1 + (sd / mean)^2)`, `mu = ln(mean) - sigma^2 / 2`), not gamma. Both are positive and
right-skewed like queueing delays and nearly agree when the spread is small (the physics' cells
have sd / mean of about 0.1-0.4). They differ where it matters to learners paid `w / t`: a
lognormal's density vanishes at 0 whatever the spread, so E[1/t] = (1 + cv^2) / mean stays finite,
whereas a gamma with sd >= mean (shape <= 1, possible in a sparsely measured or jam-hit cell) has
its mode at 0 and an infinite E[1/t]: occasional near-zero task times would pay huge rewards that
no physical task can (every real task takes at least its travel and service times).

## Limits (what the model leaves out)

* A task's time is drawn once, at its decision, from the robots committed to its circuit then;
  robots joining or leaving that circuit during the task do not change it.
* Only robots on the same circuit interfere; traffic from other circuits enters only as it was
  present in the runs that measured the tables (`tavc_agents.experiments.twin_tables`).
* Counts are per speed-class label (`Robot.speed_class`); robots of one class are alike.
* One switch cost for every class and circuit; a repaired robot's next task counts as starting at
  the circuit of its abandoned task.
* No space: no positions, no jams (`jammed` is always False, `jams`, `escapes` 0), no rendering
  (`render_mode` must be None); `state()` is the twin's own (circuits, phases, commitments) and
  `snapshot()` is refused. A working robot reports the phase `to_source` for its whole task.
* Time is continuous (physics advances in ticks of `dt`): completions fall between ticks.

What these limits cost was measured where they bite hardest, random allocation (crowds change at
every decision, half the tasks are switches; `benchmarks/twin_audit.py`): in the shipped arenas
the physics' own-circuit tasks are 3-13 % shorter than their cells, and its switch tasks cost less
extra than the tables' switch cost (measured by a robot alternating every 3 tasks), so the twin
underestimates random allocation's performance by 3-9 %. Learners, which settle and rarely switch,
are predicted more closely (the regime map).
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from tavc_env._validation import is_integer, is_number, require
from tavc_env.config import ArenaConfig
from tavc_env.engine.simulation import (
    Advance,
    ArenaSnapshot,
    Scheduled,
    ScheduleEntry,
    breakdown_schedule,
)
from tavc_env.engine.tasks import Completion, Phase
from tavc_env.env import _HISTORIES, TavcArenaEnv
from tavc_env.observations import N_PHASES

TWIN_ENV_NAME = "tavc_twin_v0"
CellKey = tuple[int, tuple[int, ...], str]
"""(circuit, robots of each class on it, the robot's class)"""
_EPS = 1e-9
# the phases the twin uses, as plain ints (an enum member's lookup costs more than a whole step)
_DECIDING, _WORKING, _BROKEN = int(Phase.DECIDING), int(Phase.TO_SOURCE), int(Phase.BROKEN)
_TABLE_KEYS = ("classes", "team", "n_circuits", "cells", "switch_cost")
_CELL_KEYS = ("circuit", "counts", "robot_class", "mean_s", "sd_s")


def team_classes(config: ArenaConfig) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """The speed classes of `config`'s robots, in order of first appearance, and how many robots
    each has."""
    counts: dict[str, int] = {}
    for robot in config.robots:
        counts[robot.speed_class] = counts.get(robot.speed_class, 0) + 1
    return tuple(counts), tuple(counts.values())


def count_vectors(team: Sequence[int]) -> Iterator[tuple[int, ...]]:
    """Every number of robots of each class (0 to the team's count) with at least one robot."""
    for counts in itertools.product(*(range(t + 1) for t in team)):
        if any(counts):
            yield counts


def required_cells(classes: Sequence[str], team: Sequence[int], n_circuits: int) -> list[CellKey]:
    """The cells a table needs: every circuit, every count vector up to `team`, and every class
    that has a robot in it."""
    return [
        (k, counts, cls)
        for k in range(n_circuits)
        for counts in count_vectors(team)
        for cls, n in zip(classes, counts)
        if n >= 1
    ]


def _sequence(name: str, value: object, kind: str) -> tuple[Any, ...]:
    ok = isinstance(value, (Sequence, np.ndarray)) and not isinstance(value, (str, bytes))
    require(ok, name, value, f"a sequence of {kind}")
    assert isinstance(value, (Sequence, np.ndarray))
    return tuple(value)


@dataclass(frozen=True)
class TaskTimeCell:
    """The task time T of a robot of class `robot_class` on circuit `circuit` while `counts[j]`
    robots of class j (the tables' classes, in order; the robot itself included) serve it: mean
    and standard deviation in seconds, from `n_tasks` measured tasks (0: given, not measured)."""

    circuit: int
    counts: tuple[int, ...]
    robot_class: str
    mean_s: float
    sd_s: float
    n_tasks: int = 0

    def __post_init__(self) -> None:
        require(
            is_integer(self.circuit) and self.circuit >= 0,
            "cell.circuit",
            self.circuit,
            "a circuit index >= 0",
        )
        counts = _sequence("cell.counts", self.counts, "robot counts, one per class")
        require(
            len(counts) >= 1 and all(is_integer(c) and c >= 0 for c in counts),
            "cell.counts",
            self.counts,
            "a non-empty sequence of robot counts >= 0, one per class",
        )
        require(
            isinstance(self.robot_class, str), "cell.robot_class", self.robot_class, "a class name"
        )
        require(
            is_number(self.mean_s) and self.mean_s > 0,
            "cell.mean_s",
            self.mean_s,
            "a finite mean task time > 0 s",
        )
        require(
            is_number(self.sd_s) and self.sd_s >= 0,
            "cell.sd_s",
            self.sd_s,
            "a finite standard deviation >= 0 s",
        )
        require(
            is_integer(self.n_tasks) and self.n_tasks >= 0,
            "cell.n_tasks",
            self.n_tasks,
            "a number of measured tasks >= 0",
        )
        object.__setattr__(self, "circuit", int(self.circuit))
        object.__setattr__(self, "counts", tuple(int(c) for c in counts))
        object.__setattr__(self, "mean_s", float(self.mean_s))
        object.__setattr__(self, "sd_s", float(self.sd_s))
        object.__setattr__(self, "n_tasks", int(self.n_tasks))

    @property
    def key(self) -> CellKey:
        return (self.circuit, self.counts, self.robot_class)

    def to_dict(self) -> dict[str, Any]:
        return {
            "circuit": self.circuit,
            "counts": list(self.counts),
            "robot_class": self.robot_class,
            "mean_s": self.mean_s,
            "sd_s": self.sd_s,
            "n_tasks": self.n_tasks,
        }


@dataclass(frozen=True)
class InterferenceTables:
    """An arena's task times by circuit, class and crowding, and its switch cost: what the twin
    draws task times from.

    `classes` are speed-class names (`Robot.speed_class`) and `team[j]` the robots of class j.
    `cells` hold, for every circuit, every vector of robots of each class serving it (each from 0
    to the team's count, at least one robot) and every class present in the vector, the mean and
    standard deviation of a task's time T_c(f, s) (see `TaskTimeCell`; `required_cells` lists
    them). `switch_cost` multiplies the time of a task that starts on another circuit than the
    robot's last one (1: switching costs nothing extra). `source` says where the numbers came
    from (free text).

    Every cell must be there, once; anything else is a ValueError naming the field.
    """

    classes: tuple[str, ...]
    team: tuple[int, ...]
    n_circuits: int
    cells: tuple[TaskTimeCell, ...]
    switch_cost: float = 1.0
    source: str = ""
    _index: dict[CellKey, TaskTimeCell] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        classes = _sequence("classes", self.classes, "speed-class names")
        require(
            len(classes) >= 1
            and all(isinstance(c, str) for c in classes)
            and len(set(classes)) == len(classes),
            "classes",
            self.classes,
            "a non-empty sequence of distinct speed-class names",
        )
        team = _sequence("team", self.team, "robot counts")
        require(
            len(team) == len(classes) and all(is_integer(t) and t >= 1 for t in team),
            "team",
            self.team,
            f"one robot count >= 1 per class ({len(classes)} classes)",
        )
        require(
            is_integer(self.n_circuits) and self.n_circuits >= 1,
            "n_circuits",
            self.n_circuits,
            "an integer >= 1",
        )
        require(
            is_number(self.switch_cost) and self.switch_cost > 0,
            "switch_cost",
            self.switch_cost,
            "a finite factor > 0 on the time of a task that starts on another circuit "
            "(1: no extra time)",
        )
        require(isinstance(self.source, str), "source", self.source, "a string")
        team = tuple(int(t) for t in team)
        cells = _sequence("cells", self.cells, "tavc_env.twin.TaskTimeCell")
        index: dict[CellKey, TaskTimeCell] = {}
        for k, cell in enumerate(cells):
            require(
                isinstance(cell, TaskTimeCell), f"cells[{k}]", cell, "a tavc_env.twin.TaskTimeCell"
            )
            require(
                cell.circuit < self.n_circuits,
                f"cells[{k}].circuit",
                cell.circuit,
                f"a circuit index in [0, {self.n_circuits - 1}]",
            )
            require(
                cell.robot_class in classes,
                f"cells[{k}].robot_class",
                cell.robot_class,
                f"one of the classes {list(classes)}",
            )
            require(
                len(cell.counts) == len(classes)
                and all(c <= t for c, t in zip(cell.counts, team))
                and cell.counts[classes.index(cell.robot_class)] >= 1,
                f"cells[{k}].counts",
                cell.counts,
                f"one count per class {list(classes)}, each at most the team's {list(team)}, with "
                f"at least one robot of the cell's class {cell.robot_class!r} (the robot itself)",
            )
            require(
                cell.key not in index,
                f"cells[{k}]",
                cell.key,
                "one cell per (circuit, counts, class): this one repeats an earlier cell",
            )
            index[cell.key] = cell
        missing = [
            key for key in required_cells(classes, team, self.n_circuits) if key not in index
        ]
        if missing:
            c, counts, cls = missing[0]
            raise ValueError(
                f"cells = {len(cells)} cells is invalid: {len(missing)} missing, the first "
                f"circuit {c}, counts {counts}, class {cls!r}; allowed: one cell for every "
                f"circuit, every number of robots of each class {list(classes)} up to the team's "
                f"{list(team)} (at least one robot) and every class present"
            )
        object.__setattr__(self, "classes", tuple(classes))
        object.__setattr__(self, "team", team)
        object.__setattr__(self, "n_circuits", int(self.n_circuits))
        object.__setattr__(self, "cells", cells)
        object.__setattr__(self, "switch_cost", float(self.switch_cost))
        object.__setattr__(self, "_index", index)

    # -- reading -------------------------------------------------------------------------------
    def cell(self, circuit: int, counts: Sequence[int], robot_class: str) -> TaskTimeCell:
        """The cell of a robot of `robot_class` on `circuit` with `counts` robots of each class."""
        key = (int(circuit), tuple(int(c) for c in counts), robot_class)
        found = self._index.get(key)
        if found is None:
            raise ValueError(
                f"cell {key} is not in the tables; allowed: a circuit in [0, "
                f"{self.n_circuits - 1}], one count per class {list(self.classes)} up to "
                f"{list(self.team)} and a class with at least one robot"
            )
        return found

    def check_team(self, config: ArenaConfig) -> None:
        """A ValueError naming `tables` unless they describe `config`'s team and circuits."""
        classes, team = team_classes(config)
        ours = dict(zip(self.classes, self.team))
        require(
            dict(zip(classes, team)) == ours and config.n_circuits == self.n_circuits,
            "tables",
            f"{self.n_circuits} circuits, robots per class {ours}",
            f"tables of this arena: {config.n_circuits} circuits, robots per class "
            f"{dict(zip(classes, team))}",
        )

    # -- building ------------------------------------------------------------------------------
    @classmethod
    def from_function(
        cls,
        config: ArenaConfig,
        mean_s: Callable[[int, tuple[int, ...], str], float] | float,
        sd_s: Callable[[int, tuple[int, ...], str], float] | float = 0.0,
        switch_cost: float = 1.0,
        source: str = "",
    ) -> InterferenceTables:
        """Tables for `config`'s team with every cell's mean (and sd) given by a function of
        (circuit, counts, class), or a constant: hypothetical arenas for what-if studies."""
        classes, team = team_classes(config)

        def value(f: Callable[[int, tuple[int, ...], str], float] | float, key: CellKey) -> float:
            return float(f(*key)) if callable(f) else f

        cells = tuple(
            TaskTimeCell(k, counts, c, value(mean_s, (k, counts, c)), value(sd_s, (k, counts, c)))
            for k, counts, c in required_cells(classes, team, config.n_circuits)
        )
        return cls(classes, team, config.n_circuits, cells, switch_cost, source)

    # -- JSON ----------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON-serialisable); `from_dict` reads it back."""
        return {
            "classes": list(self.classes),
            "team": list(self.team),
            "n_circuits": self.n_circuits,
            "switch_cost": self.switch_cost,
            "source": self.source,
            "cells": [cell.to_dict() for cell in self.cells],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> InterferenceTables:
        """Tables from `to_dict`'s data, checked (a ValueError names what is wrong)."""
        require(isinstance(data, Mapping), "tables", type(data).__name__, "a mapping (to_dict())")
        _keys("tables", data, _TABLE_KEYS, ("source",))
        raw_cells = _sequence("cells", data["cells"], "cell mappings")
        cells = []
        for k, raw in enumerate(raw_cells):
            require(
                isinstance(raw, Mapping), f"cells[{k}]", raw, "a mapping (TaskTimeCell.to_dict)"
            )
            _keys(f"cells[{k}]", raw, _CELL_KEYS, ("n_tasks",))
            try:
                cells.append(TaskTimeCell(**raw))
            except ValueError as error:
                raise ValueError(f"cells[{k}]: {error}") from None
        return cls(
            classes=data["classes"],
            team=data["team"],
            n_circuits=data["n_circuits"],
            cells=tuple(cells),
            switch_cost=data["switch_cost"],
            source=data.get("source", ""),
        )


def _keys(
    name: str, data: Mapping[str, Any], required: Sequence[str], optional: Sequence[str]
) -> None:
    missing = [k for k in required if k not in data]
    unknown = sorted(str(k) for k in data if k not in required and k not in optional)
    require(
        not missing and not unknown,
        name,
        f"keys {sorted(str(k) for k in data)}",
        f"the keys {list(required)} (optional: {list(optional)}); missing {missing}, "
        f"unknown {unknown}",
    )


# -- the decision process --------------------------------------------------------------------------
class TwinTasks:
    """Per-robot task state, as the env adapter reads it (the subset of
    `tavc_env.engine.tasks.TaskCycle` that `TavcArenaEnv` uses). Plain lists, not arrays: the
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
    (see the module's docstring). It offers what `TavcArenaEnv` calls on its `sim`: `reset`,
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
        # (circuit, counts, class index) -> (mean, mu, sigma) of the lognormal
        self._law: dict[tuple[int, tuple[int, ...], int], tuple[float, float, float]] = {}
        for cell in tables.cells:
            sigma = math.sqrt(math.log1p((cell.sd_s / cell.mean_s) ** 2))
            mu = math.log(cell.mean_s) - sigma * sigma / 2
            key = (cell.circuit, cell.counts, tables.classes.index(cell.robot_class))
            self._law[key] = (cell.mean_s, mu, sigma)
        self._rng: np.random.Generator | None = None
        self._clear()

    def _clear(self) -> None:
        n, m = self.config.n_robots, self.config.n_circuits
        self._committed = [[0] * len(self.classes) for _ in range(m)]
        self._due: list[tuple[float, int, int]] = []  # heap of (completion time, robot, token)
        self._token = [0] * n  # a robot's current task; older heap entries are stale
        self._duration = [0.0] * n
        self._undrawn: list[tuple[int, bool]] = []  # (robot, switch) chosen, time not drawn yet
        self._schedule: list[ScheduleEntry] = []

    @property
    def rng(self) -> np.random.Generator:
        """The generator passed to `reset` (every draw of the twin comes from it)."""
        if self._rng is None:
            raise ValueError("the twin has no random generator yet; allowed: call reset(rng) first")
        return self._rng

    def reset(self, rng: np.random.Generator) -> None:
        """Robots at the sinks, spread evenly over the circuits in an order drawn from `rng`
        (as in the physics); everyone decides."""
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
        for rank, i in enumerate(rng.permutation(cfg.n_robots)):
            self.tasks.circuit[i] = rank % cfg.n_circuits
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
            mean, mu, sigma = self._law[(k, tuple(self._committed[k]), self.robot_class[i])]
            t = math.exp(mu + sigma * rng.standard_normal()) if sigma > 0 else mean
            if switch:
                t *= self.tables.switch_cost
            self._duration[i] = t
            heapq.heappush(self._due, (tasks.decision_time[i] + t, i, self._token[i]))
        self._undrawn = []

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
        self._schedule.append(ScheduleEntry(self.time_s, Scheduled.REPAIR, robot))
        self._schedule.sort()

    def repair(self, robot: int) -> None:
        if self.tasks.phase[robot] != _BROKEN:
            return
        self.tasks.phase[robot] = _DECIDING
        # any other repair still scheduled for this robot belongs to a breakdown that is over
        self._schedule = [
            e for e in self._schedule if not (e.kind == Scheduled.REPAIR and e.robot == robot)
        ]

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
            if self._schedule:
                t_next = min(t_next, self._schedule[0].at_s)
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
            self._run_schedule(now, out)
            if stop_on_decision and (out.completions or out.repaired):
                break
        out.duration_s = self.time_s - start
        return out

    def _run_schedule(self, now: float, out: Advance) -> None:
        while self._schedule and self._schedule[0].at_s <= now + _EPS:
            _, kind, robot, after = self._schedule.pop(0)
            if kind == Scheduled.BREAK_DOWN:
                if self.tasks.phase[robot] != _BROKEN:
                    self.break_down(robot)
                    out.broken.append(robot)
                    if after > 0:
                        self._schedule.append(ScheduleEntry(now + after, Scheduled.REPAIR, robot))
                        self._schedule.sort()
            elif self.tasks.phase[robot] == _BROKEN:
                self.repair(robot)
                out.repaired.append(robot)


# -- the env -----------------------------------------------------------------------------------------
class TwinArenaEnv(TavcArenaEnv):
    """The arena's decision process as a PettingZoo `ParallelEnv`, with task times drawn from
    `tables` (see the module's docstring).

    Args:
        tables: the arena's `InterferenceTables` (or their `to_dict()`), for the team and
            circuits of the configuration.
        **env_kwargs: `TavcArenaEnv`'s arguments (`preset` or `config`, `options` and
            overrides of the arena or the options), except that the `EnvOptions`' `render_mode`
            must be None (the twin draws nothing) and `observation_mode` `paper` or `paper_id`;
            `jam_window_s` is accepted, unused (the twin never jams).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": TWIN_ENV_NAME,
        "render_modes": [],
        "render_fps": 10,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        tables: InterferenceTables | Mapping[str, Any],
        **env_kwargs: Any,
    ) -> None:
        if isinstance(tables, Mapping):
            tables = InterferenceTables.from_dict(tables)
        require(
            isinstance(tables, InterferenceTables),
            "tables",
            tables,
            "tavc_env.twin.InterferenceTables (or its to_dict())",
        )
        # TavcArenaEnv's own arguments and defaults, passed through rather than restated here
        super().__init__(**env_kwargs)
        require(
            self.render_mode is None,
            "render_mode",
            self.render_mode,
            "None (the twin draws nothing)",
        )
        require(
            self.options.observation_mode != "rich",
            "observation_mode",
            self.options.observation_mode,
            "'paper' or 'paper_id' (the twin has no positions for 'rich')",
        )
        self.tables = tables
        self.process = TaskTimeProcess(self.config, tables)
        # The adapter (`TavcArenaEnv`) reads only what `TaskTimeProcess` offers of an engine.
        self.sim = self.process  # type: ignore[assignment]
        n, m = self.config.n_robots, self.config.n_circuits
        size = n * (m + N_PHASES) + m * len(tables.classes)
        self.state_space = spaces.Box(0.0, 1.0, (size,), np.float32)

    def state(self) -> np.ndarray:
        """Global state of the twin: per robot [circuit one-hot, phase one-hot]; per circuit and
        class, the robots of that class working on it over the class's robots."""
        if self._rng is None:
            raise ValueError("state() called before reset(); allowed: call reset() first")
        n, m = self.config.n_robots, self.config.n_circuits
        tasks = self.process.tasks
        robots = np.zeros((n, m + N_PHASES), np.float32)
        robots[np.arange(n), tasks.circuit] = 1.0
        robots[np.arange(n), m + np.array(tasks.phase)] = 1.0
        shares = self.process.committed() / np.array(self.tables.team, dtype=float)
        return np.concatenate([robots.ravel(), shares.astype(np.float32).ravel()])

    def snapshot(self) -> ArenaSnapshot:
        raise ValueError(
            "the twin has no arena to take a snapshot of (no positions); allowed: state(), the "
            "infos, or the physics env (tavc_env.parallel_env) for snapshots"
        )

    def __setstate__(self, state: dict[str, Any]) -> None:
        super().__setstate__(state)
        if self._history is not None:  # the copy's process carries the copied episode's history
            _HISTORIES[self.sim] = self._history


def twin_parallel_env(
    tables: InterferenceTables | Mapping[str, Any], **kwargs: Any
) -> TwinArenaEnv:
    """The twin as a PettingZoo ParallelEnv: `tables` plus `tavc_env.parallel_env`'s keyword
    arguments (see `TwinArenaEnv`)."""
    return TwinArenaEnv(tables, **kwargs)
