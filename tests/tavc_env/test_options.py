"""The env's own options (`tavc_env.EnvOptions`) and how `parallel_env` takes them beside the arena:
one validated value, given whole (`options=`) or as keyword overrides, never mistaken for the
arena."""

from __future__ import annotations

import math
import pickle
from typing import Any

import pytest

import tavc_env
from tavc_env import EnvOptions


def test_defaults_are_the_documented_ones() -> None:
    options = EnvOptions()
    assert options.max_cycles == 100_000
    assert options.max_sim_time_s == 24 * 3600.0
    assert options.decision_interval_s is None
    assert (options.reward_time_unit, options.step_cap_s, options.jam_window_s) == ("ms", 600, 600)
    assert (options.observation_mode, options.observation_format) == ("paper", "dict")
    assert options.reward == "paper"
    assert options.render_mode is None
    assert options.changed() == {}


@pytest.mark.parametrize(
    ("changes", "pattern"),
    [
        ({"max_cycles": 0}, r"^max_cycles = 0 is invalid; allowed: an integer >= 1"),
        ({"max_cycles": 1.5}, r"^max_cycles = 1\.5 is invalid"),
        ({"max_sim_time_s": math.nan}, r"^max_sim_time_s = nan is invalid; allowed: a time >="),
        ({"decision_interval_s": -5.0}, r"^decision_interval_s = -5\.0 is invalid; allowed: None"),
        ({"reward_time_unit": "h"}, r"^reward_time_unit = 'h' is invalid; allowed: \['ms', 's'\]"),
        ({"reward": "rate"}, r"^reward = 'rate' is invalid; allowed: \['paper', 'value'\]"),
        ({"reward": None}, r"^reward = None is invalid"),
        ({"step_cap_s": math.inf}, r"^step_cap_s = inf is invalid; allowed: a finite time"),
        ({"jam_window_s": 0.0}, r"^jam_window_s = 0\.0 is invalid"),
        ({"observation_mode": "full"}, r"^observation_mode = 'full' is invalid"),
        ({"observation_format": "list"}, r"^observation_format = 'list' is invalid"),
        ({"render_mode": "ascii"}, r"^render_mode = 'ascii' is invalid; allowed: None or one of"),
    ],
)
def test_a_bad_option_is_refused_on_construction_naming_it(
    changes: dict[str, Any], pattern: str
) -> None:
    with pytest.raises(ValueError, match=pattern):
        EnvOptions(**changes)
    with pytest.raises(ValueError, match=pattern):
        EnvOptions().replace(**changes)


def test_options_are_frozen_and_normalised() -> None:
    options = EnvOptions(max_sim_time_s=3600, step_cap_s=60)
    assert isinstance(options.max_sim_time_s, float) and isinstance(options.step_cap_s, float)
    with pytest.raises(AttributeError):
        options.max_cycles = 5  # type: ignore[misc]
    assert pickle.loads(pickle.dumps(options)) == options
    assert options.changed() == {"max_sim_time_s": 3600.0, "step_cap_s": 60.0}


def test_times_are_checked_against_the_arenas_physics_step() -> None:
    with pytest.raises(ValueError, match=r"decision_interval_s = 0\.25 .*multiples of dt = 0\.1"):
        tavc_env.parallel_env(options=EnvOptions(decision_interval_s=0.25))
    env = tavc_env.parallel_env(options=EnvOptions(decision_interval_s=0.25), dt=0.05)
    assert env.decision_interval_s == 0.25


def test_options_given_whole_or_as_overrides_are_the_same() -> None:
    whole = tavc_env.parallel_env(
        options=EnvOptions(decision_interval_s=5.0, observation_mode="paper_id"),
        source_service_s=10.0,
    )
    loose = tavc_env.parallel_env(
        decision_interval_s=5.0, observation_mode="paper_id", source_service_s=10.0
    )
    assert whole.options == loose.options
    assert whole.config == loose.config
    assert whole.config.source_service_s == 10.0
    # overrides change the given options, as they change the given arena
    both = tavc_env.parallel_env(options=EnvOptions(decision_interval_s=5.0), max_cycles=7)
    assert both.options == EnvOptions(decision_interval_s=5.0, max_cycles=7)
    assert (both.max_cycles, both.decision_interval_s, both.observation_mode) == (7, 5.0, "paper")


def test_a_config_is_taken_whole_and_a_preset_beside_it_is_refused() -> None:
    config = tavc_env.preset("three_circuits_three_classes")
    env = tavc_env.parallel_env(config=config)
    assert env.config == config
    assert tavc_env.parallel_env().config == tavc_env.preset("dahl2004")
    for name in ("dahl2004", "three_circuits_three_classes"):
        with pytest.raises(ValueError, match=r"^preset = .* allowed: None when a config is given"):
            tavc_env.parallel_env(preset=name, config=config)
        with pytest.raises(ValueError, match=r"^preset = .* allowed: None when a config is given"):
            tavc_env.make_config(name, config)


def test_an_unknown_key_is_named_as_neither_arena_nor_option() -> None:
    with pytest.raises(ValueError) as error:
        tavc_env.parallel_env(decision_intervall_s=5.0)
    text = str(error.value)
    assert text.startswith("unknown configuration key(s) ['decision_intervall_s']: neither")
    assert "'source_service_s'" in text and "'decision_interval_s'" in text
    with pytest.raises(ValueError, match=r"^options = .* allowed: a tavc_env\.EnvOptions"):
        tavc_env.parallel_env(options={"max_cycles": 5})


def test_the_env_reads_its_options() -> None:
    env = tavc_env.parallel_env(max_cycles=3, reward_time_unit="s", observation_format="box")
    obs, _ = env.reset(seed=0)
    assert not isinstance(obs["robot_0"], dict)  # box: the vector alone
    steps = 0
    while env.agents:
        env.step({a: 0 for a in env.agents})
        steps += 1
    assert steps == 3
    env.max_cycles = 5  # PettingZoo's API test sets it: the options follow, still checked
    assert env.options.max_cycles == 5
    with pytest.raises(ValueError, match="max_cycles = 0"):
        env.max_cycles = 0


def test_an_unknown_field_is_named_with_every_allowed_one() -> None:
    """issue 35: `EnvOptions(bogus=1)` was a bare TypeError ("unexpected keyword argument")."""
    for make in (lambda **k: EnvOptions(**k), lambda **k: EnvOptions().replace(**k)):
        with pytest.raises(TypeError) as error:
            make(bogus=1)
        assert isinstance(error.value, ValueError)  # the package's refusals are ValueErrors
        text = str(error.value)
        assert text.startswith("EnvOptions(bogus=1) is invalid: no such option; allowed: ")
        assert "max_cycles, max_sim_time_s" in text and "agent_names" in text
    with pytest.raises(ValueError, match=r"\(dt: an arena field, for ArenaConfig"):
        EnvOptions(dt=0.1)  # type: ignore[call-arg]
    assert EnvOptions(max_cycles=5).max_cycles == 5
