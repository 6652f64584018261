"""Random valid arenas: a seeded generator of arena configurations for stress and liveness tests.

An arena is drawn as plain JSON data (`draw_arena`, rounded so that it reads back exactly) and
built with `arena_config`, which is where `tavc_env.ArenaConfig`'s validation accepts or refuses
it. `random_arenas` draws until it has as many valid arenas as asked and counts the refused draws
by the reason validation gave (`refusal_category`: a too-short waiting line, stations too close,
too many robots for the floor, a physics step too long for the speed and radius, ...).

    import numpy as np
    draws = random_arenas(120, np.random.default_rng(0))
    config = arena_config(draws.arenas[0])   # a tavc_env.ArenaConfig
    draws.refused                            # {"waiting line too short": 57, ...}

What is drawn (uniformly unless said otherwise): the floor (8-40 m x 6-30 m), 1-4 circuits, each
with its source and sink anywhere inside the walls, a queue direction at any angle and a value in
[1000, 2500]; 2-24 robots with top speeds in [0.1, 0.4] m/s; a robot radius in [0.15, 0.30] m;
loading 2-25 s and unloading 1-8 s, scaled by speed in a quarter of the arenas; the physics step
(0.05, 0.1 or 0.2 s); the waiting lines' offset and spacing (a little more than a robot diameter),
the joining radius, the docking tolerance, the speed noise, the turn rate and the sensing range.
The same generator state gives the same arenas.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tavc_env.config import ArenaConfig, Circuit, robots_from_speeds
from tavc_env.layout import WALL_CLEARANCE_M

WIDTH_M = (8.0, 40.0)
HEIGHT_M = (6.0, 30.0)
CIRCUITS = (1, 4)
ROBOTS = (2, 24)
SPEED_M_S = (0.1, 0.4)
RADIUS_M = (0.15, 0.30)
SOURCE_SERVICE_S = (2.0, 25.0)
SINK_SERVICE_S = (1.0, 8.0)
VALUE = (1000.0, 2500.0)
DTS = (0.05, 0.1, 0.2)
DT_WEIGHTS = (0.2, 0.6, 0.2)
SCALED_SERVICE_SHARE = 0.25
DRAWS_PER_ARENA = 5000  # `random_arenas` gives up after this many draws per arena asked for

# The description's scalar fields, as `ArenaConfig` names them; `speeds` and `circuits` (one
# [source x, source y, sink x, sink y, queue direction in degrees, value] each) complete it.
SCALARS = (
    "width",
    "height",
    "robot_radius",
    "dt",
    "source_service_s",
    "sink_service_s",
    "service_scales_with_speed",
    "queue_offset_m",
    "queue_spacing_m",
    "join_radius_m",
    "dock_tolerance_m",
    "speed_noise",
    "max_turn_rate",
    "sensing_range_m",
)


def _uniform(rng: np.random.Generator, bounds: tuple[float, float], digits: int) -> float:
    return round(float(rng.uniform(*bounds)), digits)


def draw_arena(
    rng: np.random.Generator, robots: int | None = None, circuits: int | None = None
) -> dict[str, Any]:
    """One candidate arena as JSON data (not yet validated: see `arena_config`), drawn from
    `rng` as the module describes; with `robots` or `circuits` given, a team or a number of
    circuits of that size."""
    width = _uniform(rng, WIDTH_M, 1)
    height = _uniform(rng, HEIGHT_M, 1)
    radius = _uniform(rng, RADIUS_M, 2)
    n_circuits = int(rng.integers(CIRCUITS[0], CIRCUITS[1] + 1)) if circuits is None else circuits
    n_robots = int(rng.integers(ROBOTS[0], ROBOTS[1] + 1)) if robots is None else robots
    margin = math.ceil((radius + WALL_CLEARANCE_M) * 100) / 100  # docks inside the walls

    def point() -> list[float]:
        return [
            round(float(rng.uniform(margin, width - margin)), 2),
            round(float(rng.uniform(margin, height - margin)), 2),
        ]

    lanes = [
        [*point(), *point(), int(rng.integers(360)), _uniform(rng, VALUE, 0)]
        for _ in range(n_circuits)
    ]
    speeds = [_uniform(rng, SPEED_M_S, 2) for _ in range(n_robots)]
    return {
        "width": width,
        "height": height,
        "robot_radius": radius,
        "dt": float(rng.choice(DTS, p=DT_WEIGHTS)),
        "source_service_s": _uniform(rng, SOURCE_SERVICE_S, 1),
        "sink_service_s": _uniform(rng, SINK_SERVICE_S, 1),
        "service_scales_with_speed": bool(rng.random() < SCALED_SERVICE_SHARE),
        "queue_offset_m": round(2 * radius + float(rng.uniform(0.1, 0.6)), 2),
        "queue_spacing_m": round(2 * radius + float(rng.uniform(0.05, 0.3)), 2),
        "join_radius_m": _uniform(rng, (1.0, 2.5), 2),
        "dock_tolerance_m": _uniform(rng, (0.08, 0.2), 2),
        "speed_noise": _uniform(rng, (0.0, 0.2), 2),
        "max_turn_rate": _uniform(rng, (1.0, 2.5), 2),
        "sensing_range_m": round(2.5 * radius + float(rng.uniform(0.2, 0.8)), 2),
        "speeds": speeds,
        "circuits": lanes,
    }


def arena_config(description: Mapping[str, Any]) -> ArenaConfig:
    """The arena `description` (from `draw_arena`) describes; a ValueError from the arena's
    validation if it is not a valid one."""
    circuits = tuple(
        Circuit(
            source=(float(sx), float(sy)),
            sink=(float(kx), float(ky)),
            value=float(value),
            queue_direction=(math.cos(math.radians(angle)), math.sin(math.radians(angle))),
        )
        for sx, sy, kx, ky, angle, value in description["circuits"]
    )
    return ArenaConfig(
        circuits=circuits,
        robots=robots_from_speeds([float(v) for v in description["speeds"]]),
        **{name: description[name] for name in SCALARS},
    )


def refusal_category(error: ValueError) -> str:
    """Why validation refused an arena, as a short category: what the message names, with
    circuit and robot indices dropped ("waiting line too short", "stations too close",
    "dt", "robots", ...)."""
    # a rule relating fields names them all ("dt, robot_radius, robots[0].speed"): the first
    name = str(error).partition(" = ")[0].split(", ")[0]
    if name.endswith("waiting line"):
        return "waiting line too short"
    if "(distance to " in name:
        return "stations too close"
    if re.fullmatch(r"circuits\[\d+\]\.(source|sink)", name):
        return "station outside the arena"
    if name == "robots":
        return "robots: too many for the floor"
    return re.sub(r"\[\d+\]", "[]", name)


@dataclass
class ArenaDraws:
    """What `random_arenas` drew: the valid arenas (descriptions, in the order drawn), how many
    draws it took, and the refused draws counted by `refusal_category`."""

    arenas: list[dict[str, Any]]
    draws: int
    refused: dict[str, int] = field(default_factory=dict)


def random_arenas(count: int, rng: np.random.Generator) -> ArenaDraws:
    """`count` valid arenas drawn from `rng`, refused draws counted by reason.

    Each arena's number of circuits and team size are drawn first (uniformly in `CIRCUITS` and
    `ROBOTS`) and kept: the rest of the arena is drawn again until validation accepts it. Many
    circuits and large teams are refused far more often (their lines need room: 4 circuits with
    20-24 robots about 1 draw in 100), so without this the valid arenas would be mostly one
    circuit and a small team. A RuntimeError if fewer than one draw in `DRAWS_PER_ARENA` is
    valid."""
    if not isinstance(count, int) or isinstance(count, bool) or count < 0:
        raise ValueError(f"count = {count!r} is invalid; allowed: an integer >= 0")
    arenas: list[dict[str, Any]] = []
    refused: Counter[str] = Counter()
    draws = 0
    while len(arenas) < count:
        circuits = int(rng.integers(CIRCUITS[0], CIRCUITS[1] + 1))
        robots = int(rng.integers(ROBOTS[0], ROBOTS[1] + 1))
        while True:
            if draws >= DRAWS_PER_ARENA * count:
                raise RuntimeError(
                    f"only {len(arenas)} valid arenas in {draws} draws (refused: {dict(refused)})"
                )
            description = draw_arena(rng, robots, circuits)
            draws += 1
            try:
                arena_config(description)
            except ValueError as error:
                refused[refusal_category(error)] += 1
                continue
            arenas.append(description)
            break
    return ArenaDraws(arenas, draws, dict(sorted(refused.items(), key=lambda kv: (-kv[1], kv[0]))))
