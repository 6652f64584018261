"""Fuzzing configurations: a valid arena runs without a Python exception and without overlap
beyond tolerance; an invalid one is refused with a ValueError naming its field; so are bad
arguments of the env and of `make_config`."""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

import tavc_env
from tavc_env.config import OVERLAP_TOLERANCE, PRESETS, ArenaConfig
from tavc_env.engine.simulation import EngineEvent, Simulation
from tests.fuzz.strategies import (
    INVALID_VALUES,
    NESTED,
    NOT_A_NUMBER,
    NOT_A_SEQUENCE,
    arena_fields,
    deepest_overlap,
    fuzz_settings,
    make_or_none,
    valid_config,
)

FIELDS = [f.name for f in dataclasses.fields(ArenaConfig)]
NESTED_PREFIXES = ("circuit.", "robot.", "breakdown.")


def named(error: ValueError) -> str:
    """What a refusal names: the text before ' = ' ("name = value is invalid; allowed: ...")."""
    text = str(error)
    assert " is invalid; allowed: " in text or text.startswith("unknown configuration key"), text
    return text.split(" = ")[0]


def names_a_field(error: ValueError) -> bool:
    name = named(error)
    return any(re.match(rf"{re.escape(f)}\b", name) for f in FIELDS) or name.startswith(
        NESTED_PREFIXES
    )


class OverlapWatch:
    """An observer measuring the deepest overlap after every physics tick."""

    def __init__(self, env: tavc_env.TavcArenaEnv) -> None:
        self.env = env
        self.deepest = 0.0
        self.at = 0.0

    def on_tick(self, sim: Simulation, events: list[EngineEvent]) -> None:
        depth = deepest_overlap(self.env)
        if depth > self.deepest:
            self.deepest, self.at = depth, sim.time_s


@fuzz_settings(50)
@given(
    config=valid_config(),
    seed=st.integers(0, 2**32 - 1),
    per_step=st.sampled_from([None, 1, 7, 25]),
)
def test_a_valid_config_runs_without_error_or_overlap(
    config: ArenaConfig, seed: int, per_step: int | None
) -> None:
    """Up to 800 physics ticks with random decisions (event-driven or every `per_step` ticks),
    scheduled breakdowns included; overlap measured after every tick."""
    env = tavc_env.parallel_env(
        config=config,
        decision_interval_s=None if per_step is None else per_step * config.dt,
        max_sim_time_s=800 * config.dt,
    )
    watch = OverlapWatch(env)
    env.sim.add_observer(watch)
    _, infos = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    m = config.n_circuits
    while env.agents:
        actions = {a: int(rng.integers(m)) for a in env.agents if infos[a]["action_required"]}
        _, rewards, _, _, infos = env.step(actions)
        assert all(math.isfinite(r) and r >= 0 for r in rewards.values())
    assert env.sim.ticks == 800
    assert watch.deepest <= OVERLAP_TOLERANCE, (
        f"robots overlap by {watch.deepest:.3f} radii at {watch.at:.1f} s"
    )


@fuzz_settings(40)
@given(fields=arena_fields())
def test_every_drawn_config_is_accepted_or_refused_naming_a_field(fields: dict[str, Any]) -> None:
    try:
        ArenaConfig(**fields)
    except ValueError as error:
        assert names_a_field(error), str(error)


@fuzz_settings(60)
@given(config=valid_config(), field=st.sampled_from(sorted(INVALID_VALUES)), data=st.data())
def test_an_invalid_field_is_refused_naming_it(
    config: ArenaConfig, field: str, data: st.DataObject
) -> None:
    value = data.draw(INVALID_VALUES[field], label=field)
    fields = {f: getattr(config, f) for f in FIELDS}
    fields[field] = value
    for build in (
        lambda: ArenaConfig(**fields),
        lambda: config.replace(**{field: value}),
        lambda: tavc_env.parallel_env(config=config, **{field: value}),
    ):
        with pytest.raises(ValueError) as caught:
            build()
        assert re.match(rf"{re.escape(field)}\b", named(caught.value)), str(caught.value)


@fuzz_settings(30)
@given(kind=st.sampled_from(sorted(NESTED)), data=st.data())
def test_an_invalid_circuit_robot_or_breakdown_is_refused_naming_its_field(
    kind: str, data: st.DataObject
) -> None:
    build, good, bad = NESTED[kind]
    field = data.draw(st.sampled_from(sorted(bad)), label="field")
    value = data.draw(bad[field], label="value")
    with pytest.raises(ValueError) as caught:
        build(**{**good, field: value})
    assert named(caught.value) == f"{kind}.{field}", str(caught.value)


ENV_ARGUMENTS: dict[str, st.SearchStrategy[Any]] = {
    "render_mode": st.one_of(st.text(max_size=6), st.just([]), st.just({}), st.integers()),
    "max_cycles": st.one_of(NOT_A_NUMBER, st.integers(-3, 3), st.floats(0.5, 10.0)),
    "max_sim_time_s": st.one_of(NOT_A_NUMBER, st.floats(-10.0, 1e20), st.integers(-5, 10**9)),
    "decision_interval_s": st.one_of(NOT_A_NUMBER, st.floats(-1.0, 1e300), st.integers(-2, 10)),
    "reward_time_unit": st.one_of(st.text(max_size=3), st.just(["ms"]), st.just({}), st.none()),
    "reward": st.one_of(
        st.sampled_from(["paper", "value", "Value"]), st.text(max_size=5), st.none()
    ),
    "step_cap_s": st.one_of(NOT_A_NUMBER, st.floats(-1.0, 1e20), st.integers(-2, 10**6)),
    "jam_window_s": st.one_of(NOT_A_NUMBER, st.floats(-1.0, 1e9), st.integers(-2, 10**6)),
}


@fuzz_settings(40)
@given(argument=st.sampled_from(sorted(ENV_ARGUMENTS)), data=st.data())
def test_env_arguments_are_accepted_or_refused_naming_them(
    argument: str, data: st.DataObject
) -> None:
    """Any value of an env argument builds a working env or raises a ValueError naming the
    argument; a bool is never taken for a number."""
    value = data.draw(ENV_ARGUMENTS[argument], label=argument)
    try:
        env = tavc_env.parallel_env(**{argument: value})
    except ValueError as error:
        assert named(error) == argument, str(error)
        return
    assert not isinstance(value, (bool, np.bool_)), f"{argument} = {value!r} was accepted"
    _, infos = env.reset(seed=0)
    env.step({a: 0 for a in env.agents if infos[a]["action_required"]})


@fuzz_settings(30)
@given(
    preset=st.one_of(
        st.text(max_size=12), st.integers(), st.none(), st.lists(st.text(max_size=2), max_size=2)
    ),
    key=st.text(min_size=1, max_size=12),
)
def test_make_config_refuses_unknown_presets_and_keys_naming_them(preset: Any, key: str) -> None:
    assume(not (isinstance(preset, str) and preset in PRESETS))
    if preset is None:  # None names the default preset
        assert tavc_env.make_config(preset) == tavc_env.preset("dahl2004")
        return
    with pytest.raises(ValueError, match=r"^preset = "):
        tavc_env.make_config(preset)
    with pytest.raises(ValueError, match=r"^preset = "):
        tavc_env.parallel_env(preset=preset)
    assume(key not in FIELDS and key not in ("speeds", "values"))
    with pytest.raises(ValueError, match=r"^unknown configuration key"):
        tavc_env.make_config("dahl2004", **{key: 1.0})


@fuzz_settings(30)
@given(
    speeds=st.one_of(
        st.lists(st.one_of(NOT_A_NUMBER, st.floats(-1.0, 0.0), st.floats(2.01, 1e9)), min_size=1),
        st.just([]),
        NOT_A_SEQUENCE,
    ),
    values=st.one_of(
        st.lists(st.one_of(NOT_A_NUMBER, st.floats(-1e9, 0.0)), min_size=2, max_size=2),
        st.lists(st.floats(1.0, 10.0), min_size=3, max_size=4),
        st.just([]),
        NOT_A_SEQUENCE,
    ),
)
def test_the_speeds_and_values_shorthands_refuse_bad_input_naming_it(
    speeds: Any, values: Any
) -> None:
    with pytest.raises(ValueError) as caught:
        tavc_env.make_config("dahl2004", speeds=speeds)
    assert named(caught.value).startswith("speeds"), str(caught.value)
    with pytest.raises(ValueError) as caught:
        tavc_env.make_config("dahl2004", values=values)
    assert named(caught.value).startswith(("values", "circuit.value")), str(caught.value)


def test_a_drawn_valid_config_is_valid() -> None:
    """The strategies' own check: `make_or_none` accepts a preset and refuses a broken copy."""
    fields = {f: getattr(tavc_env.preset("dahl2004"), f) for f in FIELDS}
    assert make_or_none(fields) is not None
    assert make_or_none({**fields, "dt": -1.0}) is None
