"""Bad input (DESIGN.md section 2): an action outside the space for a robot that must decide, a
missing action for such a robot, an unknown action key, an unknown config key or an impossible
config raise a `ValueError` that names the robot or field, the bad value and what is allowed.
Never a silent fallback, never a corrupted state: a rejected step leaves the env exactly as it was
(state, simulated time, counters, generator) and the env then steps exactly like a twin that never
saw the bad input.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import tavc_env
from tests.helpers import lockstep

INF, NAN = math.inf, math.nan
LANES = tavc_env.lane_circuits(2, values=(2200.0, 2000.0))


# -- helpers -----------------------------------------------------------------------------------


def _snapshot(env: tavc_env.TavcArenaEnv) -> tuple[Any, ...]:
    tasks = env.sim.tasks
    return (
        env.state().tobytes(),
        env.sim.positions().tobytes(),
        env.sim.time_s,
        env.sim.ticks,
        env.num_cycles,
        tuple(env.agents),
        repr(env.sim.rng.bit_generator.state),
        tasks.phase.tobytes(),
        tasks.mode.tobytes(),
        tasks.circuit.tobytes(),
        tasks.decision_time.tobytes(),
        env.sim.speed_factor.tobytes(),
        tuple((tuple(s.occupants), tuple(s.line)) for s in tasks.stations),
    )


def _twins(steps_before: int = 0, seed: int = 3, **kwargs: Any) -> tuple[Any, Any, Any]:
    """Two envs in the same state (reset with `seed`, then `steps_before` identical steps of
    everyone choosing circuit 1); returns them and the last (obs, infos)."""
    env, twin = tavc_env.parallel_env(**kwargs), tavc_env.parallel_env(**kwargs)
    out: tuple[Any, ...] = env.reset(seed=seed)
    twin.reset(seed=seed)
    for _ in range(steps_before):
        actions = {a: 1 for a in out[0] if out[-1][a]["action_required"]}
        out = env.step(actions)
        twin.step(actions)
    return env, twin, (out[0], out[-1])


def assert_rejected(
    env: tavc_env.TavcArenaEnv,
    twin: tavc_env.TavcArenaEnv,
    start: tuple[dict, dict],
    actions: Any,
    pattern: str,
) -> None:
    """`env.step(actions)` raises a ValueError matching `pattern` that says what is allowed,
    changes nothing, and `env` then steps exactly like `twin`."""
    before = _snapshot(env)
    with pytest.raises(ValueError, match=pattern) as error:
        env.step(actions)
    assert "allowed" in str(error.value)
    assert _snapshot(env) == before, "a rejected step changed the env"
    lockstep(env, twin, 3, start)


def _all(obs: dict[str, Any], circuit: int = 0) -> dict[str, int]:
    return dict.fromkeys(obs, circuit)


# -- actions -----------------------------------------------------------------------------------

BAD_ACTIONS = [
    5,
    2,
    -1,
    1.5,
    1.0,
    "0",
    True,
    False,
    np.int64(7),
    np.float32(1.0),
    np.bool_(True),
    np.array([1]),
    [0],
    (1,),
]


@pytest.mark.parametrize("bad", BAD_ACTIONS, ids=repr)
def test_action_outside_the_space_for_a_deciding_robot(bad: Any) -> None:
    env, twin, start = _twins()
    actions = {**_all(start[0]), "robot_2": bad}
    pattern = rf"robot_2 = {re.escape(repr(bad))} is invalid; allowed: .*\[0, 1\]"
    assert_rejected(env, twin, start, actions, pattern)


def test_bad_action_mid_episode_for_a_robot_that_became_deciding() -> None:
    env, twin, start = _twins(steps_before=3)
    deciding = [a for a, info in start[1].items() if info["action_required"]]
    busy = [a for a, info in start[1].items() if not info["action_required"]]
    assert deciding and busy
    actions = {**_all(start[0]), deciding[0]: 2}
    assert_rejected(env, twin, start, actions, rf"{deciding[0]} = 2 is invalid; allowed")


def test_bad_action_in_fixed_interval_mode() -> None:
    env, twin, start = _twins(steps_before=4, decision_interval_s=30.0)
    deciding = [a for a, info in start[1].items() if info["action_required"]]
    assert deciding, "after 120 s some robot has completed its first task"
    actions = {**_all(start[0]), deciding[-1]: -3}
    assert_rejected(env, twin, start, actions, rf"{deciding[-1]} = -3 is invalid; allowed")


@pytest.mark.parametrize("how", ["absent", "None"])
def test_missing_action_for_a_deciding_robot(how: str) -> None:
    env, twin, start = _twins()
    actions: dict[str, Any] = _all(start[0])
    if how == "absent":
        del actions["robot_4"]
    else:
        actions["robot_4"] = None
    assert_rejected(env, twin, start, actions, r"missing action for robot_4.*allowed.*\[0, 1\]")


def test_missing_action_mid_episode() -> None:
    env, twin, start = _twins(steps_before=2)
    actions = {a: 0 for a, info in start[1].items() if info["action_required"]}
    dropped = sorted(actions)[0]
    del actions[dropped]
    assert_rejected(env, twin, start, actions, rf"missing action for {dropped}\b")


def test_empty_action_dict_when_robots_must_decide() -> None:
    env, twin, start = _twins()
    assert_rejected(env, twin, start, {}, r"missing action for robot_0")


@pytest.mark.parametrize("key", ["robot_6", "robot_9", "ROBOT_0", "robot0", 3, None])
def test_unknown_action_key(key: Any) -> None:
    env, twin, start = _twins()
    actions: dict[Any, Any] = {**_all(start[0]), key: 0}
    pattern = rf"action key {re.escape(repr(key))} is unknown; allowed: .*'robot_0'.*'robot_5'"
    assert_rejected(env, twin, start, actions, pattern)


def test_unknown_action_key_mid_episode_with_only_busy_robots_named() -> None:
    """An unknown key is rejected even when every known robot is fine."""
    env, twin, start = _twins(steps_before=2)
    actions = {a: 0 for a, info in start[1].items() if info["action_required"]}
    assert_rejected(env, twin, start, {**actions, "robot_42": 1}, r"'robot_42' is unknown")


@pytest.mark.parametrize("actions", [[0] * 6, (0, 1), "robot_0", None], ids=repr)
def test_actions_must_be_a_dict(actions: Any) -> None:
    env, twin, start = _twins()
    assert_rejected(env, twin, start, actions, r"actions = .* is invalid; allowed: a dict")


def test_step_after_the_episode_ended_raises() -> None:
    env = tavc_env.parallel_env(max_cycles=1)
    obs, _ = env.reset(seed=0)
    env.step(_all(obs))
    assert env.agents == []
    with pytest.raises(ValueError, match=r"finished episode.*reset"):
        env.step({})


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    robot=st.integers(0, 5),
    bad=st.one_of(
        st.integers().filter(lambda x: not 0 <= x < 2),
        st.floats(allow_nan=True, allow_infinity=True),
        st.text(max_size=3),
        st.booleans(),
        st.lists(st.integers(0, 1), max_size=2),
        st.complex_numbers(max_magnitude=2),
    ),
)
def test_property_any_out_of_space_action_is_rejected_and_changes_nothing(
    robot: int, bad: Any
) -> None:
    env = tavc_env.parallel_env()
    obs, _ = env.reset(seed=1)
    before = _snapshot(env)
    agent = f"robot_{robot}"
    with pytest.raises(ValueError, match=rf"{agent} = {re.escape(repr(bad))} is invalid"):
        env.step({**_all(obs), agent: bad})
    assert _snapshot(env) == before


# -- configuration -----------------------------------------------------------------------------

# (keyword arguments of tavc_env.parallel_env, pattern naming the field and the bad value)
BAD_CONFIGS: list[tuple[dict[str, Any], str]] = [
    (
        {"foo": 1},
        r"unknown configuration key\(s\) \['foo'\]: neither an arena field .* nor an env option .*"
        r"allowed: arena fields .*'speeds'.*; env options .*'decision_interval_s'",
    ),
    ({"render_mod": "human"}, r"unknown configuration key\(s\) \['render_mod'\]"),
    ({"speeds": [0.3, 0.3, 0.3, -0.2, 0.2, 0.2]}, r"speeds\[3\] = -0\.2 is invalid; allowed"),
    ({"speeds": [0.0] * 6}, r"speeds\[0\] = 0\.0 is invalid"),
    ({"speeds": [3.0] * 6}, r"speeds\[0\] = 3\.0 is invalid; allowed: .*\(0, 2\]"),
    ({"speeds": [0.3, NAN]}, r"speeds\[1\] = nan is invalid"),
    ({"speeds": []}, r"speeds = \[\] is invalid; allowed: a non-empty"),
    ({"speeds": [0.3], "robots": (tavc_env.Robot(speed=0.3),)}, r"speeds = .*speeds or robots"),
    ({"robots": ()}, r"robots = \(\) is invalid; allowed: at least one Robot"),
    ({"robots": (0.3,)}, r"robots\[0\] = 0\.3 is invalid; allowed: a tavc_env\.Robot"),
    (
        {"circuits": (tavc_env.Circuit(source=(13.0, 6.5), sink=(1.5, 1.5), value=2.0), LANES[1])},
        r"circuits\[0\]\.source, width, height, robot_radius = \(13\.0, 6\.5\), 12\.0, 8\.0, 0\.22 "
        r"is invalid; allowed: a point inside the arena",
    ),
    (
        {
            "circuits": (
                LANES[0],
                tavc_env.Circuit(source=(10.5, 6.5), sink=(10.5, -1.0), value=2.0),
            )
        },
        r"circuits\[1\]\.sink, width, height, robot_radius = \(10\.5, -1\.0\), .* is invalid; "
        r"allowed: a point inside the arena",
    ),
    (  # inside the walls, but a robot standing there would overlap the wall
        {"circuits": (LANES[0], tavc_env.Circuit(source=(11.9, 6.5), sink=(10.5, 1.5), value=2.0))},
        r"circuits\[1\]\.source, width, height, robot_radius = \(11\.9, 6\.5\), ",
    ),
    (
        {"circuits": (LANES[0], LANES[0])},
        r"circuits\[1\]\.source \(distance to circuits\[0\]\.source\), robot_radius = 0\.0, 0\.22 "
        r"is invalid; "
        r"allowed: .*overlapping circuits",
    ),
    (
        {"circuits": (LANES[0], tavc_env.Circuit(source=(6.0, 6.5), sink=(1.8, 1.5), value=2.0))},
        r"circuits\[1\]\.sink \(distance to circuits\[0\]\.sink\), robot_radius = 0\.3, 0\.22 is inv",
    ),
    ({"circuits": ()}, r"circuits = \(\) is invalid; allowed: at least one Circuit"),
    (
        {"speeds": [0.25] * 100},
        r"robots, robot_radius, width, height = '100 robots', 0\.22, 12\.0, 8\.0 is invalid; "
        r"allowed: .*cannot fit",
    ),
    (
        {"breakdowns": (tavc_env.Breakdown(robot=6, at_s=10.0),)},
        r"breakdowns\[0\]\.robot, len\(robots\) = 6, 6 is invalid; allowed: a robot index in "
        r".*\[0, 5\]",
    ),
    ({"breakdowns": ("robot_0",)}, r"breakdowns\[0\] = 'robot_0' is invalid"),
    ({"dt": 0.0}, r"dt = 0\.0 is invalid; allowed: a physics step in \(0, 0\.5\]"),
    ({"dt": -0.1}, r"dt = -0\.1 is invalid"),
    ({"dt": 0.6}, r"dt = 0\.6 is invalid"),
    ({"dt": NAN}, r"dt = nan is invalid"),
    ({"dt": "0.1"}, r"dt = '0\.1' is invalid"),
    ({"render_mode": "ascii"}, r"render_mode = 'ascii' is invalid; allowed: .*'rgb_array'"),
    ({"render_mode": "RGB_ARRAY"}, r"render_mode = 'RGB_ARRAY' is invalid"),
    ({"reward_time_unit": "min"}, r"reward_time_unit = 'min' is invalid; allowed: .*'ms'"),
    ({"reward_time_unit": None}, r"reward_time_unit = None is invalid"),
    ({"max_cycles": 0}, r"max_cycles = 0 is invalid; allowed: an integer >= 1"),
    ({"max_cycles": -3}, r"max_cycles = -3 is invalid"),
    ({"max_cycles": 10.5}, r"max_cycles = 10\.5 is invalid"),
    ({"max_cycles": "100"}, r"max_cycles = '100' is invalid"),
    ({"max_cycles": True}, r"max_cycles = True is invalid"),
    ({"max_cycles": None}, r"max_cycles = None is invalid"),
    ({"max_sim_time_s": -1.0}, r"max_sim_time_s = -1\.0 is invalid; allowed: a time >="),
    ({"max_sim_time_s": 0.0}, r"max_sim_time_s = 0\.0 is invalid"),
    ({"max_sim_time_s": NAN}, r"max_sim_time_s = nan is invalid"),
    ({"max_sim_time_s": "3600"}, r"max_sim_time_s = '3600' is invalid"),
    ({"decision_interval_s": 0.0}, r"decision_interval_s = 0\.0 is invalid; allowed: None"),
    ({"decision_interval_s": 0.05}, r"decision_interval_s = 0\.05 is invalid"),
    ({"decision_interval_s": NAN}, r"decision_interval_s = nan is invalid"),
    ({"decision_interval_s": "30"}, r"decision_interval_s = '30' is invalid"),
    ({"step_cap_s": 0.0}, r"step_cap_s = 0\.0 is invalid; allowed: a finite time >="),
    ({"step_cap_s": NAN}, r"step_cap_s = nan is invalid"),
    ({"preset": "dahl2005"}, r"preset = 'dahl2005' is invalid; allowed: .*'dahl2004'"),
    ({"config": "dahl2004"}, r"config = 'dahl2004' is invalid; allowed: a tavc_env\.ArenaConfig"),
    ({"values": (1.0,)}, r"values = \(1\.0,\) is invalid; allowed: a sequence of 2"),
    ({"values": (-1.0, 2.0)}, r"values\[0\] = -1\.0 is invalid; allowed: a finite number > 0"),
    ({"values": (0.0, 2.0)}, r"values\[0\] = 0\.0 is invalid"),
    ({"speed_noise": 0.5}, r"speed_noise = 0\.5 is invalid; allowed: .*\[0, 0\.3\]"),
    ({"speed_noise": -0.1}, r"speed_noise = -0\.1 is invalid"),
    ({"robot_radius": 0.0}, r"robot_radius = 0\.0 is invalid"),
    (
        {"robot_radius": 3.0},
        r"robot_radius, width, height = 3\.0, 12\.0, 8\.0 is invalid; allowed: .*a quarter",
    ),
    ({"width": -12.0}, r"width = -12\.0 is invalid"),
    ({"height": 0}, r"height = 0 is invalid"),
    ({"source_service_s": -1.0}, r"source_service_s = -1\.0 is invalid; allowed: .*>= 0"),
    ({"sink_service_s": INF}, r"sink_service_s = inf is invalid"),
    (
        {"queue_spacing_m": 0.2},
        r"queue_spacing_m, robot_radius = 0\.2, 0\.22 is invalid; allowed: .*the robot diam",
    ),
    ({"queue_offset_m": 0.1}, r"queue_offset_m, robot_radius = 0\.1, 0\.22 is invalid"),
    ({"join_radius_m": 0.0}, r"join_radius_m = 0\.0 is invalid"),
    ({"dock_tolerance_m": -0.1}, r"dock_tolerance_m = -0\.1 is invalid"),
    ({"max_turn_rate": 0.0}, r"max_turn_rate = 0\.0 is invalid"),
    ({"sensing_range_m": INF}, r"sensing_range_m = inf is invalid"),
]


@pytest.mark.parametrize(
    ("kwargs", "pattern"), BAD_CONFIGS, ids=[repr(k)[:60] for k, _ in BAD_CONFIGS]
)
@pytest.mark.parametrize("view", ["parallel", "aec"])
def test_bad_config_raises_naming_field_and_value(
    kwargs: dict[str, Any], pattern: str, view: str
) -> None:
    factory = tavc_env.parallel_env if view == "parallel" else tavc_env.env
    with pytest.raises(ValueError, match=pattern) as error:
        factory(**kwargs)
    assert "allowed" in str(error.value)


@pytest.mark.parametrize(
    ("build", "pattern"),
    [
        (lambda: tavc_env.Robot(speed=-1.0), r"robot\.speed = -1\.0 is invalid"),
        (lambda: tavc_env.Robot(speed=True), r"robot\.speed = True is invalid"),
        (
            lambda: tavc_env.Circuit(source=(1.0, 1.0), sink=(3.0, 3.0), value=0.0),
            r"circuit\.value = 0\.0 is invalid",
        ),
        (
            lambda: tavc_env.Circuit(source=(1.0,), sink=(3.0, 3.0), value=1.0),
            r"circuit\.source = \(1\.0,\) is invalid; allowed: a pair of finite numbers",
        ),
        (
            lambda: tavc_env.Circuit(source=(1.0, NAN), sink=(3.0, 3.0), value=1.0),
            r"circuit\.source = \(1\.0, nan\) is invalid",
        ),
        (
            lambda: tavc_env.Circuit(
                source=(1.0, 1.0), sink=(3.0, 3.0), value=1.0, queue_direction=(0.0, 0.0)
            ),
            r"circuit\.queue_direction = \(0\.0, 0\.0\) is invalid; allowed: a non-zero vector",
        ),
        (lambda: tavc_env.Breakdown(robot=-1, at_s=1.0), r"breakdown\.robot = -1 is invalid"),
        (lambda: tavc_env.Breakdown(robot=True, at_s=1.0), r"breakdown\.robot = True is invalid"),
        (lambda: tavc_env.Breakdown(robot=0, at_s=-5.0), r"breakdown\.at_s = -5\.0 is invalid"),
        (
            lambda: tavc_env.Breakdown(robot=0, at_s=5.0, repair_after_s=0.0),
            r"breakdown\.repair_after_s = 0\.0 is invalid; allowed: None or a duration > 0",
        ),
        (lambda: tavc_env.lane_circuits(0), r"n_circuits = 0 is invalid"),
        (
            lambda: tavc_env.lane_circuits(2, values=(1.0,)),
            r"values = \(1\.0,\) is invalid; allowed: a sequence of 2",
        ),
        (lambda: tavc_env.preset("nope"), r"preset = 'nope' is invalid"),
        (
            lambda: tavc_env.preset("dahl2004").replace(dt=0.0),
            r"dt = 0\.0 is invalid",
        ),
    ],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_bad_component_raises_naming_field_and_value(build: Any, pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        build()


POSITIVE_FIELDS = [
    "width",
    "height",
    "robot_radius",
    "queue_offset_m",
    "queue_spacing_m",
    "join_radius_m",
    "dock_tolerance_m",
    "max_turn_rate",
    "sensing_range_m",
]


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(POSITIVE_FIELDS),
    value=st.one_of(
        st.floats(max_value=0.0),
        st.integers(max_value=0),
        st.sampled_from([NAN, INF, -INF, True, False, None, "1.0", (1.0,)]),
    ),
)
def test_property_non_positive_or_non_finite_lengths_are_rejected(name: str, value: Any) -> None:
    with pytest.raises(
        ValueError, match=rf"^{name} = {re.escape(repr(value))} is invalid; allowed"
    ):
        tavc_env.parallel_env(**{name: value})


@settings(max_examples=30, deadline=None)
@given(
    x=st.one_of(st.floats(-5.0, 0.26), st.floats(11.74, 20.0)),
    y=st.floats(-5.0, 15.0),
    which=st.sampled_from(["source", "sink"]),
    swap=st.booleans(),
)
def test_property_stations_outside_the_arena_are_rejected(
    x: float, y: float, which: str, swap: bool
) -> None:
    """Any station whose centre is closer than radius + 5 cm to a wall (or beyond it) is rejected,
    naming the circuit, the station and the point."""
    point = (y * 12.0 / 15.0, x * 8.0 / 12.0) if swap else (x, y)
    inside_x = 0.27 <= point[0] <= 11.73
    inside_y = 0.27 <= point[1] <= 7.73
    if inside_x and inside_y:  # the swap can map a point inside; not this property's concern
        return
    circuit = LANES[1]
    moved = (
        tavc_env.Circuit(source=point, sink=circuit.sink, value=circuit.value)
        if which == "source"
        else tavc_env.Circuit(source=circuit.source, sink=point, value=circuit.value)
    )
    pattern = (
        rf"circuits\[1\]\.{which}, width, height, robot_radius = {re.escape(repr(point))}, 12\.0, "
        r"8\.0, 0\.22 is invalid; allowed: a point"
    )
    with pytest.raises(ValueError, match=pattern):
        tavc_env.parallel_env(circuits=(LANES[0], moved))


# -- time arguments of the env ----------------------------------------------------------------


@pytest.mark.parametrize("name", ["max_sim_time_s", "decision_interval_s", "step_cap_s"])
def test_bool_is_not_a_time(name: str) -> None:
    with pytest.raises(ValueError, match=rf"{name} = True is invalid"):
        tavc_env.parallel_env(**{name: True})


def test_infinite_step_cap_is_rejected() -> None:
    with pytest.raises(ValueError, match=r"step_cap_s = inf is invalid; allowed: a finite time"):
        tavc_env.parallel_env(max_sim_time_s=INF, step_cap_s=INF)


def test_infinite_time_limit_with_a_finite_step_cap_works() -> None:
    env = tavc_env.parallel_env(max_sim_time_s=INF)
    obs, _ = env.reset(seed=0)
    env.step(_all(obs))  # event-driven: returns at the first completion
    assert env.agents and env.sim.time_s > 0


def test_infinite_decision_interval_with_no_time_limit_is_rejected() -> None:
    with pytest.raises(ValueError, match="decision_interval_s"):
        tavc_env.parallel_env(max_sim_time_s=INF, decision_interval_s=INF)


def test_decision_interval_not_a_multiple_of_dt_is_rejected() -> None:
    with pytest.raises(ValueError, match=r"decision_interval_s = 0.25 is invalid.*multiples of dt"):
        tavc_env.parallel_env(decision_interval_s=0.25)


def test_decision_interval_that_is_a_multiple_of_dt_is_honoured() -> None:
    env = tavc_env.parallel_env(decision_interval_s=0.3)
    obs, _ = env.reset(seed=0)
    env.step(_all(obs))
    assert env.sim.time_s == pytest.approx(0.3)


# -- issue 12: bad input that used to reach a traceback ----------------------------------------

NOT_ITERABLE: list[tuple[dict[str, Any], str]] = [
    ({"circuits": 5}, r"^circuits = 5 is invalid; allowed: a sequence of tavc_env\.Circuit"),
    ({"robots": None}, r"^robots = None is invalid; allowed: a sequence of tavc_env\.Robot"),
    ({"breakdowns": 3}, r"^breakdowns = 3 is invalid; allowed: a sequence of tavc_env\.Breakdown"),
    ({"circuits": "ab"}, r"^circuits = 'ab' is invalid; allowed: a sequence"),
    ({"robots": {"speed": 0.3}}, r"^robots = \{'speed': 0\.3\} is invalid; allowed: a sequence"),
]


@pytest.mark.parametrize(("kwargs", "pattern"), NOT_ITERABLE, ids=lambda x: repr(x)[:40])
@pytest.mark.parametrize("view", ["parallel", "aec", "config"])
def test_a_config_field_that_is_not_a_sequence_is_a_value_error(
    kwargs: dict[str, Any], pattern: str, view: str
) -> None:
    """Used to be `TypeError: 'int' object is not iterable` from `tuple(self.circuits)`."""
    factories = {"parallel": tavc_env.parallel_env, "aec": tavc_env.env}
    with pytest.raises(ValueError, match=pattern):
        if view == "config":
            tavc_env.ArenaConfig(
                **{**{"circuits": LANES, "robots": (tavc_env.Robot(0.3),)}, **kwargs}
            )
        else:
            factories[view](**kwargs)


@pytest.mark.parametrize("name", [[1], {"a": 1}, {1}, 3])
def test_an_unhashable_or_non_string_preset_name_is_a_value_error(name: Any) -> None:
    """`preset=[1]` used to be `TypeError: unhashable type: 'list'`."""
    pattern = rf"^preset = {re.escape(repr(name))} is invalid; allowed: one of \['dahl2004'"
    with pytest.raises(ValueError, match=pattern):
        tavc_env.preset(name)
    with pytest.raises(ValueError, match=pattern):
        tavc_env.parallel_env(preset=name)


INTEGER_SEEDS = [np.int64(3), np.int32(3), np.uint8(3), np.uint64(3), np.int16(3)]


@pytest.mark.parametrize("seed", INTEGER_SEEDS, ids=lambda s: type(s).__name__)
def test_a_numpy_integer_seed_is_the_same_seed(seed: Any) -> None:
    """`reset(seed=np.int64(3))` used to be refused by gymnasium ("must be a python integer")."""
    env, twin = tavc_env.parallel_env(), tavc_env.parallel_env()
    start = env.reset(seed=seed)
    assert repr(start) == repr(twin.reset(seed=3))
    lockstep(env, twin, 3, start)


def test_a_numpy_integer_seed_in_the_aec_view() -> None:
    aec, twin = tavc_env.env(), tavc_env.env()
    aec.reset(seed=np.int64(5))
    twin.reset(seed=5)
    assert repr(aec.unwrapped.state()) == repr(twin.unwrapped.state())


BAD_SEEDS = [True, False, np.bool_(True), 3.0, np.float64(3.0), "3", -1, np.int64(-2), [3]]


def test_a_large_python_integer_is_a_seed() -> None:
    env = tavc_env.parallel_env()
    env.reset(seed=2**128)  # numpy's SeedSequence takes any integer >= 0


@pytest.mark.parametrize("seed", BAD_SEEDS, ids=repr)
@pytest.mark.parametrize("view", ["parallel", "aec"])
def test_a_seed_that_is_not_a_non_negative_integer_is_refused(seed: Any, view: str) -> None:
    """`reset(seed=True)` used to be accepted as seed 1; floats, strings and negative numbers gave
    gymnasium's own error type instead of a ValueError."""
    env = tavc_env.parallel_env() if view == "parallel" else tavc_env.env()
    with pytest.raises(ValueError, match=rf"^seed = {re.escape(repr(seed))} is invalid; allowed"):
        env.reset(seed=seed)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        (
            {"decision_interval_s": 1e300},
            r"decision_interval_s = 1e\+300 is invalid; allowed: .*at most max_sim_time_s",
        ),
        (
            {"decision_interval_s": 7200.0, "max_sim_time_s": 3600.0},
            r"decision_interval_s = 7200\.0 is invalid; allowed: .*at most max_sim_time_s = 3600",
        ),
        (
            {"decision_interval_s": 1e300, "max_sim_time_s": INF},
            r"decision_interval_s = 1e\+300 is invalid; allowed: .*at most",
        ),
        ({"max_sim_time_s": 1e300}, r"max_sim_time_s = 1e\+300 is invalid; allowed: .*at most"),
        ({"step_cap_s": 1e300}, r"step_cap_s = 1e\+300 is invalid; allowed: .*at most"),
    ],
)
def test_time_arguments_beyond_the_episode_or_a_float_are_refused(
    kwargs: dict[str, Any], pattern: str
) -> None:
    """`decision_interval_s=1e300` used to be accepted and truncated the episode at its first
    step without saying why."""
    with pytest.raises(ValueError, match=pattern):
        tavc_env.parallel_env(**kwargs)


def test_a_decision_interval_equal_to_the_episode_is_one_step() -> None:
    env = tavc_env.parallel_env(decision_interval_s=60.0, max_sim_time_s=60.0)
    obs, _ = env.reset(seed=0)
    *_, truncations, _ = env.step(_all(obs))
    assert all(truncations.values()) and env.sim.time_s == pytest.approx(60.0)


# -- the AEC view ------------------------------------------------------------------------------


def _aec_state(aec: Any) -> tuple[Any, ...]:
    return (
        aec.agent_selection,
        _snapshot(aec.unwrapped),
        repr(aec.rewards),
        repr(aec._cumulative_rewards),
        repr(aec.terminations),
        repr(aec.truncations),
    )


def _drive(aec: Any, steps: int, rng_seed: int = 0) -> list[tuple[Any, ...]]:
    """Run `steps` agent turns choosing a valid circuit; record each `last()`."""
    rng = np.random.default_rng(rng_seed)
    out = []
    for _ in range(steps):
        obs, reward, term, trunc, info = aec.last()
        out.append((aec.agent_selection, repr(obs), reward, term, trunc, repr(info)))
        aec.step(None if term or trunc else int(rng.choice(np.flatnonzero(obs["action_mask"]))))
    return out


@pytest.mark.parametrize("bad", [5, -1, 1.5, "0", True, None, np.float32(1.0)], ids=repr)
@pytest.mark.parametrize("turn", [0, 2, 5])
def test_aec_bad_action_is_refused_at_its_agent_and_changes_nothing(bad: Any, turn: int) -> None:
    """PettingZoo's bare `parallel_to_aec` stored the bad action, raised when the *last* agent
    stepped (naming another agent), kept the bad action and so raised again on every later step:
    the env was stuck. Now the agent that gives the bad action gets the ValueError, and the env
    then runs exactly like a twin that never saw it."""
    aec, twin = tavc_env.env(), tavc_env.env()
    aec.reset(seed=4)
    twin.reset(seed=4)
    _drive(aec, turn)
    _drive(twin, turn)
    agent = aec.agent_selection
    assert aec.infos[agent]["action_required"]
    before = _aec_state(aec)
    pattern = rf"^action of {agent} = {re.escape(repr(bad))} is invalid; allowed: .*\[0, 1\]"
    with pytest.raises(ValueError, match=pattern):
        aec.step(bad)
    assert _aec_state(aec) == before
    assert _drive(aec, 20, rng_seed=1) == _drive(twin, 20, rng_seed=1)


def test_aec_action_of_a_robot_that_need_not_decide_is_ignored_as_in_the_parallel_view() -> None:
    aec = tavc_env.env()
    aec.reset(seed=0)
    _drive(aec, 6)  # the first decisions; then most robots are busy
    for _ in range(12):
        agent = aec.agent_selection
        if not aec.infos[agent]["action_required"]:
            aec.step(99)  # ignored, like an action for a busy robot in the parallel view
        else:
            aec.step(0)
    assert aec.unwrapped.num_cycles == 3


def test_aec_action_for_a_finished_agent_must_be_none() -> None:
    aec = tavc_env.env(max_cycles=1)
    aec.reset(seed=0)
    _drive(aec, 6)
    agent = aec.agent_selection
    assert aec.truncations[agent]
    with pytest.raises(ValueError, match=rf"^action of {agent} = 0 is invalid; allowed: None"):
        aec.step(0)
    aec.step(None)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"robot": 0, "at_s": INF}, r"^breakdown\.at_s = inf is invalid; allowed: a time >= 0"),
        ({"robot": 0, "at_s": NAN}, r"^breakdown\.at_s = nan is invalid"),
        ({"robot": 0, "at_s": True}, r"^breakdown\.at_s = True is invalid"),
        ({"robot": 0, "at_s": "5"}, r"^breakdown\.at_s = '5' is invalid"),
        ({"robot": 0.0, "at_s": 5.0}, r"^breakdown\.robot = 0\.0 is invalid; allowed: a robot"),
        ({"robot": "robot_0", "at_s": 5.0}, r"^breakdown\.robot = 'robot_0' is invalid"),
        (
            {"robot": 0, "at_s": 5.0, "repair_after_s": INF},
            r"^breakdown\.repair_after_s = inf is invalid; allowed: None or a duration > 0",
        ),
        ({"robot": 0, "at_s": 5.0, "repair_after_s": -1.0}, r"^breakdown\.repair_after_s = -1"),
    ],
)
def test_a_scheduled_breakdown_is_checked_when_it_is_made(
    kwargs: dict[str, Any], pattern: str
) -> None:
    """Times finite and >= 0, a robot index; the index is checked against the team when the
    arena is built (`breakdowns[0].robot = 6` above), never when the breakdown fires."""
    with pytest.raises(ValueError, match=pattern):
        tavc_env.Breakdown(**kwargs)


def test_a_numpy_integer_is_a_breakdown_robot_index() -> None:
    env = tavc_env.parallel_env(breakdowns=(tavc_env.Breakdown(np.int64(5), np.float64(1.0)),))
    obs, _ = env.reset(seed=0)
    _, _, _, _, infos = env.step(_all(obs))
    assert infos["robot_5"]["broken"]


@pytest.mark.parametrize("options", ["x", 3, ["a"], ("max_cycles", 5)], ids=repr)
@pytest.mark.parametrize("view", ["parallel", "aec"])
def test_reset_options_that_are_not_a_mapping_are_refused(options: Any, view: str) -> None:
    """issue 35: `reset(options='x')` was silently ignored."""
    env = tavc_env.parallel_env() if view == "parallel" else tavc_env.env()
    with pytest.raises(
        ValueError, match=rf"^options = {re.escape(repr(options))} is invalid; allowed: None or a"
    ):
        env.reset(seed=0, options=options)
    env.reset(seed=0, options={})  # a mapping (or None) is taken
