"""The task cycle: stations, waiting lines, legs, task timing. No physics and no learning here.

A task starts when a robot standing at a sink chooses a circuit: it drives to that circuit's source,
waits its turn, is loaded, drives to the circuit's sink, waits its turn, is unloaded, and the task
is complete (the robot's next decision epoch). The task time runs from the decision to the end of
unloading.

A station (one source and one sink per circuit) serves one robot at a time in each of its bays
(`station_bays`, one by default: a single dock). A robot that comes within `join_radius_m` of a
station's dock joins its line: if a bay is free and nobody waits, it drives into the free bay
nearest the dock, otherwise it drives to the next free waiting slot beside the dock and waits
there. When a robot's service ends it leaves its bay, and the robot at the head of the line drives
into that bay. The line is first come first served and stands in space: waiting robots are
obstacles.

A line longer than its first row (the row along the wall from the dock) stands in several rows
across the approach to the dock, and a robot driving at the dock would push into them. So while
the next free slot lies beyond the first row, a robot heading for the station drives to that slot,
the end of the line, and joins within `join_radius_m` of it; it is aimed again whenever the line
grows or shrinks. Lines within their first row, all that the shipped six-robot arenas ever form,
are approached at the dock as before.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from tavc_env.config import ArenaConfig
from tavc_env.engine import navigation as rules
from tavc_env.engine.navigation import TaskArrays
from tavc_env.layout import stack_rows


class Phase(enum.IntEnum):
    """What a robot is doing, as reported in infos."""

    DECIDING = rules.DECIDING
    TO_SOURCE = rules.TO_SOURCE
    TO_SINK = rules.TO_SINK
    BROKEN = rules.BROKEN


PHASE_NAMES = {
    Phase.DECIDING: "deciding",
    Phase.TO_SOURCE: "to_source",
    Phase.TO_SINK: "to_sink",
    Phase.BROKEN: "broken",
}


class Mode(enum.IntEnum):
    """How a robot moves within its phase."""

    IDLE = rules.IDLE  # deciding or broken: stands still
    TRAVEL = rules.TRAVEL  # driving toward a station
    QUEUED = rules.QUEUED  # in a station's line, at (or driving to) its waiting slot
    DOCKING = rules.DOCKING  # the station is its: driving onto the dock
    SERVICE = rules.SERVICE  # standing on the dock while loaded / unloaded


NEVER = rules.NEVER


class Station:
    """Bays serving one robot each (the first is the dock), with one line of waiting slots: a
    view of station `k` in the task cycle's arrays."""

    def __init__(self, arrays: TaskArrays, k: int) -> None:
        self._arrays = arrays
        self._k = k

    @property
    def docks(self) -> np.ndarray:
        """(bays, 2) bay positions, the dock first."""
        return self._arrays.docks[self._k, : self._arrays.n_bays[self._k]]

    @property
    def slots(self) -> np.ndarray:
        """(k, 2) waiting positions, in the order the line fills them."""
        return self._arrays.slots[self._k, : self._arrays.n_slots[self._k]]

    @property
    def first_row(self) -> int:
        """How many of `slots` stand in the first row, along the wall from the dock."""
        return int(self._arrays.first_row[self._k])

    @property
    def service_s(self) -> float:
        return float(self._arrays.service_s[self._k])

    @property
    def occupants(self) -> list[int]:
        """Per bay, the robot in it or -1."""
        return self._arrays.occupants[self._k, : self._arrays.n_bays[self._k]].tolist()

    @property
    def line(self) -> list[int]:
        """The waiting robots, head first."""
        return self._arrays.line[self._k, : self._arrays.line_len[self._k]].tolist()

    @property
    def dock(self) -> np.ndarray:
        return self.docks[0]

    @property
    def occupant(self) -> int:
        """The robot in the first bay (the dock), or -1: a one-bay station's occupant."""
        return int(self._arrays.occupants[self._k, 0])

    @property
    def busy(self) -> float:
        """The fraction of bays in use."""
        occupants = self.occupants
        return sum(o >= 0 for o in occupants) / len(occupants)

    def free_bay(self) -> int:
        """The free bay nearest the dock, or -1."""
        return int(rules.free_bay(self._arrays, self._k))


@dataclass(frozen=True)
class Completion:
    """A finished task: robot `robot` delivered on `circuit` after `task_time_s` seconds."""

    robot: int
    circuit: int
    task_time_s: float
    time_s: float


class TaskCycle:
    """Per-robot task state and the stations, in arrays (`arrays`) that the compiled rules of
    `tavc_env.engine.navigation` advance, inside the compiled tick or through the methods here."""

    def __init__(self, config: ArenaConfig) -> None:
        self.config = config
        n = config.n_robots
        # Station k is the source (k even) or sink (k odd) of circuit k // 2.
        k_stations = len(config.stations())
        rows = [config.waiting_rows(k, max(n - 1, 1)) for k in range(k_stations)]
        slots = [stack_rows(r) for r in rows]
        docks = [config.bays(k) for k in range(k_stations)]
        most_slots = max(len(s) for s in slots)
        most_bays = max(len(d) for d in docks)
        padded_slots = np.zeros((k_stations, most_slots, 2))
        padded_docks = np.zeros((k_stations, most_bays, 2))
        for k in range(k_stations):
            padded_slots[k, : len(slots[k])] = slots[k]
            padded_docks[k, : len(docks[k])] = docks[k]
        self.values = np.array([c.value for c in config.circuits], dtype=float)
        speeds = np.array([r.speed for r in config.robots], dtype=float)
        self.arrays = TaskArrays(
            phase=np.zeros(n, dtype=np.int64),
            mode=np.zeros(n, dtype=np.int64),
            circuit=np.zeros(n, dtype=np.int64),
            station=np.full(n, -1, dtype=np.int64),
            bay=np.full(n, -1, dtype=np.int64),
            decision_time=np.zeros(n),
            service_until=np.full(n, math.inf),
            trigger=np.full(n, NEVER),
            target=np.zeros((n, 2)),
            completed=np.zeros(n, dtype=np.int64),
            moving=np.zeros(n, dtype=np.bool_),
            service_scale=(
                config.service_reference_speed / speeds
                if config.service_scales_with_speed
                else np.ones(n)
            ),
            docks=padded_docks,
            n_bays=np.array([len(d) for d in docks], dtype=np.int64),
            slots=padded_slots,
            n_slots=np.array([len(s) for s in slots], dtype=np.int64),
            first_row=np.array([len(r[0]) if r else 0 for r in rows], dtype=np.int64),
            service_s=np.array(
                [
                    config.sink_service_s if k % 2 else config.source_service_s
                    for k in range(k_stations)
                ],
                dtype=float,
            ),
            occupants=np.full((k_stations, most_bays), -1, dtype=np.int64),
            line=np.full((k_stations, max(n, 1)), -1, dtype=np.int64),
            line_len=np.zeros(k_stations, dtype=np.int64),
            join_radius_m=float(config.join_radius_m),
            dock_tolerance_m=float(config.dock_tolerance_m),
        )
        self.stations = [Station(self.arrays, k) for k in range(k_stations)]
        a = self.arrays
        self.phase, self.mode, self.circuit = a.phase, a.mode, a.circuit
        self.station, self.bay = a.station, a.bay
        self.decision_time, self.service_until = a.decision_time, a.service_until
        self.trigger, self.target, self.moving = a.trigger, a.target, a.moving
        self.completed, self.service_scale = a.completed, a.service_scale

    # -- queries -------------------------------------------------------------------------------
    def needs_decision(self) -> np.ndarray:
        return self.phase == rules.DECIDING

    def source_of(self, circuit: int) -> int:
        return 2 * circuit

    def sink_of(self, circuit: int) -> int:
        return 2 * circuit + 1

    def completion(self, i: int, now: float) -> Completion:
        """Robot i's task, completed at `now`."""
        return Completion(
            robot=i,
            circuit=int(self.circuit[i]),
            task_time_s=now - self.decision_time[i],
            time_s=now,
        )

    # -- transitions (the compiled rules) --------------------------------------------------------
    def start(self, i: int, circuit: int) -> None:
        """Robot i begins, standing at circuit's sink, waiting for its first decision."""
        self.phase[i] = rules.DECIDING
        rules.set_mode(self.arrays, i, rules.IDLE)
        self.circuit[i] = circuit
        self.station[i] = -1
        self.bay[i] = -1
        self.trigger[i] = NEVER
        self.service_until[i] = math.inf

    def choose(self, i: int, circuit: int, now: float) -> None:
        """Robot i (deciding) starts a task on `circuit`."""
        rules.choose_fields(i, circuit, now, *self.arrays)

    def arrive(self, i: int, now: float) -> None:
        """Robot i reached the distance that fires its current trigger."""
        rules.arrive(self.arrays, i, now)

    def finish_service(self, i: int, now: float) -> Completion | None:
        """Robot i's loading or unloading ended; returns the completed task after unloading."""
        return self.completion(i, now) if rules.finish_service(self.arrays, i) else None

    def break_down(self, i: int) -> None:
        """Robot i stops serving: it leaves any line or dock; its task is abandoned."""
        rules.break_down(self.arrays, i)

    def repair(self, i: int) -> None:
        """Robot i is back: it must decide where to go next (its last circuit stays its state)."""
        self.phase[i] = rules.DECIDING
        rules.set_mode(self.arrays, i, rules.IDLE)
