"""Fuzzing numbers of every type (issue 28, item 6): any value, of any type, in any number field of
an arena, of its parts (Circuit, Robot, Breakdown) and of the helper constructors. Every outcome
is one of two: accepted, with every number stored as a plain float or int, and the arena then
builds an env, resets and steps; or refused by the package's ValueError naming the field (or
argument) given, alone or among the fields of the rule it breaks.

The outcomes of each family are counted as hypothesis events; the tally of a run:

    python -m pytest tests/fuzz/test_number_types.py -p no:xdist --hypothesis-show-statistics
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

import tavc_env
from tavc_env.config import ArenaConfig, Breakdown, Circuit, Robot
from tavc_env.validation import plain_number
from tests.fuzz.strategies import HOSTILE, fuzz_settings, typed_integer, typed_number

BASE = tavc_env.preset("dahl2004")
FIELDS = {f.name for f in dataclasses.fields(ArenaConfig)}
# the number fields of ArenaConfig, each with the range its drawn numbers come from (around the
# preset's value, so that many are accepted; the hostile values go anywhere)
NUMBER_FIELDS: dict[str, tuple[float, float]] = {
    name: (0.0, 2.0 * float(getattr(BASE, name)) or 1.0)
    for name in (
        "width",
        "height",
        "robot_radius",
        "source_service_s",
        "sink_service_s",
        "service_reference_speed",
        "queue_offset_m",
        "queue_spacing_m",
        "join_radius_m",
        "dock_tolerance_m",
        "speed_noise",
        "max_turn_rate",
        "sensing_range_m",
        "dt",
        "clearance_governor_m",
    )
}


def names(error: ValueError) -> list[str]:
    """The fields a refusal names ("a, b = 1, 2 is invalid; allowed: ..."), `len(x)` read as x."""
    text = str(error)
    assert "\n" not in text, text
    if text.startswith("unknown configuration key"):
        return ["<unknown key>"]
    assert " is invalid; allowed: " in text, text
    return [re.sub(r"^len\((.*)\)$", r"\1", n) for n in text.split(" = ")[0].split(", ")]


def names_any(error: ValueError, *prefixes: str) -> bool:
    """Whether the refusal names a field starting with one of `prefixes` (a field, or an item of
    one: `values` covers `values[1]`)."""
    return any(re.match(rf"{re.escape(p)}(?!\w)", n) for n in names(error) for p in prefixes)


def all_plain(config: ArenaConfig) -> bool:
    numbers: list[Any] = [getattr(config, name) for name in NUMBER_FIELDS]
    numbers += [config.station_bays, *config.start_circuits]
    for c in config.circuits:
        numbers += [*c.source, *c.sink, *c.queue_direction, c.value]
    numbers += [r.speed for r in config.robots]
    for b in config.breakdowns:
        numbers += [b.robot, b.at_s, 1.0 if b.repair_after_s is None else b.repair_after_s]
    labels_plain = all(type(r.speed_class) is str for r in config.robots)
    return labels_plain and all(type(v) in (float, int) for v in numbers)


def runs(config: ArenaConfig) -> None:
    """An env on `config` builds, resets and takes three steps of 20 physics ticks."""
    assert all_plain(config), repr(config)
    interval = 20 * config.dt
    env = tavc_env.parallel_env(
        config=config, decision_interval_s=interval, max_sim_time_s=3 * interval
    )
    _, infos = env.reset(seed=0)
    while env.agents:
        actions = {a: 0 for a in env.agents if infos[a]["action_required"]}
        _, rewards, _, _, infos = env.step(actions)
        assert all(math.isfinite(r) for r in rewards.values())
    assert env.sim.ticks == 60


def field_value(field: str) -> st.SearchStrategy[Any]:
    """Near the preset's value (mostly accepted), anywhere in twice its range, or hostile."""
    lo, hi = NUMBER_FIELDS[field]
    return st.one_of(typed_number(0.4 * hi, 0.6 * hi), typed_number(lo, hi), HOSTILE)


# -- family 1: any type in any number field of ArenaConfig --------------------------------------


@fuzz_settings(80)
@given(data=st.data(), field=st.sampled_from([*sorted(NUMBER_FIELDS), "station_bays"]))
def test_any_value_in_any_config_number_field_runs_or_is_refused_naming_it(
    data: st.DataObject, field: str
) -> None:
    value = data.draw(
        st.one_of(typed_integer(0, 9), HOSTILE) if field == "station_bays" else field_value(field),
        label=field,
    )
    try:
        config = tavc_env.make_config("dahl2004", **{field: value})
    except ValueError as error:
        assert names_any(error, field), str(error)
        event("refused, naming the field")
        return
    number = plain_number(value)
    assert number is not None, f"{field} = {value!r} accepted"
    assert getattr(config, field) == number
    runs(config)
    event("accepted and ran")


# -- family 2: the parts, alone and in an arena ---------------------------------------------------


def point_near(x: float, y: float) -> st.SearchStrategy[Any]:
    """A point near (x, y) (mostly accepted), anywhere in the arena, half hostile, or hostile."""
    return st.one_of(
        st.tuples(typed_number(x - 1.0, x + 1.0), typed_number(y - 0.5, y + 0.5)),
        st.tuples(typed_number(x - 1.0, x + 1.0), typed_number(y - 0.5, y + 0.5)),
        st.tuples(typed_number(0.0, 12.0), typed_number(0.0, 8.0)),
        st.tuples(typed_number(0.0, 12.0), HOSTILE),
        HOSTILE,
    )


# part -> (constructor, valid arguments, where it goes in dahl2004, field -> drawn values)
PARTS: dict[str, tuple[Any, dict[str, Any], str, dict[str, st.SearchStrategy[Any]]]] = {
    "circuit": (
        Circuit,
        dataclasses.asdict(BASE.circuits[1]),
        "circuits[1]",
        {
            "source": point_near(10.5, 6.5),
            "sink": point_near(10.5, 1.5),
            "value": st.one_of(typed_number(0.0, 5000.0), HOSTILE),
            "queue_direction": st.one_of(
                st.tuples(typed_number(-1.0, 1.0), typed_number(-1.0, 1.0)),
                st.sampled_from([(1e308, 1e308), (5e-324, 5e-324), (-1e308, 5e-324)]),
                point_near(-1.0, 0.0),
            ),
        },
    ),
    "robot": (
        Robot,
        {"speed": 0.3, "speed_class": "fast"},
        "robots[0]",
        {
            "speed": st.one_of(typed_number(0.0, 0.5), HOSTILE),
            "speed_class": st.one_of(st.text(max_size=4), HOSTILE),
        },
    ),
    "breakdown": (
        Breakdown,
        {"robot": 2, "at_s": 1.0, "repair_after_s": None},
        "breakdowns[0]",
        {
            "robot": st.one_of(typed_integer(0, 8), HOSTILE),
            "at_s": st.one_of(typed_number(0.0, 10.0), HOSTILE),
            "repair_after_s": st.one_of(st.none(), typed_number(0.0, 10.0), HOSTILE),
        },
    ),
}


def with_part(kind: str, part: Any) -> dict[str, Any]:
    if kind == "circuit":
        return {"circuits": (BASE.circuits[0], part)}
    if kind == "robot":
        return {"robots": (part, *BASE.robots[1:])}
    return {"breakdowns": (part,)}


@fuzz_settings(80)
@given(data=st.data(), kind=st.sampled_from(sorted(PARTS)))
def test_any_value_in_a_part_runs_or_is_refused_naming_the_part_or_its_field(
    data: st.DataObject, kind: str
) -> None:
    build, good, place, fields = PARTS[kind]
    field = data.draw(st.sampled_from(sorted(fields)), label="field")
    value = data.draw(fields[field], label=field)
    try:
        part = build(**{**good, field: value})
    except ValueError as error:
        assert names(error) == [f"{kind}.{field}"], str(error)
        event(f"{kind}: refused by the part")
        return
    try:
        config = tavc_env.make_config("dahl2004", **with_part(kind, part))
    except ValueError as error:
        assert names_any(error, place, place.split("[")[0]), str(error)
        event(f"{kind}: refused by the arena, naming {place}")
        return
    runs(config)
    event(f"{kind}: accepted and ran")


# -- family 3: the helper constructors -----------------------------------------------------------

COUNT = st.one_of(
    st.sampled_from([0, -1, 401, 10**6, 10**400, True, 2.0, "2", None]),
    st.builds(np.float64, st.integers(1, 3)),
    HOSTILE,
)


def speeds(n: int, lo: float = 0.1) -> st.SearchStrategy[Any]:
    return st.lists(typed_number(lo, 0.3), min_size=n, max_size=n)


ANY_SEQUENCE = st.one_of(
    st.lists(st.one_of(typed_number(0.0, 3000.0), HOSTILE), max_size=3),
    st.lists(typed_number(-1.0, 3.0), max_size=4),
    HOSTILE,
)
# helper -> its arguments, each: (a valid value, any value); one argument (or none) gets any value
HELPERS: dict[str, dict[str, tuple[st.SearchStrategy[Any], st.SearchStrategy[Any]]]] = {
    "lane_circuits": {
        "n_circuits": (typed_integer(1, 2), COUNT),
        "width": (typed_number(21.0, 30.0), st.one_of(typed_number(-1.0, 40.0), HOSTILE)),
        "height": (typed_number(8.0, 12.0), st.one_of(typed_number(-1.0, 20.0), HOSTILE)),
        "values": (st.none(), ANY_SEQUENCE),
        "wall_margin": (typed_number(1.0, 2.0), st.one_of(typed_number(-1.0, 10.0), HOSTILE)),
    },
    "scaled_config": {
        "n_circuits": (typed_integer(1, 3), COUNT),
        "robots_per_circuit": (typed_integer(1, 3), COUNT),
        "speeds": (speeds(2), ANY_SEQUENCE),
        "lane_spacing_m": (typed_number(3.0, 12.0), st.one_of(typed_number(-1.0, 20.0), HOSTILE)),
    },
    "robots_from_speeds": {"speeds": (speeds(6), st.one_of(speeds(6, 0.0), ANY_SEQUENCE))},
    "make_config": {
        "values": (st.lists(typed_number(1.0, 3000.0), min_size=2, max_size=2), ANY_SEQUENCE),
        "speeds": (speeds(6), ANY_SEQUENCE),
    },
}
CALLS = {
    "lane_circuits": tavc_env.lane_circuits,
    "scaled_config": tavc_env.scaled_config,
    "robots_from_speeds": tavc_env.robots_from_speeds,
    "make_config": lambda **kw: tavc_env.make_config("dahl2004", **kw),
}


@st.composite
def helper_calls(draw: st.DrawFn) -> tuple[str, dict[str, Any], tuple[str, ...]]:
    """(helper, its arguments, the names a refusal may give): valid arguments but one (or none)
    that may be anything; `replace` with a field of dahl2004 (or any key) set to any value."""
    name = draw(st.sampled_from([*sorted(HELPERS), "replace"]))
    if name == "replace":
        field = draw(st.sampled_from(sorted(NUMBER_FIELDS)))
        hi = NUMBER_FIELDS[field][1]
        key = draw(st.one_of(st.just(field), st.just(field), st.text(max_size=6)))
        value = draw(st.one_of(typed_number(0.4 * hi, 0.6 * hi), field_value(field)))
        return name, {key: value}, (*FIELDS, "<unknown key>")
    arguments = HELPERS[name]
    odd = draw(st.sampled_from([None, *sorted(arguments)]))
    drawn = {a: draw(any_ if a == odd else valid) for a, (valid, any_) in arguments.items()}
    if name == "lane_circuits" and odd is None and draw(st.booleans()):
        drawn["values"] = draw(
            st.lists(typed_number(1.0, 3000.0), min_size=1, max_size=1).map(
                lambda v: v * int(drawn["n_circuits"])
            )
        )
    return name, drawn, (*arguments, *FIELDS)


def as_arena(name: str, built: Any) -> ArenaConfig:
    """The arena a helper's result makes (lanes with two robots, robots in dahl2004's lanes)."""
    if name == "lane_circuits":
        width = max(c.source[0] for c in built) + 1.5
        height = max(c.source[1] for c in built) + 1.5
        return ArenaConfig(width=width, height=height, circuits=built, robots=(Robot(0.3),) * 2)
    if name == "robots_from_speeds":
        return tavc_env.make_config("dahl2004", robots=built)
    assert isinstance(built, ArenaConfig)
    return built


@fuzz_settings(80)
@given(call=helper_calls())
def test_the_helper_constructors_build_a_running_arena_or_refuse_naming_an_argument(
    call: tuple[str, dict[str, Any], tuple[str, ...]],
) -> None:
    name, arguments, allowed = call
    try:
        built = BASE.replace(**arguments) if name == "replace" else CALLS[name](**arguments)
    except ValueError as error:
        assert names_any(error, *allowed), f"{name}: {error}"
        event(f"{name}: refused, naming an argument")
        return
    try:
        config = as_arena(name, built)
    except ValueError as error:  # lanes or robots that the arena around them refuses
        assert names_any(error, *FIELDS), f"{name}: {error}"
        event(f"{name}: built; its arena refused, naming a field")
        return
    runs(config)
    event(f"{name}: built and ran")


def test_the_tally_helpers_read_a_relating_rule() -> None:
    """The harness's own check: every field of a relating rule is read from its message."""
    with pytest.raises(ValueError) as caught:
        tavc_env.make_config("dahl2004", width=1e-300)
    assert names(caught.value) == ["robot_radius", "width", "height"]
    assert names_any(caught.value, "width") and not names_any(caught.value, "dt")
