"""The model twin's interference tables: an arena's task times by circuit, speed class and
crowding, and its switch cost (what `TaskTimeProcess` draws task times from; measured in the
physics by `tavc_env.twin.measure`)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tavc_env.config import ArenaConfig
from tavc_env.validation import is_integer, is_number, require

CellKey = tuple[int, tuple[int, ...], str]
"""(circuit, robots of each class on it, the robot's class)"""
_TABLE_KEYS = ("classes", "team", "n_circuits", "cells", "switch_cost")
_LEARNER_KEYS = ("class_switch_costs", "first_own_cells", "first_switch_cells")
"""the optional keys of tables measured among learners (`tavc_env.twin.learner_tables`)"""
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

    def lognormal(self) -> tuple[float, float]:
        """(mu, sigma) of the lognormal with this cell's mean and sd (moments matched: see
        `tavc_env.twin`)."""
        sigma = math.sqrt(math.log1p((self.sd_s / self.mean_s) ** 2))
        return math.log(self.mean_s) - sigma * sigma / 2, sigma

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

    Tables measured among learners (`tavc_env.twin.learner_tables`) say three things more, each
    optional (empty: the twin as it was, `tavc_twin_v0`'s draws unchanged):

    * `class_switch_costs`: one switch cost per class (in `classes`' order), instead of
      `switch_cost` for all;
    * `first_own_cells` and `first_switch_cells`: the time of each robot's first task, from the
      start allocation, by the cell it was decided in, when it stays on its start circuit or
      leaves it (no switch cost applied on top: the cells are what such first tasks took). Both
      or neither, each with every cell of `cells`.

    Every cell must be there, once; anything else is a ValueError naming the field.
    """

    classes: tuple[str, ...]
    team: tuple[int, ...]
    n_circuits: int
    cells: tuple[TaskTimeCell, ...]
    switch_cost: float = 1.0
    source: str = ""
    class_switch_costs: tuple[float, ...] = ()
    first_own_cells: tuple[TaskTimeCell, ...] = ()
    first_switch_cells: tuple[TaskTimeCell, ...] = ()
    _index: dict[CellKey, TaskTimeCell] = field(init=False, repr=False, compare=False)
    _first: dict[tuple[bool, CellKey], TaskTimeCell] = field(init=False, repr=False, compare=False)

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
        costs = _sequence("class_switch_costs", self.class_switch_costs, "switch costs")
        require(
            len(costs) in (0, len(classes)) and all(is_number(c) and c > 0 for c in costs),
            "class_switch_costs",
            self.class_switch_costs,
            f"empty, or one finite factor > 0 per class {list(classes)}",
        )
        cells = self._checked_cells("cells", self.cells, classes, team)
        first_own = self._checked_cells("first_own_cells", self.first_own_cells, classes, team)
        first_switch = self._checked_cells(
            "first_switch_cells", self.first_switch_cells, classes, team
        )
        require(
            bool(first_own) == bool(first_switch),
            "first_own_cells",
            f"{len(first_own)} cells (first_switch_cells: {len(first_switch)})",
            "both first-task tables or neither",
        )
        object.__setattr__(self, "classes", tuple(classes))
        object.__setattr__(self, "team", team)
        object.__setattr__(self, "n_circuits", int(self.n_circuits))
        object.__setattr__(self, "cells", cells)
        object.__setattr__(self, "switch_cost", float(self.switch_cost))
        object.__setattr__(self, "class_switch_costs", tuple(float(c) for c in costs))
        object.__setattr__(self, "first_own_cells", first_own)
        object.__setattr__(self, "first_switch_cells", first_switch)
        object.__setattr__(self, "_index", {cell.key: cell for cell in cells})
        first = {(False, c.key): c for c in first_own} | {(True, c.key): c for c in first_switch}
        object.__setattr__(self, "_first", first)

    def _checked_cells(
        self, name: str, given: object, classes: Sequence[str], team: Sequence[int]
    ) -> tuple[TaskTimeCell, ...]:
        """`given` as cells, each valid for these tables; complete (every required cell once)
        unless empty and optional (not `cells`)."""
        cells = _sequence(name, given, "tavc_env.twin.TaskTimeCell")
        if not cells and name != "cells":
            return ()
        index: dict[CellKey, TaskTimeCell] = {}
        for k, cell in enumerate(cells):
            require(
                isinstance(cell, TaskTimeCell), f"{name}[{k}]", cell, "a tavc_env.twin.TaskTimeCell"
            )
            require(
                cell.circuit < self.n_circuits,
                f"{name}[{k}].circuit",
                cell.circuit,
                f"a circuit index in [0, {self.n_circuits - 1}]",
            )
            require(
                cell.robot_class in classes,
                f"{name}[{k}].robot_class",
                cell.robot_class,
                f"one of the classes {list(classes)}",
            )
            require(
                len(cell.counts) == len(classes)
                and all(c <= t for c, t in zip(cell.counts, team))
                and cell.counts[classes.index(cell.robot_class)] >= 1,
                f"{name}[{k}].counts",
                cell.counts,
                f"one count per class {list(classes)}, each at most the team's {list(team)}, with "
                f"at least one robot of the cell's class {cell.robot_class!r} (the robot itself)",
            )
            require(
                cell.key not in index,
                f"{name}[{k}]",
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
                f"{name} = {len(cells)} cells is invalid: {len(missing)} missing, the first "
                f"circuit {c}, counts {counts}, class {cls!r}; allowed: one cell for every "
                f"circuit, every number of robots of each class {list(classes)} up to the team's "
                f"{list(team)} (at least one robot) and every class present"
            )
        return tuple(cells)

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

    def first_cell(
        self, circuit: int, counts: Sequence[int], robot_class: str, switch: bool
    ) -> TaskTimeCell | None:
        """The cell of a robot's first task (None: these tables have no first-task cells)."""
        if not self._first:
            return None
        self.cell(circuit, counts, robot_class)  # a ValueError naming a bad key
        return self._first[
            (bool(switch), (int(circuit), tuple(int(c) for c in counts), robot_class))
        ]

    def class_switch_cost(self, robot_class: str) -> float:
        """The factor on a switching task's time for a robot of `robot_class`."""
        require(
            robot_class in self.classes, "robot_class", robot_class, f"one of {list(self.classes)}"
        )
        if not self.class_switch_costs:
            return self.switch_cost
        return self.class_switch_costs[self.classes.index(robot_class)]

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
        data: dict[str, Any] = {
            "classes": list(self.classes),
            "team": list(self.team),
            "n_circuits": self.n_circuits,
            "switch_cost": self.switch_cost,
            "source": self.source,
            "cells": [cell.to_dict() for cell in self.cells],
        }
        if self.class_switch_costs:  # absent, not empty: older tables' data (and digests) stay
            data["class_switch_costs"] = list(self.class_switch_costs)
        if self.first_own_cells:
            data["first_own_cells"] = [cell.to_dict() for cell in self.first_own_cells]
            data["first_switch_cells"] = [cell.to_dict() for cell in self.first_switch_cells]
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> InterferenceTables:
        """Tables from `to_dict`'s data, checked (a ValueError names what is wrong)."""
        require(isinstance(data, Mapping), "tables", type(data).__name__, "a mapping (to_dict())")
        _keys("tables", data, _TABLE_KEYS, ("source", *_LEARNER_KEYS))
        return cls(
            classes=data["classes"],
            team=data["team"],
            n_circuits=data["n_circuits"],
            cells=_cells_from("cells", data["cells"]),
            switch_cost=data["switch_cost"],
            source=data.get("source", ""),
            class_switch_costs=data.get("class_switch_costs", ()),
            first_own_cells=_cells_from("first_own_cells", data.get("first_own_cells", ())),
            first_switch_cells=_cells_from(
                "first_switch_cells", data.get("first_switch_cells", ())
            ),
        )


def _cells_from(name: str, given: object) -> tuple[TaskTimeCell, ...]:
    cells = []
    for k, raw in enumerate(_sequence(name, given, "cell mappings")):
        require(isinstance(raw, Mapping), f"{name}[{k}]", raw, "a mapping (TaskTimeCell.to_dict)")
        _keys(f"{name}[{k}]", raw, _CELL_KEYS, ("n_tasks",))
        try:
            cells.append(TaskTimeCell(**raw))
        except ValueError as error:
            raise ValueError(f"{name}[{k}]: {error}") from None
    return tuple(cells)


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


def as_tables(tables: object) -> InterferenceTables:
    """`tables` as `InterferenceTables`: the tables themselves, or their `to_dict()` (checked);
    anything else is a ValueError naming what is allowed."""
    if isinstance(tables, Mapping):
        tables = InterferenceTables.from_dict(tables)
    require(
        isinstance(tables, InterferenceTables),
        "tables",
        tables,
        "tavc_env.twin.InterferenceTables (or its to_dict())",
    )
    assert isinstance(tables, InterferenceTables)
    return tables
