"""Numbers of any type (issue 28, items 1 and 2): every number of an arena is checked and stored as
a plain `float` or `int` when the arena is made, so nothing past validation meets a numpy scalar,
a `Fraction` or a `Decimal` (they used to fail deep inside numba, numpy or string formatting).
Any real type a float holds exactly is accepted; one it does not hold is refused with the float to
give instead; bools, bytes, complex numbers, strings, None and containers are refused. Each field
is checked on its own before any rule relating fields, and such a rule names every field it
relates.
"""

from __future__ import annotations

import math
import re
import time
from decimal import Decimal
from fractions import Fraction
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_env.config import MAX_CIRCUITS, ArenaConfig, Breakdown, Circuit, Robot

# Every number field of ArenaConfig with a valid value that float16 holds exactly (so each type
# below gives the same number); the rest of the arena is dahl2004's.
VALID: dict[str, float] = {
    "width": 12.0,
    "height": 8.0,
    "robot_radius": 0.25,
    "source_service_s": 20.0,
    "sink_service_s": 4.0,
    "service_reference_speed": 0.25,
    "queue_offset_m": 1.0,
    "queue_spacing_m": 0.625,
    "join_radius_m": 1.5,
    "dock_tolerance_m": 0.125,
    "speed_noise": 0.125,
    "max_turn_rate": 1.75,
    "sensing_range_m": 1.0,
    "dt": 0.125,
    "clearance_governor_m": 0.5,
}
REAL_TYPES = {
    "Fraction": Fraction,
    "float16": np.float16,
    "float32": np.float32,
    "float64": np.float64,
    "longdouble": np.longdouble,
    "Decimal": lambda v: Decimal(repr(v)),
}
NOT_NUMBERS = [True, np.True_, b"1", bytearray(b"1"), 1j, "0.5", None, [0.5], (0.5,)]
NOT_NUMBERS += [{"v": 0.5}, np.array(0.5), np.array([0.5]), object()]


def plain(value: object) -> bool:
    return type(value) in (float, int)


def run_a_little(config: ArenaConfig, steps: int = 3) -> None:
    """Build the env, reset it and step it with everyone choosing circuit 0."""
    env = tavc_env.parallel_env(config=config, max_sim_time_s=120.0)
    _, infos = env.reset(seed=0)
    for _ in range(steps):
        if not env.agents:
            break
        _, _, _, _, infos = env.step({a: 0 for a in env.agents if infos[a]["action_required"]})


def numbers_of(config: ArenaConfig) -> list[object]:
    """Every number an arena holds, its parts' included."""
    found: list[object] = [getattr(config, name) for name in VALID]
    found.append(config.station_bays)
    for c in config.circuits:
        found += [*c.source, *c.sink, *c.queue_direction, c.value]
    for r in config.robots:
        found.append(r.speed)
    for b in config.breakdowns:
        found += [b.robot, b.at_s] + ([] if b.repair_after_s is None else [b.repair_after_s])
    return found


# -- ArenaConfig's fields ------------------------------------------------------------------------


@pytest.mark.parametrize("kind", sorted(REAL_TYPES))
def test_every_number_field_takes_any_real_type_a_float_holds_and_stores_a_plain_float(
    kind: str,
) -> None:
    """All fields at once in one type, then the arena runs (it used to fail in numba's typing, in
    numpy's float16 or in formatting a Fraction)."""
    given = {name: REAL_TYPES[kind](value) for name, value in VALID.items()}
    config = tavc_env.make_config("dahl2004", **given)
    for name, value in VALID.items():
        stored = getattr(config, name)
        assert type(stored) is float and stored == value, (name, stored)
    assert all(plain(v) for v in numbers_of(config))
    run_a_little(config)


@pytest.mark.parametrize("name", sorted(VALID))
@pytest.mark.parametrize("kind", ["Fraction", "float16"])
def test_each_field_alone_in_a_foreign_type_runs(name: str, kind: str) -> None:
    config = tavc_env.make_config("dahl2004", **{name: REAL_TYPES[kind](VALID[name])})
    assert type(getattr(config, name)) is float
    run_a_little(config, steps=1)


@pytest.mark.parametrize("integer_type", [int, np.int64, np.uint16, np.int8])
def test_an_integer_stays_a_plain_int(integer_type: Any) -> None:
    """An int stored as an int keeps its repr (saved trials are keyed by digests of the repr)."""
    config = tavc_env.make_config(
        "dahl2004", width=integer_type(12), height=integer_type(8), station_bays=integer_type(1)
    )
    assert (type(config.width), type(config.height), type(config.station_bays)) == (int,) * 3
    assert "width=12, height=8," in repr(config)
    assert repr(config) == repr(tavc_env.make_config("dahl2004", width=12, height=8))


@pytest.mark.parametrize("name", sorted(VALID))
@pytest.mark.parametrize("bad", NOT_NUMBERS, ids=lambda v: type(v).__name__ + repr(v)[:12])
def test_a_non_number_in_any_number_field_is_refused_naming_it(name: str, bad: Any) -> None:
    with pytest.raises(ValueError, match=rf"^{name} = .* is invalid; allowed: "):
        tavc_env.make_config("dahl2004", **{name: bad})


@pytest.mark.parametrize(
    ("bad", "hint"),
    [
        (Fraction(1, 10), "give 0.1"),
        (Decimal("0.1"), "give 0.1"),
        (np.longdouble("0.1"), "give 0.1"),
        (Fraction(1, 3), "give 0.3333333333333333"),
    ],
    ids=repr,
)
def test_a_number_a_float_does_not_hold_is_refused_with_the_float_to_give(
    bad: Any, hint: str
) -> None:
    pattern = rf"^dock_tolerance_m = {re.escape(repr(bad))} is invalid; allowed: .*{hint}\)$"
    with pytest.raises(ValueError, match=pattern):
        tavc_env.make_config("dahl2004", dock_tolerance_m=bad)


@pytest.mark.parametrize(
    "bad", [10**400, -(10**400), 2**53 + 1, 10**5000], ids=["1e400", "-1e400", "2^53+1", "1e5000"]
)
def test_an_integer_beyond_the_floats_is_refused_in_one_line(bad: int) -> None:
    with pytest.raises(ValueError, match=r"^width = .* is invalid; allowed: ") as caught:
        tavc_env.make_config("dahl2004", width=bad)
    assert "\n" not in str(caught.value) and len(str(caught.value)) < 1200


@pytest.mark.parametrize("dt", [5e-30, 1e-300, 9.9e-5])
def test_a_physics_step_too_short_for_a_float_to_count_is_refused_naming_dt(dt: float) -> None:
    """The fuzz suite's long profile found dt = 5e-30 accepted, then the env refusing its own
    default step cap (a consequence, in another field's name)."""
    with pytest.raises(ValueError, match=rf"^dt = {dt!r} is invalid; allowed: .*at least 0\.0001"):
        tavc_env.make_config("dahl2004", dt=dt)
    config = tavc_env.make_config("dahl2004", dt=1e-4)
    run_a_little(config, steps=1)


def test_a_zero_dimensional_array_is_no_sequence_of_speeds() -> None:
    """Found by the fuzz suite: `speeds=np.array(1.0)` was a bare TypeError."""
    for bad in (np.array(1.0), np.array(0.3)):
        with pytest.raises(ValueError, match=r"^speeds = array\(.*\) is invalid; allowed: "):
            tavc_env.scaled_config(2, speeds=bad)
    assert len(tavc_env.robots_from_speeds(np.array([0.3, 0.2]))) == 2


def test_a_station_blocked_by_another_circuit_names_the_circuits() -> None:
    """Found by the fuzz suite: a sink moved next to another circuit's leaves that circuit's line
    no room; the refusal names the station without room and the circuits whose places decide."""
    moved = Circuit((10.5, 6.5), (3.0, 1.0), 2000.0, (-1.0, 0.0))
    with pytest.raises(
        ValueError, match=r"^circuits\[\d\]\.\w+ waiting line, len\(robots\), circuits, "
    ):
        tavc_env.make_config("dahl2004", circuits=(tavc_env.preset("dahl2004").circuits[0], moved))


@pytest.mark.parametrize("bad", [True, np.True_, 2.0, Fraction(2), "2", None, 0, 9])
def test_station_bays_is_an_integer(bad: Any) -> None:
    with pytest.raises(ValueError, match=r"^station_bays = .* is invalid; allowed: an integer"):
        tavc_env.make_config("dahl2004", station_bays=bad)


def test_start_circuits_are_plain_ints() -> None:
    config = tavc_env.make_config("dahl2004", start_circuits=[np.int64(0), np.uint8(1)] * 3)
    assert all(type(c) is int for c in config.start_circuits)
    for bad in ([0.0] * 6, [True] * 6, ["0"] * 6):
        with pytest.raises(ValueError, match=r"^start_circuits = .* is invalid; allowed: "):
            tavc_env.make_config("dahl2004", start_circuits=bad)


# -- the parts: Circuit, Robot, Breakdown --------------------------------------------------------


def test_a_circuit_takes_any_real_type_and_stores_plain_floats() -> None:
    c = Circuit(
        source=(Fraction(3, 2), np.float16(6.5)),
        sink=(np.int64(2), Decimal("1.5")),
        value=np.float32(2000.0),
        queue_direction=(np.int8(1), Fraction(0)),
    )
    assert (c.source, c.sink, c.value, c.queue_direction) == (
        (1.5, 6.5),
        (2.0, 1.5),
        2000.0,
        (1.0, 0.0),
    )
    assert all(plain(v) for v in (*c.source, *c.sink, *c.queue_direction, c.value))
    assert type(Circuit((1.0, 1.0), (2.0, 2.0), np.int64(5)).value) is int


@pytest.mark.parametrize("field", ["source", "sink", "queue_direction"])
@pytest.mark.parametrize(
    "bad", [b"\x01\x06", bytearray(b"\x01\x06"), "16", (1.0, "2"), (1.0, None)]
)
def test_a_circuit_point_is_two_numbers_not_bytes_or_text(field: str, bad: Any) -> None:
    good = {"source": (1.5, 6.5), "sink": (1.5, 1.5), "value": 2000.0}
    with pytest.raises(ValueError, match=rf"^circuit\.{field} = .* is invalid; allowed: a pair"):
        Circuit(**{**good, field: bad})


def test_a_circuit_coordinate_a_float_does_not_hold_is_refused_with_the_float_to_give() -> None:
    with pytest.raises(ValueError, match=r"^circuit\.source = .*give 0\.1\)$"):
        Circuit((Fraction(1, 10), 1.0), (2.0, 2.0), 1.0)
    with pytest.raises(ValueError, match=r"^circuit\.value = Fraction\(1, 10\) .*give 0\.1\)$"):
        Circuit((1.0, 1.0), (2.0, 2.0), Fraction(1, 10))


@pytest.mark.parametrize(
    ("direction", "unit"),
    [
        ((1e308, 1e308), (math.sqrt(0.5), math.sqrt(0.5))),
        ((5e-324, 5e-324), (math.sqrt(0.5), math.sqrt(0.5))),
        ((-1e308, 1.7e308), None),
        ((5e-324, 0.0), (1.0, 0.0)),
        ((3.0, 4.0), (0.6, 0.8)),
    ],
)
def test_a_queue_direction_of_extreme_length_normalises_to_unit_length(
    direction: tuple[float, float], unit: tuple[float, float] | None
) -> None:
    """(1e308, 1e308) overflows a length, (5e-324, 5e-324) underflows it: both used to give a
    wrong vector ((1.0, 1.0) for the second) without a word."""
    got = Circuit((1.0, 1.0), (2.0, 2.0), 1.0, direction).queue_direction
    assert math.hypot(*got) == pytest.approx(1.0, abs=1e-15)
    assert math.atan2(got[1], got[0]) == pytest.approx(math.atan2(*direction[::-1]), abs=1e-15)
    if unit is not None:
        assert got == pytest.approx(unit, abs=1e-15)


def test_a_queue_direction_of_an_ordinary_length_is_what_it_always_was() -> None:
    """Bit for bit (lanes' directions enter the digests of saved trials)."""
    for d in [(1.0, 0.0), (-1.0, 0.0), (1, 1), (0.3, -0.7), (1e-100, 3e-100)]:
        norm = math.hypot(*d)
        assert Circuit((1.0, 1.0), (2.0, 2.0), 1.0, d).queue_direction == (d[0] / norm, d[1] / norm)


def test_a_zero_queue_direction_is_refused() -> None:
    for zero in [(0.0, 0.0), (0, -0.0), (np.float16(0), Fraction(0))]:
        with pytest.raises(ValueError, match=r"^circuit\.queue_direction = .*a non-zero vector"):
            Circuit((1.0, 1.0), (2.0, 2.0), 1.0, zero)


def test_a_robot_takes_any_real_speed_and_a_string_class() -> None:
    robot = Robot(np.float16(0.25), np.str_("fast"))
    assert (type(robot.speed), robot.speed, type(robot.speed_class)) == (float, 0.25, str)
    assert Robot(Fraction(1, 4)).speed == 0.25


@pytest.mark.parametrize("label", [["x"], [1], None, 1, b"fast", ("fast",)], ids=repr)
def test_a_speed_class_must_be_a_string(label: Any) -> None:
    """`speed_class=['x']` used to run and then crash the trial summary (unhashable)."""
    with pytest.raises(ValueError, match=r"^robot\.speed_class = .* is invalid; allowed: a str"):
        Robot(0.3, label)


def test_a_breakdown_takes_integer_and_real_types_and_stores_plain_ones() -> None:
    b = Breakdown(np.uint8(2), Fraction(1, 4), np.float32(2.5))
    assert (b.robot, b.at_s, b.repair_after_s) == (2, 0.25, 2.5)
    assert (type(b.robot), type(b.at_s), type(b.repair_after_s)) == (int, float, float)
    for bad in (2.0, Fraction(2), True, "2"):
        with pytest.raises(ValueError, match=r"^breakdown\.robot = "):
            Breakdown(bad, 1.0)  # type: ignore[arg-type]


# -- a breakdown schedule covering every robot --------------------------------------------------


@pytest.mark.parametrize("at_s", [0.0, 30.0])
@pytest.mark.parametrize("repair", [None, 60.0])
@pytest.mark.parametrize("view", ["parallel", "aec"])
def test_a_breakdown_of_every_robot_is_valid_and_runs(
    at_s: float, repair: float | None, view: str
) -> None:
    """Reported refused with numpy's "zero-size array to reduction operation maximum"."""
    config = tavc_env.make_config(
        "dahl2004", breakdowns=tuple(Breakdown(i, at_s, repair) for i in range(6))
    )
    if view == "parallel":
        env = tavc_env.parallel_env(config=config, max_sim_time_s=300.0, decision_interval_s=30.0)
        _, infos = env.reset(seed=0)
        while env.agents:
            _, _, _, _, infos = env.step({a: 1 for a in env.agents if infos[a]["action_required"]})
        assert env.sim.time_s == pytest.approx(300.0)
    else:
        aec = tavc_env.env(config=config, max_sim_time_s=300.0, decision_interval_s=30.0)
        aec.reset(seed=0)
        for _ in aec.agent_iter(200):
            _, _, done, cut, _ = aec.last()
            aec.step(None if done or cut else 1)


# -- the helper constructors ---------------------------------------------------------------------


def test_lane_circuits_takes_a_numpy_integer_and_refuses_a_bool() -> None:
    assert tavc_env.lane_circuits(np.int64(2)) == tavc_env.lane_circuits(2)
    for bad in (True, False, 2.0, "2", None):
        with pytest.raises(ValueError, match=r"^n_circuits = .* is invalid; allowed: an integer"):
            tavc_env.lane_circuits(bad)  # type: ignore[arg-type]


def test_lane_circuits_refuses_a_huge_count_at_once() -> None:
    """10**400 used to build a list of values until the machine ran out of memory (22 GB)."""
    start = time.perf_counter()
    for huge in (10**400, MAX_CIRCUITS + 1, 2**63):
        with pytest.raises(ValueError, match=r"^n_circuits = .* allowed: an integer in \[1, "):
            tavc_env.lane_circuits(huge)
    assert time.perf_counter() - start < 1.0


@pytest.mark.parametrize("values", [5, "ab", b"ab", {"a": 1.0, "b": 2.0}, 2.5, True])
def test_lane_circuits_values_that_are_not_a_sequence_are_refused_naming_values(
    values: Any,
) -> None:
    """`values=5` was a bare TypeError, `values='ab'` reported as `circuit.value = 'a'`."""
    pattern = r"^values = .* is invalid; allowed: a sequence of 2 circuit values"
    with pytest.raises(ValueError, match=pattern) as caught:
        tavc_env.lane_circuits(2, values=values)
    assert "circuit.value" not in str(caught.value)


@pytest.mark.parametrize(
    ("values", "named"),
    [((1.0, "a"), r"values\[1\]"), ((True, 2.0), r"values\[0\]"), ((1.0,), "values")],
)
def test_lane_circuits_checks_each_value_naming_it(values: Any, named: str) -> None:
    with pytest.raises(ValueError, match=rf"^{named} = "):
        tavc_env.lane_circuits(2, values=values)


def test_lane_circuits_takes_any_real_type_and_gives_plain_floats() -> None:
    lanes = tavc_env.lane_circuits(
        2, width=Fraction(12), height=np.float16(8), values=[np.int64(2200), Decimal(2000)]
    )
    assert lanes == tavc_env.lane_circuits(2, values=(2200.0, 2000.0))
    assert all(type(c.value) is float for c in lanes)
    with pytest.raises(ValueError, match=r"^wall_margin, width, height = 4\.0, 8\.0, 8\.0 "):
        tavc_env.lane_circuits(2, width=8.0, height=8.0, wall_margin=4.0)


@pytest.mark.parametrize("speeds", [(), [], "ab", 0.3, None, {"fast": 0.3}])
def test_scaled_config_with_no_speeds_is_a_clear_error(speeds: Any) -> None:
    """`speeds=()` used to be a ZeroDivisionError."""
    with pytest.raises(ValueError, match=r"^speeds = .* is invalid; allowed: "):
        tavc_env.scaled_config(2, speeds=speeds)


def test_scaled_config_takes_numpy_integers_and_refuses_bools() -> None:
    assert tavc_env.scaled_config(np.int64(2), np.int32(3)) == tavc_env.scaled_config(2, 3)
    assert tavc_env.scaled_config(2, 3, speeds=[np.float16(0.25), Fraction(3, 16)]).n_robots == 6
    for kwargs in ({"n_circuits": True}, {"n_circuits": 2, "robots_per_circuit": 3.0}):
        with pytest.raises(ValueError, match=r"^(n_circuits|robots_per_circuit) = "):
            tavc_env.scaled_config(**kwargs)
    with pytest.raises(ValueError, match=r"^lane_spacing_m = .*give 9\.1"):
        tavc_env.scaled_config(2, lane_spacing_m=Fraction(91, 10))


def test_scaled_config_30_by_30_is_refused_at_once() -> None:
    """It used to search for 39 s before refusing."""
    start = time.perf_counter()
    with pytest.raises(ValueError, match=r"^n_circuits, robots_per_circuit = 30, 30 is invalid"):
        tavc_env.scaled_config(30, 30)
    assert time.perf_counter() - start < 0.5


def test_robots_from_speeds_takes_any_real_type_and_refuses_others() -> None:
    robots = tavc_env.robots_from_speeds((np.float16(0.25), Fraction(1, 4), np.int64(1)))
    assert [r.speed for r in robots] == [0.25, 0.25, 1.0]
    assert all(type(r.speed) is float for r in robots)
    with pytest.raises(ValueError, match=r"^speeds\[1\] = Fraction\(1, 5\) .*give 0\.2\)$"):
        tavc_env.robots_from_speeds([0.3, Fraction(1, 5)])
    for bad in ("ab", b"ab", 0.3, None, []):
        with pytest.raises(ValueError, match=r"^speeds = "):
            tavc_env.robots_from_speeds(bad)  # type: ignore[arg-type]


def test_replace_refuses_an_unknown_field_with_the_packages_message() -> None:
    """It used to be the dataclass's TypeError."""
    with pytest.raises(ValueError, match=r"^unknown configuration key\(s\) \['bogus'\]; allowed: "):
        tavc_env.preset("dahl2004").replace(bogus=1)
    assert tavc_env.preset("dahl2004").replace(width=Fraction(12)).width == 12.0


def test_make_config_values_keep_their_type_when_plain_and_are_coerced_otherwise() -> None:
    config = tavc_env.make_config("dahl2004", values=(2200, np.float32(2000.0)))
    assert [(type(c.value), c.value) for c in config.circuits] == [(int, 2200), (float, 2000.0)]
    with pytest.raises(ValueError, match=r"^values\[1\] = 'x' is invalid"):
        tavc_env.make_config("dahl2004", values=(2200.0, "x"))


# -- messages: each field on its own, then rules naming every field they relate ----------------


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"width": 1e-300}, r"^robot_radius, width, height = 0\.22, 1e-300, 8\.0 is invalid"),
        ({"robot_radius": 2.0}, r"^queue_spacing_m, robot_radius = 0\.6, 2\.0 is invalid"),
        ({"robot_radius": 0.5}, r"^queue_spacing_m, robot_radius = 0\.6, 0\.5 is invalid"),
        ({"dt": 0.5}, r"^dt, robot_radius, robots\[0\]\.speed = 0\.5, 0\.22, 0\.3 is invalid"),
        ({"sensing_range_m": 0.5}, r"^sensing_range_m, robot_radius = 0\.5, 0\.22 is invalid"),
        (
            {"clearance_governor_m": 0.9},
            r"^clearance_governor_m, sensing_range_m, robot_radius = 0\.9, 1\.0, 0\.22 is inv",
        ),
        ({"width": 0.0}, r"^width = 0\.0 is invalid"),  # on its own first
        ({"width": 0.0, "robot_radius": -1.0}, r"^width = 0\.0 is invalid"),
        ({"width": 12.0, "robot_radius": -1.0}, r"^robot_radius = -1\.0 is invalid"),
        ({"station_bays": 2, "robot_radius": 9.0}, r"^robot_radius, width, height = 9\.0, "),
    ],
    ids=lambda x: x if isinstance(x, str) else repr(x),
)
def test_a_refusal_names_the_field_given_or_every_field_of_the_rule(
    kwargs: dict[str, Any], pattern: str
) -> None:
    """`width=1e-300` used to be reported as a bad `robot_radius`, radius 2.0 as a bad
    `queue_spacing_m`."""
    with pytest.raises(ValueError, match=pattern):
        tavc_env.make_config("dahl2004", **kwargs)
