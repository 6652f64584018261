"""What every engine of the arena shares: the `Engine` protocol the env drives, the result of an
`advance`, and the schedule of breakdowns and repairs.

Two engines implement the protocol: the physics (`tavc_env.engine.simulation.Simulation`) and the
model twin's task-time process (`tavc_env.twin.engine.TaskTimeProcess`). The env
(`tavc_env.env.ArenaEnv`) reads and drives nothing else of either.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

import numpy as np

from tavc_env.config import ArenaConfig
from tavc_env.engine.tasks import Completion

SCHEDULE_EPS_S = 1e-9  # an entry due within this of now is due now (times are sums of floats)


@dataclass
class Advance:
    """What happened during one call to an engine's `advance`."""

    completions: list[Completion] = field(default_factory=list)
    repaired: list[int] = field(default_factory=list)
    broken: list[int] = field(default_factory=list)
    duration_s: float = 0.0


class TaskView(Protocol):
    """Per-robot task state as the env reads it, one robot at a time (arrays or lists)."""

    @property
    def phase(self) -> Sequence[int] | np.ndarray:
        """`Phase` codes."""

    @property
    def circuit(self) -> Sequence[int] | np.ndarray:
        """The circuit of each robot's current or last task."""

    @property
    def decision_time(self) -> Sequence[float] | np.ndarray:
        """When each robot last decided."""

    @property
    def completed(self) -> Sequence[int] | np.ndarray:
        """Tasks each robot completed since reset."""

    @property
    def values(self) -> np.ndarray:
        """The value of a delivery on each circuit now."""

    def needs_decision(self) -> np.ndarray:
        """Which robots must decide now (bool per robot)."""


class Engine(Protocol):
    """An arena's decision process, as the env drives it: reset with a generator, robots choose
    circuits, time advances from event to event; breakdowns, repairs and value changes come
    between. Every random draw comes from the generator given to `reset`."""

    @property
    def config(self) -> ArenaConfig: ...

    @property
    def tasks(self) -> TaskView: ...

    @property
    def time_s(self) -> float:
        """Simulated seconds since reset."""

    @property
    def rng(self) -> np.random.Generator:
        """The generator given to `reset` (a ValueError before)."""

    @property
    def jam_window_s(self) -> float: ...

    @property
    def jammed(self) -> bool: ...

    @property
    def jams(self) -> int: ...

    @property
    def time_jammed_s(self) -> float: ...

    @property
    def escapes(self) -> int: ...

    def reset(self, rng: np.random.Generator) -> None: ...

    def choose(self, robot: int, circuit: int) -> None:
        """A deciding robot starts a task on `circuit`."""

    def advance(self, max_duration_s: float, stop_on_decision: bool = True) -> Advance:
        """Run until a robot must decide (if `stop_on_decision`) or `max_duration_s` passed."""

    def break_down(self, robot: int) -> None: ...

    def schedule_repair(self, robot: int) -> None:
        """Repair `robot` in the next `advance` (a decision epoch like a scheduled repair)."""

    def broken(self) -> np.ndarray: ...

    def set_circuit_values(self, values: np.ndarray) -> None: ...


# -- the schedule of breakdowns and repairs ----------------------------------------------------------
class Scheduled(enum.IntEnum):
    """What a schedule entry does (breakdowns sort before repairs at the same time)."""

    BREAK_DOWN = 0
    REPAIR = 1


class ScheduleEntry(NamedTuple):
    """A breakdown or repair due at `at_s`; a breakdown's `repair_after_s` schedules its repair
    (negative: none). Entries sort by time, then kind, then robot."""

    at_s: float
    kind: Scheduled
    robot: int
    repair_after_s: float = -1.0


class Repairable(Protocol):
    """What running a schedule does to an engine."""

    def is_broken(self, robot: int) -> bool: ...

    def break_down(self, robot: int) -> None: ...

    def repair(self, robot: int) -> None: ...


def start_allocation(config: ArenaConfig, rng: np.random.Generator) -> list[tuple[int, int]]:
    """Where each robot starts, as `(robot, circuit)` in the order robots take their places at
    the sinks (the first of a circuit at its dock, the next ones in its waiting line):
    `config.start_circuits` in robot order if given, else an even spread over the circuits in an
    order drawn from `rng` (never by speed). Both engines start so."""
    if config.start_circuits:
        return list(enumerate(config.start_circuits))
    m = config.n_circuits
    return [(int(i), rank % m) for rank, i in enumerate(rng.permutation(config.n_robots))]


def breakdown_schedule(config: ArenaConfig) -> list[ScheduleEntry]:
    """The config's scheduled breakdowns as schedule entries, in time order (-1: no repair)."""
    return sorted(
        ScheduleEntry(
            b.at_s,
            Scheduled.BREAK_DOWN,
            b.robot,
            -1.0 if b.repair_after_s is None else b.repair_after_s,
        )
        for b in config.breakdowns
    )


def add_repair(schedule: list[ScheduleEntry], at_s: float, robot: int) -> None:
    """Schedule a repair of `robot` at `at_s`, keeping `schedule` in order."""
    schedule.append(ScheduleEntry(at_s, Scheduled.REPAIR, robot))
    schedule.sort()


def without_repairs(schedule: list[ScheduleEntry], robot: int) -> list[ScheduleEntry]:
    """`schedule` less the repairs of `robot` (once it is repaired, any other repair still
    scheduled for it belongs to a breakdown that is over)."""
    return [e for e in schedule if not (e.kind == Scheduled.REPAIR and e.robot == robot)]


def next_due_s(schedule: list[ScheduleEntry]) -> float:
    """When the first entry of `schedule` is due (math.inf: none)."""
    return schedule[0].at_s if schedule else float("inf")


def run_due(schedule: list[ScheduleEntry], now: float, engine: Repairable, out: Advance) -> None:
    """Apply every entry of `schedule` due at `now`, in order: a breakdown of a robot that is not
    broken breaks it (and schedules its repair, if any), a repair of a broken one repairs it;
    `out` records both."""
    while schedule and schedule[0].at_s <= now + SCHEDULE_EPS_S:
        _, kind, robot, after = schedule.pop(0)
        if kind == Scheduled.BREAK_DOWN:
            if not engine.is_broken(robot):
                engine.break_down(robot)
                out.broken.append(robot)
                if after > 0:
                    add_repair(schedule, now + after, robot)
        elif engine.is_broken(robot):
            engine.repair(robot)
            out.repaired.append(robot)
