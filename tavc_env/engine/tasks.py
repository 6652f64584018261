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
from dataclasses import dataclass, field

import numpy as np

from tavc_env.config import ArenaConfig
from tavc_env.layout import stack_rows


class Phase(enum.IntEnum):
    """What a robot is doing, as reported in infos."""

    DECIDING = 0
    TO_SOURCE = 1
    TO_SINK = 2
    BROKEN = 3


PHASE_NAMES = {
    Phase.DECIDING: "deciding",
    Phase.TO_SOURCE: "to_source",
    Phase.TO_SINK: "to_sink",
    Phase.BROKEN: "broken",
}


class Mode(enum.IntEnum):
    """How a robot moves within its phase."""

    IDLE = 0  # deciding or broken: stands still
    TRAVEL = 1  # driving toward a station
    QUEUED = 2  # in a station's line, at (or driving to) its waiting slot
    DOCKING = 3  # the station is its: driving onto the dock
    SERVICE = 4  # standing on the dock while loaded / unloaded


NEVER = -1.0
# The codes as plain ints for the rules below: comparing a numpy scalar with an IntEnum member
# goes through the enum class's attribute lookup and a conversion, at every event
_DECIDING, _TO_SOURCE, _TO_SINK, _BROKEN = (int(p) for p in Phase)
_IDLE, _TRAVEL, _QUEUED, _DOCKING, _SERVICE = (int(m) for m in Mode)
_FIRST_MOVING = _TRAVEL
_LAST_MOVING = _DOCKING


@dataclass
class Station:
    """Bays serving one robot each (the first is the dock), with one line of waiting slots."""

    docks: np.ndarray  # (bays, 2) bay positions, the dock first
    slots: np.ndarray  # (k, 2) waiting positions, in the order the line fills them
    first_row: int  # how many of `slots` stand in the first row, along the wall from the dock
    service_s: float
    occupants: list[int] = field(default_factory=list)  # per bay, the robot in it or -1
    line: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.occupants:
            self.occupants = [-1] * len(self.docks)

    @property
    def dock(self) -> np.ndarray:
        return self.docks[0]

    @property
    def occupant(self) -> int:
        """The robot in the first bay (the dock), or -1: a one-bay station's occupant."""
        return self.occupants[0]

    @property
    def busy(self) -> float:
        """The fraction of bays in use."""
        return sum(o >= 0 for o in self.occupants) / len(self.occupants)

    def free_bay(self) -> int:
        """The free bay nearest the dock, or -1."""
        return next((b for b, o in enumerate(self.occupants) if o < 0), -1)


@dataclass(frozen=True)
class Completion:
    """A finished task: robot `robot` delivered on `circuit` after `task_time_s` seconds."""

    robot: int
    circuit: int
    task_time_s: float
    time_s: float


class TaskCycle:
    """Per-robot task state and the stations; advanced by the simulation at events only."""

    def __init__(self, config: ArenaConfig) -> None:
        self.config = config
        n = config.n_robots
        # Station k is the source (k even) or sink (k odd) of circuit k // 2.
        self.stations = []
        for k in range(len(config.stations())):
            rows = config.waiting_rows(k, max(n - 1, 1))
            self.stations.append(
                Station(
                    docks=config.bays(k),
                    slots=stack_rows(rows),
                    first_row=len(rows[0]) if rows else 0,
                    service_s=config.source_service_s if k % 2 == 0 else config.sink_service_s,
                )
            )
        self.values = np.array([c.value for c in config.circuits], dtype=float)
        speeds = np.array([r.speed for r in config.robots], dtype=float)
        self.service_scale = (
            config.service_reference_speed / speeds
            if config.service_scales_with_speed
            else np.ones(n)
        )
        self.phase = np.zeros(n, dtype=np.int64)
        self.mode = np.zeros(n, dtype=np.int64)
        self.circuit = np.zeros(n, dtype=np.int64)
        self.station = np.full(n, -1, dtype=np.int64)
        self.bay = np.full(n, -1, dtype=np.int64)  # the bay a docking or served robot holds
        self.decision_time = np.zeros(n)
        self.service_until = np.full(n, math.inf)
        self.trigger = np.full(n, NEVER)  # distance to target that fires an event; NEVER: none
        self.target = np.zeros((n, 2))
        self.completed = np.zeros(n, dtype=np.int64)
        self.moving = np.zeros(n, dtype=np.bool_)  # robots driving toward a target (kept in sync)

    # -- queries -------------------------------------------------------------------------------
    def _set_mode(self, i: int, mode: int) -> None:
        self.mode[i] = mode
        self.moving[i] = _FIRST_MOVING <= mode <= _LAST_MOVING

    def needs_decision(self) -> np.ndarray:
        return self.phase == _DECIDING

    def source_of(self, circuit: int) -> int:
        return 2 * circuit

    def sink_of(self, circuit: int) -> int:
        return 2 * circuit + 1

    # -- transitions ---------------------------------------------------------------------------
    def start(self, i: int, circuit: int) -> None:
        """Robot i begins, standing at circuit's sink, waiting for its first decision."""
        self.phase[i] = _DECIDING
        self._set_mode(i, _IDLE)
        self.circuit[i] = circuit
        self.station[i] = -1
        self.bay[i] = -1
        self.trigger[i] = NEVER
        self.service_until[i] = math.inf

    def choose(self, i: int, circuit: int, now: float) -> None:
        """Robot i (deciding) starts a task on `circuit`."""
        self.phase[i] = _TO_SOURCE
        self.circuit[i] = circuit
        self.decision_time[i] = now
        self._travel_to(i, self.source_of(circuit))

    def _travel_to(self, i: int, station: int) -> None:
        self.station[i] = station
        self._set_mode(i, _TRAVEL)
        self._aim(i, self.stations[station])

    def _aim(self, i: int, st: Station) -> None:
        """Robot i, travelling to `st`, drives at its dock, or at the end of a line that has
        spilled beyond its first row."""
        tail = len(st.line)
        self.target[i] = st.slots[tail] if st.first_row <= tail < len(st.slots) else st.dock
        self.trigger[i] = self.config.join_radius_m

    def _line_changed(self, station: int) -> None:
        """Re-aim the robots travelling to `station` and move its waiting robots up."""
        st = self.stations[station]
        for k, j in enumerate(st.line):
            self.target[j] = st.slots[k]
        for traveller in np.flatnonzero((self.mode == _TRAVEL) & (self.station == station)):
            self._aim(int(traveller), st)

    def arrive(self, i: int, now: float) -> None:
        """Robot i reached the distance that fires its current trigger."""
        if self.mode[i] == _TRAVEL:
            self._join(i)
        elif self.mode[i] == _DOCKING:
            st = self.stations[self.station[i]]
            self._set_mode(i, _SERVICE)
            self.trigger[i] = NEVER
            self.service_until[i] = now + st.service_s * self.service_scale[i]

    def _join(self, i: int) -> None:
        st = self.stations[self.station[i]]
        bay = st.free_bay()
        if bay >= 0 and not st.line:
            self._dock(i, st, bay)
        else:
            st.line.append(i)
            self._set_mode(i, _QUEUED)
            self.trigger[i] = NEVER
            self._line_changed(int(self.station[i]))

    def _dock(self, i: int, st: Station, bay: int) -> None:
        st.occupants[bay] = i
        self.bay[i] = bay
        self._set_mode(i, _DOCKING)
        self.target[i] = st.docks[bay]
        self.trigger[i] = self.config.dock_tolerance_m

    def _release(self, i: int) -> None:
        """Robot i leaves its bay; the head of the line, if any, takes it."""
        station, bay = int(self.station[i]), int(self.bay[i])
        st = self.stations[station]
        st.occupants[bay] = -1
        self.bay[i] = -1
        if st.line:
            head = st.line.pop(0)
            self._dock(head, st, bay)
            self._line_changed(station)

    def finish_service(self, i: int, now: float) -> Completion | None:
        """Robot i's loading or unloading ended; returns the completed task after unloading."""
        self.service_until[i] = math.inf
        self._release(i)
        c = int(self.circuit[i])
        if self.phase[i] == _TO_SOURCE:
            self.phase[i] = _TO_SINK
            self._travel_to(i, self.sink_of(c))
            return None
        self.phase[i] = _DECIDING
        self._set_mode(i, _IDLE)
        self.station[i] = -1
        self.trigger[i] = NEVER
        self.completed[i] += 1
        return Completion(robot=i, circuit=c, task_time_s=now - self.decision_time[i], time_s=now)

    def break_down(self, i: int) -> None:
        """Robot i stops serving: it leaves any line or dock; its task is abandoned."""
        s = self.station[i]
        if s >= 0:
            st = self.stations[s]
            if self.bay[i] >= 0:
                self._release(i)
            elif i in st.line:
                st.line.remove(i)
                self._line_changed(int(s))
        self.phase[i] = _BROKEN
        self._set_mode(i, _IDLE)
        self.station[i] = -1
        self.trigger[i] = NEVER
        self.service_until[i] = math.inf

    def repair(self, i: int) -> None:
        """Robot i is back: it must decide where to go next (its last circuit stays its state)."""
        self.phase[i] = _DECIDING
        self._set_mode(i, _IDLE)
