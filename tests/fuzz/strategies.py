"""Hypothesis strategies of the fuzzing harness: arena configurations (valid and invalid), action
streams, seeds of every type, and damaged stored files; plus the invariants' measuring helpers."""

from __future__ import annotations

import decimal
import fractions
import math
import numbers
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from hypothesis import assume, settings
from hypothesis import strategies as st

import tavc_env
from tavc_env.config import (
    MAX_STEP_OVER_RADIUS,
    MIN_SENSING_OVER_RADIUS,
    ArenaConfig,
    Breakdown,
    Circuit,
    Robot,
)
from tavc_env.engine.world import WALL_THICKNESS_M

PROFILE = os.environ.get("TAVC_FUZZ", "ci") or "ci"
SCALE = 25 if PROFILE == "long" else 1


def fuzz_settings(examples: int) -> settings:
    """The profile's settings with `examples` examples (25 times as many in the long profile)."""
    return settings(settings.get_profile(f"tavc-fuzz-{PROFILE}"), max_examples=examples * SCALE)


# -- configurations ----------------------------------------------------------------------------
# Overlap is only promised inside the envelope the shipped presets' densities were measured in
# (tavc_env.config, MAX_STEP_OVER_RADIUS): big robots packed tight (radius 0.4 m, 24 robots in a
# 16 x 12 m arena) still press about 0.05 radii into each other, a crowding problem of issue 12
# item 1. So the valid configurations drawn here keep radius <= 0.3 m and at most 8 robots per
# circuit; the invalid ones go anywhere.
MAX_RADIUS_M = 0.3
MAX_ROBOTS_PER_CIRCUIT = 8


def _finite(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@st.composite
def arena_fields(draw: st.DrawFn) -> dict[str, Any]:
    """Fields of an `ArenaConfig` inside the envelope, built from the config's dataclasses
    (circuits as lanes or at random points, robots, breakdowns). Most are valid; the rest are
    refused by the config (with a ValueError naming a field) and `valid_config` drops them."""
    m = draw(st.integers(1, 3))
    n = draw(st.integers(1, MAX_ROBOTS_PER_CIRCUIT * m))
    radius = draw(_finite(0.1, MAX_RADIUS_M))
    dt = draw(st.sampled_from([0.02, 0.05, 0.1, 0.2]))
    top = min(2.0, MAX_STEP_OVER_RADIUS * radius / dt)
    speeds = draw(st.lists(_finite(0.05, top), min_size=n, max_size=n))
    spacing = draw(_finite(2 * radius + 0.02, 2 * radius + 0.5))
    width = draw(_finite(6.0 + 5.0 * (m - 1), 12.0 + 9.0 * (m - 1)))
    height = draw(_finite(8.0, 14.0))
    if draw(st.booleans()):
        values = draw(st.lists(_finite(1.0, 5000.0), min_size=m, max_size=m))
        circuits = tavc_env.lane_circuits(m, width, height, values=values)
    else:
        margin = 1.0
        point = st.tuples(_finite(margin, width - margin), _finite(margin, height - margin))
        directions = st.sampled_from([(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (1, 1)])
        circuits = tuple(
            Circuit(draw(point), draw(point), draw(_finite(1.0, 5000.0)), draw(directions))
            for _ in range(m)
        )
    breakdowns = tuple(
        Breakdown(
            draw(st.integers(0, n - 1)),
            draw(_finite(0.0, 120.0)),
            draw(st.none() | _finite(1.0, 60.0)),
        )
        for _ in range(draw(st.integers(0, 3)))
    )
    return {
        "width": width,
        "height": height,
        "circuits": circuits,
        "robots": tuple(Robot(v, "fuzz") for v in speeds),
        "robot_radius": radius,
        "source_service_s": draw(_finite(0.0, 20.0)),
        "sink_service_s": draw(_finite(0.0, 8.0)),
        "service_scales_with_speed": draw(st.booleans()),
        "service_reference_speed": draw(_finite(0.05, 1.0)),
        "queue_offset_m": draw(_finite(2 * radius, 1.5)),
        "queue_spacing_m": spacing,
        "join_radius_m": draw(_finite(0.5, 2.5)),
        "dock_tolerance_m": draw(_finite(0.05, 0.25)),
        "speed_noise": draw(_finite(0.0, 0.3)),
        "max_turn_rate": draw(_finite(0.5, 4.0)),
        "sensing_range_m": draw(_finite(MIN_SENSING_OVER_RADIUS * radius, 2.5)),
        "dt": dt,
        "breakdowns": breakdowns,
    }


def make_or_none(fields: dict[str, Any]) -> ArenaConfig | None:
    try:
        return ArenaConfig(**fields)
    except ValueError:
        return None


@st.composite
def valid_config(draw: st.DrawFn) -> ArenaConfig:
    config = make_or_none(draw(arena_fields()))
    assume(config is not None)
    assert config is not None
    return config


# Values no field accepts, whatever the others are (wrong type, not finite, not positive).
NOT_A_NUMBER: st.SearchStrategy[Any] = st.one_of(
    st.just(math.nan),
    st.just(math.inf),
    st.just(-math.inf),
    st.just(np.float64("nan")),
    st.booleans(),
    st.none(),
    st.text(max_size=4),
    st.just("0.5"),
    st.lists(_finite(0.1, 1.0), min_size=1, max_size=2),
    st.complex_numbers(allow_nan=False, allow_infinity=False, min_magnitude=0.1, max_magnitude=2),
    st.just({"value": 1.0}),
    st.just(object()),
)
NOT_POSITIVE = st.one_of(NOT_A_NUMBER, _finite(-1e9, 0.0), st.integers(-5, 0))
NOT_NONNEGATIVE = st.one_of(NOT_A_NUMBER, _finite(-1e9, -1e-9), st.integers(-5, -1))
NOT_A_SEQUENCE = st.one_of(
    st.none(),
    st.integers(-3, 3),
    _finite(-1.0, 1.0),
    st.text(max_size=3),
    st.just({"a": 1}),
    st.just(object()),
)

# field -> values refused for that field alone (the message must name the field)
INVALID_VALUES: dict[str, st.SearchStrategy[Any]] = {
    "width": st.one_of(NOT_POSITIVE, _finite(1.0001e6, 1e300)),
    "height": st.one_of(NOT_POSITIVE, _finite(1.0001e6, 1e300)),
    "robot_radius": NOT_POSITIVE,
    "queue_offset_m": NOT_POSITIVE,
    "queue_spacing_m": NOT_POSITIVE,
    "join_radius_m": NOT_POSITIVE,
    "dock_tolerance_m": NOT_POSITIVE,
    "max_turn_rate": NOT_POSITIVE,
    "sensing_range_m": st.one_of(NOT_POSITIVE, _finite(1e-6, 0.249)),  # < 2.5 x radius >= 0.1
    "service_reference_speed": NOT_POSITIVE,
    "source_service_s": NOT_NONNEGATIVE,
    "sink_service_s": NOT_NONNEGATIVE,
    "service_scales_with_speed": st.one_of(
        st.integers(0, 1), st.none(), st.text(max_size=4), st.just(np.True_), _finite(0.0, 1.0)
    ),
    "dt": st.one_of(NOT_POSITIVE, _finite(0.5001, 1e6)),
    "speed_noise": st.one_of(NOT_NONNEGATIVE, _finite(0.3001, 1e6)),
    "circuits": st.one_of(
        NOT_A_SEQUENCE,
        st.just(()),
        st.lists(st.one_of(st.integers(), st.none(), st.just((1.0, 2.0))), min_size=1, max_size=3),
    ),
    "robots": st.one_of(
        NOT_A_SEQUENCE,
        st.just(()),
        st.lists(st.one_of(_finite(0.1, 0.3), st.none(), st.text(max_size=2)), min_size=1),
        st.integers(1200, 1500).map(lambda k: tuple(Robot(0.01) for _ in range(k))),  # no room
    ),
    "breakdowns": st.one_of(
        NOT_A_SEQUENCE,
        st.lists(st.one_of(st.integers(), st.just((0, 5.0))), min_size=1, max_size=2),
        st.integers(100, 10**9).map(lambda k: (Breakdown(k, 10.0),)),  # no such robot
    ),
}

# the dataclasses inside a config: (constructor, valid arguments, field -> refused values)
NESTED: dict[str, tuple[Callable[..., Any], dict[str, Any], dict[str, st.SearchStrategy[Any]]]] = {
    "circuit": (
        Circuit,
        {"source": (3.0, 6.5), "sink": (3.0, 1.5), "value": 2000.0},
        {
            "source": st.one_of(NOT_A_SEQUENCE, st.tuples(NOT_A_NUMBER, _finite(0, 1))),
            "sink": st.one_of(NOT_A_SEQUENCE, st.lists(_finite(0, 1), min_size=3, max_size=4)),
            "value": NOT_POSITIVE,
            "queue_direction": st.one_of(NOT_A_SEQUENCE, st.just((0.0, 0.0))),
        },
    ),
    "robot": (Robot, {"speed": 0.3}, {"speed": st.one_of(NOT_POSITIVE, _finite(2.0001, 1e9))}),
    "breakdown": (
        Breakdown,
        {"robot": 0, "at_s": 10.0},
        {
            "robot": st.one_of(st.integers(-(10**6), -1), NOT_A_NUMBER, _finite(0.5, 3.5)),
            "at_s": NOT_NONNEGATIVE,
            "repair_after_s": st.one_of(NOT_POSITIVE.filter(lambda v: v is not None)),
        },
    ),
}


# -- actions ------------------------------------------------------------------------------------
INTEGER_TYPES = (
    int,
    np.int8,
    np.int16,
    np.int32,
    np.int64,
    np.uint8,
    np.uint16,
    np.uint32,
    np.uint64,
)


def integer_like(lo: int, hi: int) -> st.SearchStrategy[Any]:
    """An integer in [lo, hi] as a Python int, a numpy integer of any width or a 0-d array."""
    return st.one_of(
        st.builds(lambda t, v: t(v), st.sampled_from(INTEGER_TYPES), st.integers(max(lo, 0), hi)),
        st.builds(lambda v: np.array(v, dtype=np.int64), st.integers(lo, hi)),
        st.integers(lo, hi),
    )


def bad_actions(m: int) -> st.SearchStrategy[Any]:
    """Actions a deciding robot must not be given in an arena with `m` circuits."""
    return st.one_of(
        st.none(),
        st.integers(-(2**70), -1),
        st.integers(m, 2**70),
        st.booleans(),
        st.just(np.True_),
        st.floats(allow_nan=True, allow_infinity=True),
        st.builds(lambda v: np.float64(v), st.integers(0, m - 1)),
        st.builds(lambda v: np.array(float(v)), st.integers(0, m - 1)),
        st.builds(lambda v: np.array([v]), st.integers(0, m - 1)),
        st.text(max_size=3),
        st.just([0]),
        st.just({"circuit": 0}),
        st.builds(fractions.Fraction, st.integers(0, m - 1)),
        st.builds(decimal.Decimal, st.integers(0, m - 1)),
    )


def is_valid_action(action: Any, m: int) -> bool:
    """The documented rule: an integer circuit index in [0, m - 1] (int, numpy integer or a 0-d
    integer array; bool and floats are not integers)."""
    if isinstance(action, np.ndarray):
        if action.shape != () or action.dtype.kind not in "iu":
            return False
        action = action.item()
    if isinstance(action, (bool, np.bool_)) or not isinstance(action, numbers.Integral):
        return False
    return 0 <= int(action) < m


@dataclass(frozen=True)
class StepPlan:
    """How to build one step's action dict from the robots that must decide: one `choice` per
    deciding robot in order (an index into valid circuits, or a bad action), whether to drop one
    of them, garbage for robots that need not decide, and unknown keys."""

    choices: tuple[Any, ...]
    drop: int | None
    idle_garbage: Any
    unknown_key: Any


def step_plans(m: int) -> st.SearchStrategy[StepPlan]:
    good = integer_like(0, m - 1)
    choice = st.one_of(good, good, good, bad_actions(m))  # mostly valid
    return st.builds(
        StepPlan,
        choices=st.lists(choice, min_size=24, max_size=24).map(tuple),
        drop=st.none() | st.none() | st.integers(0, 23),
        idle_garbage=st.one_of(integer_like(0, m - 1), bad_actions(m)),
        unknown_key=st.one_of(
            *[st.none()] * 6, st.just("robot_999"), st.integers(0, 3), st.just(("robot_0",))
        ),
    )


def build_actions(plan: StepPlan, deciding: list[str], idle: list[str]) -> dict[Any, Any]:
    actions: dict[Any, Any] = {}
    for k, agent in enumerate(deciding):
        if plan.drop != k:
            actions[agent] = plan.choices[k % len(plan.choices)]
    for agent in idle[:2]:
        actions[agent] = plan.idle_garbage  # ignored whatever it is
    if plan.unknown_key is not None:
        actions[plan.unknown_key] = 0
    return actions


def plan_is_valid(plan: StepPlan, deciding: list[str], m: int) -> bool:
    if plan.unknown_key is not None:
        return False
    if plan.drop is not None and plan.drop < len(deciding):
        return False
    return all(
        is_valid_action(plan.choices[k % len(plan.choices)], m) for k in range(len(deciding))
    )


# -- seeds ----------------------------------------------------------------------------------------
SEEDS: st.SearchStrategy[Any] = st.one_of(
    st.none(),
    st.integers(0, 2**31),
    st.integers(-(2**70), 2**80),
    st.builds(lambda t, v: t(v), st.sampled_from(INTEGER_TYPES), st.integers(0, 127)),
    st.builds(lambda t, v: t(v), st.sampled_from(INTEGER_TYPES[1:5]), st.integers(-128, -1)),
    st.booleans(),
    st.just(np.True_),
    st.floats(allow_nan=True, allow_infinity=True),
    st.builds(lambda v: np.float32(v), st.integers(0, 5)),
    st.builds(lambda v: np.array(v), st.integers(0, 5)),
    st.text(max_size=4),
    st.just([1, 2]),
    st.builds(fractions.Fraction, st.integers(0, 5)),
    st.builds(decimal.Decimal, st.integers(0, 5)),
)


def is_valid_seed(seed: Any) -> bool:
    """The documented rule: None or an integer >= 0 (int or numpy integer; not bool, not float)."""
    if seed is None:
        return True
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, numbers.Integral):
        return False
    return int(seed) >= 0


# -- measuring ------------------------------------------------------------------------------------
def deepest_overlap(env: tavc_env.TavcArenaEnv) -> float:
    """The deepest interpenetration of two robots on the floor, or of a robot and a wall, in
    robot radii (0: nobody touches)."""
    snap = env.snapshot()
    cfg = env.config
    r = cfg.robot_radius
    pos = snap.positions[~snap.broken]
    if len(pos) == 0:
        return 0.0
    walls = r + WALL_THICKNESS_M
    deepest = max(
        0.0,
        float(np.max(walls - pos[:, 0])),
        float(np.max(walls - pos[:, 1])),
        float(np.max(pos[:, 0] - (cfg.width - walls))),
        float(np.max(pos[:, 1] - (cfg.height - walls))),
    )
    if len(pos) > 1:
        diff = pos[:, None, :] - pos[None, :, :]
        dist = np.hypot(diff[..., 0], diff[..., 1])
        np.fill_diagonal(dist, np.inf)
        deepest = max(deepest, float(2 * r - dist.min()))
    return deepest / r


# -- numbers of every type (issue 28) -----------------------------------------------------------
# Real types a float may or may not hold exactly; the config stores any it holds as a plain float.
REAL_KINDS: dict[str, Callable[[float], Any]] = {
    "float": float,
    "float16": np.float16,
    "float32": np.float32,
    "float64": np.float64,
    "longdouble": np.longdouble,
    "Fraction": fractions.Fraction,  # exact from a float
    "Decimal": decimal.Decimal,  # exact from a float
}
WHOLE_KINDS: tuple[Callable[[int], Any], ...] = (int, np.int64, np.int32, np.uint32)


def _as_kind(kind: str, value: float) -> Any:
    with np.errstate(over="ignore"):  # float16 beyond 65504 is inf (refused): a case like any
        return REAL_KINDS[kind](value)


def typed_number(lo: float, hi: float) -> st.SearchStrategy[Any]:
    """A finite number in [lo, hi] as any real type, or a whole one as any integer type."""
    reals = st.builds(_as_kind, st.sampled_from(sorted(REAL_KINDS)), _finite(lo, hi))
    first, last = max(0, math.ceil(lo)), math.floor(hi)
    if first > last:  # no whole number in the range
        return reals
    wholes = st.builds(
        lambda make, v: make(v), st.sampled_from(WHOLE_KINDS), st.integers(first, last)
    )
    return st.one_of(reals, wholes)


def typed_integer(lo: int, hi: int) -> st.SearchStrategy[Any]:
    """An integer in [lo, hi] (lo >= 0) as a Python int or any numpy integer type that holds it."""
    return st.builds(
        lambda make, v: make(v),
        st.sampled_from((int, np.int64, np.int16, np.uint8)),
        st.integers(lo, hi),
    )


# What no number field should take for a number, and numbers at the edges of every type.
HOSTILE: st.SearchStrategy[Any] = st.one_of(
    NOT_A_NUMBER,
    st.binary(max_size=3),
    st.just(bytearray(b"\x01")),
    st.just(np.True_),
    st.just(None),
    st.fractions(),  # mostly not held exactly by a float: refused with the float to give
    st.decimals(allow_nan=True, allow_infinity=True),
    st.integers(-(2**80), 2**80),
    st.sampled_from([10**400, -(10**400), 2**53 + 1, 0, -1]),
    st.floats(),  # nan, infinities, subnormals, huge
    st.sampled_from([5e-324, 1e-300, 1e308, -0.0]),
    st.builds(np.array, _finite(0.1, 1.0)),
    st.lists(_finite(0.1, 1.0), max_size=2).map(np.array),
    st.tuples(_finite(0.1, 1.0)),
    st.text(max_size=3),
)
