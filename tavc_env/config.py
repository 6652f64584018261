"""Configuration of the prioritized transportation arena: frozen, validated dataclasses and presets.

Everything physical about an arena lives here (geometry, robots, stations, controller limits, the
physics step and scheduled breakdowns). RL-facing options (time limits, reward units, stepping mode)
are the environment's, not the arena's (`tavc_env.options.EnvOptions`).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tavc_env.layout import WALL_CLEARANCE_M, stack_rows, waiting_rows
from tavc_env.validation import (
    integer,
    is_integer,
    point,
    real,
    require,
    require_together,
)

Point = tuple[float, float]
MAX_SPEED_M_S = 2.0  # a Pioneer-sized robot; far above the 0.2-0.3 m/s of the paper

# The physics envelope (issue 12). Measured by `python -m tests.tavc_env.test_envelope` (about
# 10 min on one core): dahl2004's lanes with 6, 16 and 24 robots (fast and slow in turn, random
# circuit choices), speed noise 0.1 and 0.3, 900 simulated s each, at radius 0.22 m with dt 0.1,
# 0.2 and 0.25 s and at radius 0.1 m with dt 0.05 s; the deepest overlap of two robots (or of a
# robot and a wall), worst of the 24 runs per ratio, against max speed x dt / radius:
#   ratio       0.10   0.15   0.20   0.25   0.30   0.35   0.40   0.45   0.50
#   overlap/r   0.000  0.004  0.000  0.015  0.059  0.050  0.071  0.119  0.236
# (an earlier run, 1200 s and 2-3 seeds: 0.093 r at 0.40, 0.21 r at 0.45, 0.32 r at 0.91 and
# 1.7 r, robots driving through each other, at 2.3). The tolerance is a tenth of the radius: 0.40
# is the largest ratio measured within it, and the bound keeps a margin below. The shipped
# presets run at 0.136 (0.3 m/s, dt 0.1 s, radius 0.22 m). Not covered by this bound: large robots
# packed tight (radius 0.4 m, 24 robots in 16 x 12 m) press 0.05 radii into each other and the
# walls even at 0.025 radii per step; that is crowding, not the step (issue 12, item 1).
MAX_STEP_OVER_RADIUS = 0.35
OVERLAP_TOLERANCE = 0.1  # deepest overlap accepted inside the envelope, in robot radii
# The avoidance weight ramps from 0 at the sensing range to 1 at contact (2 radii): at 2 radii it
# divides by zero (`navigation._steer_one`, ZeroDivisionError mid-run); just above, robots see each
# other only when touching (at 2.05 radii six dahl2004 robots needed 23 escape manoeuvres in 900 s,
# none at >= 2.3 radii).
MIN_SENSING_OVER_RADIUS = 2.5
# Positions are floats: at 1e6 m a float still resolves 1e-10 m, and the neighbour grid's cell
# numbers fit a 64-bit integer with room to spare.
MAX_ARENA_SIDE_M = 1e6
MAX_BAYS = 8  # bays per station: a loading bank, not a warehouse wall
# The shortest physics step: `max_time_s` (dt x 1e-6 / float epsilon) is then 125 h, beyond any
# run of the studies; with a shorter step the env's own default limits (a 600 s step cap) could not
# be met, and the refusal would name them instead of dt.
MIN_DT_S = 1e-4
MAX_SCALED_ROBOTS = 400  # scaled_config: the largest team it lays out in a few seconds (128 x 3)
# Circuits per arena: the validation compares every pair of stations (2000 stations: 4 million
# pairs, 32 MB), and `lane_circuits(10**400)` must be refused before it builds a list of values.
MAX_CIRCUITS = 1000
PAIR = "a pair of finite numbers (x, y) in metres"


def _items(name: str, value: object, kind: str) -> tuple[Any, ...]:
    """`value` as a tuple, refusing what is not a sequence of items (a number, None, a string, a
    mapping) with a ValueError instead of the TypeError `tuple()` would raise."""
    ok = isinstance(value, Iterable) and not isinstance(value, (str, bytes, bytearray, Mapping))
    require(ok, name, value, f"a sequence of {kind}")
    assert isinstance(value, Iterable)
    try:
        return tuple(value)
    except TypeError:  # iterable in name only: a 0-d numpy array
        require(False, name, value, f"a sequence of {kind}")
        raise


def _unit(name: str, value: object) -> Point:
    """`value` (a direction) scaled to length 1. A vector whose length a float does not hold
    (1e308 in both coordinates overflows it, 5e-324 underflows it to the smallest float) is
    first divided by its largest coordinate; any other is divided by its length directly, as it
    always was (the direction of a saved arena stays bit for bit what it was)."""
    d = point(value, name, PAIR)
    norm = math.hypot(*d)
    if not (1e-150 < norm < 1e150):
        scale = max(abs(d[0]), abs(d[1]))
        require(scale > 0, name, value, "a non-zero vector")
        d = (d[0] / scale, d[1] / scale)
        norm = math.hypot(*d)
    return (d[0] / norm, d[1] / norm)


@dataclass(frozen=True)
class Circuit:
    """One source/sink pair and the value `w` of a delivery on it.

    `queue_direction` points from each station's dock along the line where robots wait their turn
    (the first waiting slot is `queue_offset_m` from the dock, then every `queue_spacing_m`).
    """

    source: Point
    sink: Point
    value: float
    queue_direction: Point = (1.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "source", point(self.source, "circuit.source", PAIR))
        object.__setattr__(self, "sink", point(self.sink, "circuit.sink", PAIR))
        direction = _unit("circuit.queue_direction", self.queue_direction)
        object.__setattr__(self, "queue_direction", direction)
        value = real(self.value, "circuit.value", "a finite number > 0", lambda v: v > 0)
        object.__setattr__(self, "value", value)


@dataclass(frozen=True)
class Robot:
    """A robot's nominal top speed (m/s) and a speed-class label used only for reporting."""

    speed: float
    speed_class: str = ""

    def __post_init__(self) -> None:
        allowed = f"a finite speed in (0, {MAX_SPEED_M_S:g}] m/s"
        speed = real(self.speed, "robot.speed", allowed, lambda v: 0 < v <= MAX_SPEED_M_S)
        object.__setattr__(self, "speed", speed)
        # a label the reports group robots by: it must be hashable and print as text
        label = self.speed_class
        require(isinstance(label, str), "robot.speed_class", label, "a string (a label)")
        object.__setattr__(self, "speed_class", str(label))


@dataclass(frozen=True)
class Breakdown:
    """Robot `robot` (index) breaks down at `at_s` simulated seconds; repaired `repair_after_s` later
    (None: stays broken until `repair` is called)."""

    robot: int
    at_s: float
    repair_after_s: float | None = None

    def __post_init__(self) -> None:
        robot = integer(self.robot, "breakdown.robot", "a robot index >= 0", lambda i: i >= 0)
        object.__setattr__(self, "robot", robot)
        at_s = real(self.at_s, "breakdown.at_s", "a time >= 0 s", lambda v: v >= 0)
        object.__setattr__(self, "at_s", at_s)
        if self.repair_after_s is not None:
            after = real(
                self.repair_after_s,
                "breakdown.repair_after_s",
                "None or a duration > 0 s",
                lambda v: v > 0,
            )
            object.__setattr__(self, "repair_after_s", after)


def _positive(v: float) -> bool:
    return v > 0


def _non_negative(v: float) -> bool:
    return v >= 0


_SIDE = f"a side of at most {MAX_ARENA_SIDE_M:g} m and more than 0 (positions are floats)"
# Each number field of ArenaConfig: what is allowed, and the test, on its own (rules relating
# fields come after all of these, in ArenaConfig._validate).
_NUMBER_FIELDS: Mapping[str, tuple[str, Callable[[float], bool]]] = {
    "width": (_SIDE, lambda v: 0 < v <= MAX_ARENA_SIDE_M),
    "height": (_SIDE, lambda v: 0 < v <= MAX_ARENA_SIDE_M),
    **dict.fromkeys(
        (
            "robot_radius",
            "queue_offset_m",
            "queue_spacing_m",
            "join_radius_m",
            "dock_tolerance_m",
            "max_turn_rate",
            "sensing_range_m",
            "service_reference_speed",
        ),
        ("a finite number > 0", _positive),
    ),
    "source_service_s": ("a finite time >= 0 s", _non_negative),
    "sink_service_s": ("a finite time >= 0 s", _non_negative),
    "dt": (
        f"a physics step in (0, 0.5] s, at least {MIN_DT_S:g} s (a float must resolve "
        "125 h of steps to a millionth of a step)",
        lambda v: MIN_DT_S <= v <= 0.5,
    ),
    "speed_noise": ("a relative standard deviation in [0, 0.3]", lambda v: 0 <= v <= 0.3),
    "clearance_governor_m": ("0 (off) or a finite clearance > 0 m", _non_negative),
}


@dataclass(frozen=True)
class ArenaConfig:
    """The physical arena. Lengths in metres, times in seconds, speeds in m/s.

    Stations (one source and one sink per circuit) serve one robot at a time: a robot must reach the
    dock, stand there for the service time (loading at a source, unloading at a sink), and leave.
    Robots that arrive while a station is busy wait in a physical line beside it, first come first
    served. This is where most interference comes from (see DESIGN.md section 2 and the docs page
    `docs/results/interference.md`).

    With `service_scales_with_speed`, a robot's loading and unloading take the service time times
    `service_reference_speed / speed`: a faster robot is faster at the whole task, docking and
    handling included (the paper treats speed as task-processing speed). Off by default.
    """

    width: float = 12.0
    height: float = 8.0
    circuits: tuple[Circuit, ...] = ()
    robots: tuple[Robot, ...] = ()
    robot_radius: float = 0.22
    source_service_s: float = 20.0
    sink_service_s: float = 4.0
    service_scales_with_speed: bool = False
    service_reference_speed: float = 0.25
    queue_offset_m: float = 0.9
    queue_spacing_m: float = 0.6
    join_radius_m: float = 1.5
    dock_tolerance_m: float = 0.12
    speed_noise: float = 0.1
    max_turn_rate: float = 1.75
    sensing_range_m: float = 1.0
    dt: float = 0.1
    breakdowns: tuple[Breakdown, ...] = field(default_factory=tuple)
    # 0: off. Otherwise a robot drives at min(1, clearance / clearance_governor_m) of its own top
    # speed, clearance being the free space to the nearest robot in its front half-plane (see
    # tavc_env.engine.navigation). At most sensing_range_m - 2 x robot_radius: it must see the
    # robots it slows for.
    clearance_governor_m: float = 0.0
    # Bays per station: that many robots are loaded (or unloaded) side by side, each in its own
    # bay, one line waiting for whichever frees first. 1: a one-robot dock (the paper's). Bays
    # stand `queue_spacing_m` apart along the queue direction, a loading bank along the wall,
    # and the line starts `queue_offset_m` beyond the last (see tavc_env.layout).
    station_bays: int = 1
    # True: robots overtake slower ones as laser-based avoidance does. The governor measures the
    # clearance only to robots in the robot's own path (not to one it passes alongside), and a
    # robot dead ahead is passed on the side the walls leave room on (tavc_env.engine.navigation).
    # False (every preset but dahl2004_passing): the governor slows a robot for anything in its
    # front half-plane, so passing needs a wide berth.
    overtaking: bool = False
    # Where the robots stand at reset: one circuit per robot, each robot at that circuit's sink
    # (the first at the dock, the rest in its waiting line, in robot order). Empty (the default):
    # spread evenly over the circuits in an order drawn from the reset's generator.
    start_circuits: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        for name, kind in (
            ("circuits", "tavc_env.Circuit"),
            ("robots", "tavc_env.Robot"),
            ("breakdowns", "tavc_env.Breakdown"),
        ):
            object.__setattr__(self, name, _items(name, getattr(self, name), kind))
        start = _items("start_circuits", self.start_circuits, "circuit index")
        object.__setattr__(
            self, "start_circuits", tuple(int(c) if is_integer(c) else c for c in start)
        )
        # every number on its own first (and as a plain int or float), then the rules relating
        # fields (in _validate), so that a consequence is never blamed on one field alone
        for name, (allowed, ok) in _NUMBER_FIELDS.items():
            object.__setattr__(self, name, real(getattr(self, name), name, allowed, ok))
        bays = integer(
            self.station_bays,
            "station_bays",
            f"an integer in [1, {MAX_BAYS}]",
            lambda b: 1 <= b <= MAX_BAYS,
        )
        object.__setattr__(self, "station_bays", bays)
        for name in ("service_scales_with_speed", "overtaking"):
            value = getattr(self, name)
            require(isinstance(value, bool), name, value, "True or False")
        self._validate_items()
        # the stations, once (validation and layout look them up per station; not a field)
        stations = []
        for i, c in enumerate(self.circuits):
            if isinstance(c, Circuit):  # (anything else is refused by the validation)
                stations.append((f"circuits[{i}].source", c.source, c.queue_direction))
                stations.append((f"circuits[{i}].sink", c.sink, c.queue_direction))
        object.__setattr__(self, "_stations", tuple(stations))
        docks = np.array([dock for _, dock, _ in stations], dtype=float).reshape(-1, 2)
        object.__setattr__(self, "_docks", docks)
        self._validate()

    @property
    def n_circuits(self) -> int:
        return len(self.circuits)

    @property
    def n_robots(self) -> int:
        return len(self.robots)

    @property
    def max_time_s(self) -> float:
        """The longest simulated time a float still resolves to a millionth of the physics step
        (time is `ticks * dt`; beyond this the tolerances of the event checks no longer hold)."""
        return self.dt * 1e-6 / sys.float_info.epsilon

    def _validate_items(self) -> None:
        """The circuits, robots, breakdowns and start circuits, each on its own."""
        require(
            1 <= len(self.circuits) <= MAX_CIRCUITS,
            "circuits",
            self.circuits,
            f"at least one Circuit and at most {MAX_CIRCUITS}",
        )
        require(len(self.robots) >= 1, "robots", self.robots, "at least one Robot")
        for i, c in enumerate(self.circuits):
            require(isinstance(c, Circuit), f"circuits[{i}]", c, "a tavc_env.Circuit")
        for i, r in enumerate(self.robots):
            require(isinstance(r, Robot), f"robots[{i}]", r, "a tavc_env.Robot")
        for i, event in enumerate(self.breakdowns):
            require(isinstance(event, Breakdown), f"breakdowns[{i}]", event, "a tavc_env.Breakdown")
        require(
            all(is_integer(c) and c >= 0 for c in self.start_circuits),
            "start_circuits",
            self.start_circuits,
            "empty (an even spread) or circuit indices (integers >= 0), one per robot",
        )

    def _validate(self) -> None:
        """The rules relating fields; each message names every field it relates."""
        r, w, h = self.robot_radius, self.width, self.height
        require_together(
            r * 4 <= min(w, h),
            {"robot_radius": r, "width": w, "height": h},
            f"robot_radius at most a quarter of the arena's smaller side (min(width, height) / 4 "
            f"= {min(w, h) / 4} m)",
        )
        for name in ("queue_spacing_m", "queue_offset_m"):
            require_together(
                getattr(self, name) >= 2 * r,
                {name: getattr(self, name), "robot_radius": r},
                f"{name} >= the robot diameter 2 x robot_radius = {2 * r} m",
            )
        self._validate_envelope()
        margin = self.robot_radius + WALL_CLEARANCE_M
        inside = f"x in [{margin}, {self.width - margin}], y in [{margin}, {self.height - margin}]"
        stations = [(name, p) for name, p, _ in self.stations()]
        for name, p in stations:
            ok = margin <= p[0] <= self.width - margin and margin <= p[1] <= self.height - margin
            require_together(
                ok,
                {name: p, "width": w, "height": h, "robot_radius": r},
                f"a point inside the arena, robot_radius + {WALL_CLEARANCE_M} m off its walls: "
                f"{inside}",
            )
        # Two docks closer than two robot diameters would make one robot's service block the other
        # station, so the circuits would not be separate task classes.
        min_gap = 4 * self.robot_radius
        # only pairs near the limit need the exact test (numpy's distances differ from math.dist
        # in the last bit at most); they are tested in the order of the loop over all pairs
        docks = np.array([p for _, p in stations], dtype=float).reshape(-1, 2)
        near = np.hypot(*(docks[:, None, :] - docks[None, :, :]).transpose(2, 0, 1))
        for a, b in zip(*np.nonzero(np.triu(near < min_gap * (1 + 1e-6) + 1e-9, 1))):
            (na, pa), (nb, pb) = stations[int(a)], stations[int(b)]
            gap = math.dist(pa, pb)
            require_together(
                gap >= min_gap,
                {f"{nb} (distance to {na})": round(gap, 3), "robot_radius": r},
                f"stations at least 4 x robot_radius = {min_gap} m apart (overlapping circuits)",
            )
        n, m = self.n_robots, self.n_circuits
        for i, event in enumerate(self.breakdowns):
            require_together(
                event.robot < n,
                {f"breakdowns[{i}].robot": event.robot, "len(robots)": n},
                f"a robot index in [0, len(robots) - 1] = [0, {n - 1}]",
            )
        if self.start_circuits:
            require_together(
                len(self.start_circuits) == n and all(c < m for c in self.start_circuits),
                {"start_circuits": self.start_circuits, "len(robots)": n, "len(circuits)": m},
                f"empty (an even spread) or {n} circuit indices in [0, {m - 1}], one per robot",
            )
        require_together(
            _robots_fit(n, r, w, h),
            {"robots": f"{n} robots", "robot_radius": r, "width": w, "height": h},
            f"at most {_most_robots(r, w, h)} robots of radius {r} m in a {w} x {h} m arena "
            "(robots cannot fit)",
        )
        # the room at a station depends on where every station is and on these fields
        room_fields = {
            "circuits": f"{m} circuits",  # where every other station stands
            "station_bays": self.station_bays,
            "queue_spacing_m": self.queue_spacing_m,
            "queue_offset_m": self.queue_offset_m,
            "robot_radius": r,
            "width": w,
            "height": h,
        }
        for k, (name, _, _) in enumerate(self.stations()):
            fit = len(self.bays(k))
            require_together(
                fit == self.station_bays,
                {f"{name} bays": f"room for {fit} bays", **room_fields},
                f"room for all {self.station_bays} bays, {self.queue_spacing_m:g} m apart along "
                "the queue direction inside the arena and nearer their own station than any other "
                "(or: fewer bays, a smaller queue_spacing_m, circuits further apart)",
            )
        room = [len(self.waiting_slots(k, self.n_robots - 1)) for k in range(len(self.stations()))]
        for (name, _, _), held in zip(self.stations(), room):
            require_together(
                held >= self.n_robots - 1,
                {
                    f"{name} waiting line": f"room for {held} robots",
                    "len(robots)": n,
                    **room_fields,
                },
                f"room for all {self.n_robots - 1} robots that may wait there; the lines of this "
                f"arena hold a team of at most {min(room) + 1} robots (or: a larger arena, "
                "circuits further apart or another queue_direction)",
            )

    def _validate_envelope(self) -> None:
        """The physics envelope: steps short enough that robots do not interpenetrate, and a
        sensing range beyond contact (see MAX_STEP_OVER_RADIUS and MIN_SENSING_OVER_RADIUS)."""
        r = self.robot_radius
        top = max(range(self.n_robots), key=lambda i: self.robots[i].speed)
        fastest = self.robots[top].speed
        longest = MAX_STEP_OVER_RADIUS * r / fastest
        require_together(
            fastest * self.dt <= MAX_STEP_OVER_RADIUS * r * (1 + 1e-9),
            {"dt": self.dt, "robot_radius": r, f"robots[{top}].speed": fastest},
            f"a physics step of at most {MAX_STEP_OVER_RADIUS:g} x robot_radius / the top speed "
            f"= {longest:.4g} s here (radius {r:g} m, top speed {fastest:g} m/s): a robot must move "
            f"less than {MAX_STEP_OVER_RADIUS:g} radii per step or robots interpenetrate; use a "
            "smaller dt, slower robots or a larger radius",
        )
        least = MIN_SENSING_OVER_RADIUS * r
        require_together(
            self.sensing_range_m >= least * (1 - 1e-9),
            {"sensing_range_m": self.sensing_range_m, "robot_radius": r},
            f"a range of at least {MIN_SENSING_OVER_RADIUS:g} x robot_radius = {least:.4g} m "
            "(robots must sense each other before they touch at 2 x robot_radius)",
        )
        reach = self.sensing_range_m - 2 * r
        governor = self.clearance_governor_m
        require_together(
            governor <= reach * (1 + 1e-9),
            {
                "clearance_governor_m": governor,
                "sensing_range_m": self.sensing_range_m,
                "robot_radius": r,
            },
            f"0 (off) or a clearance of at most sensing_range_m - 2 x robot_radius = {reach:.4g} m "
            "(a robot can only slow for robots it senses)",
        )

    def stations(self) -> list[tuple[str, Point, Point]]:
        """(name, dock, queue direction) of every station: source then sink of each circuit."""
        return list(self._station_list())

    def _station_list(self) -> tuple[tuple[str, Point, Point], ...]:
        listed: tuple[tuple[str, Point, Point], ...] = self.__dict__["_stations"]  # not a field
        return listed

    def docks(self) -> list[Point]:
        return [dock for _, dock, _ in self.stations()]

    def waiting_rows(self, station: int, count: int) -> list[np.ndarray]:
        """Up to `count` waiting positions of station `station` (index into `stations()`), row by
        row in the order the line fills them (see `tavc_env.layout.waiting_rows`); the line
        starts `queue_offset_m` beyond the last bay."""
        offset = self.queue_offset_m + (self.station_bays - 1) * self.queue_spacing_m
        return self._rows(station, offset, count)

    def bays(self, station: int) -> np.ndarray:
        """The bay positions of station `station` (index into `stations()`): a loading bank
        along the wall, the dock first, then every `queue_spacing_m` along the queue direction.
        They follow the rule of waiting slots (inside the arena, nearer their own dock than any
        other), so fewer than `station_bays` come back if they do not fit (validation refuses
        that)."""
        rows = self._rows(station, 0.0, self.station_bays)
        return rows[0] if rows else np.zeros((0, 2))

    def _rows(self, station: int, offset: float, count: int) -> list[np.ndarray]:
        _, dock, direction = self._station_list()[station]
        others = np.delete(self.__dict__["_docks"], station, axis=0)
        return waiting_rows(
            dock,
            direction,
            others,
            self.width,
            self.height,
            self.robot_radius,
            offset,
            self.queue_spacing_m,
            count,
        )

    def waiting_slots(self, station: int, count: int) -> np.ndarray:
        """Up to `count` waiting positions of station `station`, nearest the head of the line
        first."""
        return stack_rows(self.waiting_rows(station, count))

    def replace(self, **changes: Any) -> ArenaConfig:
        """A copy with fields changed (validated again)."""
        _refuse_unknown(changes, ARENA_FIELDS)
        return dataclasses.replace(self, **changes)


def _refuse_unknown(given: Mapping[str, Any], allowed: frozenset[str]) -> None:
    unknown = sorted(set(given) - allowed)
    if unknown:
        raise ValueError(f"unknown configuration key(s) {unknown}; allowed: {sorted(allowed)}")


def _robots_fit(n: int, radius: float, width: float, height: float) -> bool:
    """Robots' footprints (with a margin) cover at most a quarter of the floor."""
    return n * (2 * radius + 0.1) ** 2 <= 0.25 * (width * height)


def _most_robots(radius: float, width: float, height: float) -> int:
    return int(0.25 * (width * height) / (2 * radius + 0.1) ** 2)


def lane_circuits(
    n_circuits: int,
    width: float = 12.0,
    height: float = 8.0,
    values: Sequence[float] | None = None,
    wall_margin: float = 1.5,
) -> tuple[Circuit, ...]:
    """Circuits as vertical lanes spread across the arena: source at the top, sink at the bottom.

    Lanes sit `wall_margin` from the side walls and are evenly spaced between, so crossing from one
    circuit's sink to another circuit's source is a long diagonal: circuits are spatially
    classifiable. Waiting lines run along the top and bottom walls toward the arena's centre.
    """
    n = integer(
        n_circuits,
        "n_circuits",
        f"an integer in [1, {MAX_CIRCUITS}]",
        lambda k: 1 <= k <= MAX_CIRCUITS,
    )
    length = "a finite length > 0 m"
    width = real(width, "width", length, _positive)
    height = real(height, "height", length, _positive)
    wall_margin = real(wall_margin, "wall_margin", length, _positive)
    require_together(
        2 * wall_margin < min(width, height),
        {"wall_margin": wall_margin, "width": width, "height": height},
        "wall_margin below half the arena's smaller side",
    )
    if values is None:
        values = [2200.0 - 200.0 * i for i in range(n)]
    worth = [float(w) for w in _circuit_values(values, n)]
    xs = (
        [width / 2]
        if n == 1
        else [wall_margin + i * (width - 2 * wall_margin) / (n - 1) for i in range(n)]
    )
    circuits = []
    for x, w in zip(xs, worth):
        direction = (1.0, 0.0) if x <= width / 2 else (-1.0, 0.0)
        circuits.append(
            Circuit(
                source=(x, height - wall_margin),
                sink=(x, wall_margin),
                value=w,
                queue_direction=direction,
            )
        )
    return tuple(circuits)


def _circuit_values(values: object, n: int) -> tuple[float | int, ...]:
    """`values` (one per circuit, `n` circuits), each checked on its own, as plain numbers."""
    kind = f"{n} circuit values (finite numbers > 0)"
    items = _items("values", values, kind)
    require(len(items) == n, "values", values, f"a sequence of {kind}")
    return tuple(
        real(w, f"values[{i}]", "a finite number > 0", _positive) for i, w in enumerate(items)
    )


def _dahl2004() -> ArenaConfig:
    fast = tuple(Robot(0.30, "fast") for _ in range(3))
    slow = tuple(Robot(0.20, "slow") for _ in range(3))
    return ArenaConfig(circuits=lane_circuits(2, values=(2200.0, 2000.0)), robots=fast + slow)


def _dahl2004_homogeneous() -> ArenaConfig:
    return ArenaConfig(
        circuits=lane_circuits(2, values=(2200.0, 2000.0)),
        robots=tuple(Robot(0.25, "medium") for _ in range(6)),
    )


def _three_circuits_three_classes() -> ArenaConfig:
    """A harder allocation problem than the paper's: three circuits of values 2200 / 2000 / 1800 in
    a 21 x 8 m arena (lanes 9 m apart, as in `dahl2004`), nine robots in three speed classes
    (three each at 0.30, 0.25 and 0.20 m/s)."""
    speeds = (0.30, 0.25, 0.20)
    labels = ("fast", "medium", "slow")
    return ArenaConfig(
        width=21.0,
        circuits=lane_circuits(3, width=21.0, values=(2200.0, 2000.0, 1800.0)),
        robots=tuple(Robot(v, label) for v, label in zip(speeds, labels) for _ in range(3)),
    )


# Arena regimes of the differentiation study (docs/tutorials/reproduce.md): overrides of the
# `dahl2004` arena, each a physical hypothesis about who yields to whom at the stations.
ARENA_REGIMES: Mapping[str, Mapping[str, Any]] = {
    # one-robot docks, 20 s loading and 4 s unloading whatever the robot (the default)
    "stations": {},
    # loading and unloading at the robot's own pace: speed as task-processing speed
    "competence": {"service_scales_with_speed": True},
    # short docks: little queueing, interference mostly from traffic
    "light_stations": {"source_service_s": 6.0, "sink_service_s": 2.0},
}

# The congestion arena (`dahl2004_congestion`), chosen by the design search of
# `benchmarks/congestion_design.py` from physics measurements alone (committed before any learner
# ran on it): a clearance-governed speed over 2.56 m of clearance, read by a 3 m range sensor, and
# 40 s loading. Its crowding elasticity is the lowest the search found (about 1.17, not <= 1).
CONGESTION: Mapping[str, Any] = {
    "clearance_governor_m": 2.56,
    "sensing_range_m": 3.0,
    "source_service_s": 40.0,
}

# The second design search's lowest-e arena (`benchmarks/congestion_design.py --search bays`),
# which by that search's rule joins the regime map: the congestion arena with three bays per
# station. About e = 1.10, still above 1; 3 + 3 stays the homogeneous equilibrium.
BAYS: Mapping[str, Any] = {**CONGESTION, "station_bays": 3}

# The passing arena (`dahl2004_passing`), the third design search's choice by its committed rule
# (`benchmarks/congestion_design.py --search passing`, physics only, before any learner ran
# on it): robots that overtake, two bays per station and 120 s loading. No arena of that search met
# every target; this one is the closest: e about 1.07 (the lowest measured), t(4)/t(3) about 1.33,
# and a fast robot keeps its whole speed advantage in company (rho = its ratio alone, 1.10).
PASSING: Mapping[str, Any] = {"overtaking": True, "source_service_s": 120.0, "station_bays": 2}

PRESETS: Mapping[str, Any] = {
    "dahl2004": _dahl2004,
    "dahl2004_homogeneous": _dahl2004_homogeneous,
    "three_circuits_three_classes": _three_circuits_three_classes,
    "dahl2004_competence": lambda: _dahl2004().replace(**ARENA_REGIMES["competence"]),
    "dahl2004_light_stations": lambda: _dahl2004().replace(**ARENA_REGIMES["light_stations"]),
    "dahl2004_congestion": lambda: _dahl2004().replace(**CONGESTION),
    "dahl2004_bays": lambda: _dahl2004().replace(**BAYS),
    "dahl2004_passing": lambda: _dahl2004().replace(**PASSING),
    # 24 robots (fast and slow alternating) on eight lane circuits worth 2200 down to 2130, 9 m
    # apart as in dahl2004: the paper's density (three robots a circuit) at four times its size
    "large_team": lambda: scaled_config(8, 3),
}


DEFAULT_PRESET = "dahl2004"
# What an override may name: a field of `ArenaConfig`, or a shorthand of `make_config`.
ARENA_FIELDS = frozenset(f.name for f in dataclasses.fields(ArenaConfig))
ARENA_KEYS = ARENA_FIELDS | {"speeds", "values"}


def preset(name: str) -> ArenaConfig:
    """The named preset's configuration."""
    require(isinstance(name, str) and name in PRESETS, "preset", name, f"one of {sorted(PRESETS)}")
    config: ArenaConfig = PRESETS[name]()
    return config


def make_config(
    preset_name: str | None = None, config: ArenaConfig | None = None, **overrides: Any
) -> ArenaConfig:
    """Build a configuration from a preset (None: `dahl2004`) or a given `config` (not both), and
    field overrides.

    Besides the fields of `ArenaConfig`, two shorthands are accepted: `speeds` (one top speed per
    robot; classes are labelled fast/slow/medium by comparison with the mean) and `values` (one value
    per circuit, keeping the geometry). Unknown keys raise a ValueError listing what is allowed.
    """
    if config is not None:
        require(
            preset_name is None,
            "preset",
            preset_name,
            "None when a config is given (the config is the whole arena; change it with "
            "overrides or config.replace)",
        )
        require(isinstance(config, ArenaConfig), "config", config, "a tavc_env.ArenaConfig or None")
    base = (
        config
        if config is not None
        else preset(DEFAULT_PRESET if preset_name is None else preset_name)
    )
    _refuse_unknown(overrides, ARENA_KEYS)
    changes = {k: v for k, v in overrides.items() if k in ARENA_FIELDS}
    if "speeds" in overrides:
        require(
            "robots" not in overrides, "speeds", overrides["speeds"], "speeds or robots, not both"
        )
        changes["robots"] = robots_from_speeds(overrides["speeds"])
    if "values" in overrides:
        circuits = _items("circuits", changes.get("circuits", base.circuits), "tavc_env.Circuit")
        # kept as given (an int stays an int: saved trials' digests hash the circuits' reprs)
        values = _circuit_values(overrides["values"], len(circuits))
        changes["circuits"] = tuple(
            dataclasses.replace(c, value=v) for c, v in zip(circuits, values)
        )
    return base.replace(**changes) if changes else base


def preset_overrides(config: ArenaConfig, preset_name: str) -> tuple[tuple[str, Any], ...]:
    """The fields in which `config` differs from the preset `preset_name`, sorted by name (the
    inverse of `make_config`: `make_config(preset_name, **dict(overrides))` rebuilds `config`)."""
    base = preset(preset_name)
    changed = [
        (f.name, getattr(config, f.name))
        for f in dataclasses.fields(ArenaConfig)
        if getattr(config, f.name) != getattr(base, f.name)
    ]
    return tuple(sorted(changed, key=lambda item: item[0]))


def _speed(v: float) -> bool:
    return 0 < v <= MAX_SPEED_M_S


def robots_from_speeds(speeds: Sequence[float]) -> tuple[Robot, ...]:
    """Robots with the given top speeds, labelled fast / slow / medium relative to the mean speed."""
    allowed = "a non-empty sequence of speeds in m/s"
    items = _items("speeds", speeds, "speeds in m/s")
    require(len(items) >= 1, "speeds", speeds, allowed)
    speeds = [
        float(real(v, f"speeds[{i}]", f"a speed in (0, {MAX_SPEED_M_S:g}] m/s", _speed))
        for i, v in enumerate(items)
    ]
    mean = sum(speeds) / len(speeds)
    labels = [
        "fast" if s > mean + 1e-9 else "slow" if s < mean - 1e-9 else "medium" for s in speeds
    ]
    return tuple(Robot(float(s), label) for s, label in zip(speeds, labels))


def scaled_config(
    n_circuits: int,
    robots_per_circuit: int = 3,
    speeds: Sequence[float] = (0.30, 0.20),
    lane_spacing_m: float = 9.0,
) -> ArenaConfig:
    """A `dahl2004`-like arena scaled up: `n_circuits` lanes `lane_spacing_m` apart (9 m, as in
    `dahl2004`), `n_circuits * robots_per_circuit` robots with top speeds cycling through `speeds`
    (fast, slow, fast, ... by default), circuit values falling by 10 from 2200.

    The arena is made as tall as it must be (from the paper's 8 m, in steps of 2 m up to 80 m) for
    every station's waiting line to hold every other robot (the validation of `ArenaConfig`); if
    no height up to 80 m is enough, the lanes are moved further apart (x1.5, 2, 3, 4).
    """
    n_circuits = integer(n_circuits, "n_circuits", "an integer >= 1", lambda k: k >= 1)
    robots_per_circuit = integer(
        robots_per_circuit, "robots_per_circuit", "an integer >= 1", lambda k: k >= 1
    )
    lane_spacing_m = real(
        lane_spacing_m, "lane_spacing_m", "a finite spacing >= 3 m", lambda v: v >= 3.0
    )
    cycle = robots_from_speeds(speeds)  # every speed checked, and at least one
    n = n_circuits * robots_per_circuit
    require_together(
        n <= MAX_SCALED_ROBOTS,
        {"n_circuits": n_circuits, "robots_per_circuit": robots_per_circuit},
        f"at most {MAX_SCALED_ROBOTS} robots in all (n_circuits x robots_per_circuit; larger "
        "arenas take too long to lay out)",
    )
    robots = robots_from_speeds([cycle[i % len(cycle)].speed for i in range(n)])
    fastest = (max(robots, key=lambda r: r.speed),)
    values = [2200.0 - 10.0 * i for i in range(n_circuits)]
    # Each candidate arena is first built with the fastest robot alone: every check that does
    # not depend on the team's size, and the geometry of the waiting lines, which is checked
    # station by station, stopping at the first that is too short. Only an arena whose lines
    # hold the team is built with the whole team (validated in full). The arena chosen is the
    # one the full validation of every candidate in turn would choose.
    probe: ArenaConfig | None = None
    for spacing in (lane_spacing_m * f for f in (1.0, 1.5, 2.0, 3.0, 4.0)):
        width = 3.0 + spacing * max(n_circuits - 1, 1)
        for height in range(8, 82, 2):
            fields: dict[str, Any] = {
                "width": width,
                "height": float(height),
                "circuits": lane_circuits(
                    n_circuits, width=width, height=float(height), values=values
                ),
            }
            probe = ArenaConfig(**fields, robots=fastest)
            if not _robots_fit(n, probe.robot_radius, width, float(height)) or all(
                len(probe.waiting_slots(k, n - 1)) >= n - 1 for k in range(len(probe.stations()))
            ):
                return ArenaConfig(**fields, robots=robots)
    assert probe is not None
    held = min(len(probe.waiting_slots(k, n - 1)) for k in range(len(probe.stations())))
    raise ValueError(
        f"n_circuits, robots_per_circuit = {n_circuits}, {robots_per_circuit} is invalid; "
        f"allowed: at most {(held + 1) // n_circuits} robots per circuit with {n_circuits} "
        f"circuits: no arena up to {probe.width:g} x {probe.height:g} m (lanes up to 4 x "
        f"{lane_spacing_m:g} m apart) has waiting lines for {n} robots (at most {held + 1})"
    )


JAM_WINDOW_S = 600.0  # the jam detector's default window: ten typical tasks of the shipped arenas without any progress
