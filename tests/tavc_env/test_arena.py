"""One door to "which arena" (`tavc_env.resolve_arena`): every form names the same arena, the env
built from it is the scenario's or the preset's, and every clash is refused there in one line."""

from __future__ import annotations

from typing import Any

import pytest

import tavc_env
from tavc_env.adapters.batched import BatchedArenaEnv
from tavc_env.arena import make_env, resolve_env_kwargs


@pytest.mark.parametrize(
    "spec",
    ["bad_start", "tavc/bad_start-v0", tavc_env.SCENARIOS["bad_start"], {"scenario": "bad_start"}],
)
def test_every_form_of_a_scenario_is_the_scenario(spec: Any) -> None:
    arena = tavc_env.resolve_arena(spec)
    assert arena.scenario is tavc_env.SCENARIOS["bad_start"]
    assert arena.config == arena.scenario.config() and arena.kwargs == {"scenario": "bad_start"}
    env = arena.parallel_env()
    assert isinstance(env, tavc_env.ScenarioEnv)
    assert env.options.max_sim_time_s == arena.scenario.episode_s  # the scenario's episode


def test_a_preset_a_config_and_overrides_as_the_env_takes_them() -> None:
    by_name = tavc_env.resolve_arena("dahl2004_passing", dt=0.05)
    assert by_name.config == tavc_env.make_config("dahl2004_passing", dt=0.05)
    assert by_name.kwargs == {"preset": "dahl2004_passing", "dt": 0.05}
    assert by_name.preset == "dahl2004_passing" and by_name.scenario is None
    assert tavc_env.resolve_arena({"preset": "dahl2004_passing", "dt": 0.05}) == by_name
    assert tavc_env.resolve_arena(None).kwargs == {}  # the default preset, named by nobody
    assert tavc_env.resolve_arena(None).config == tavc_env.preset("dahl2004")
    config = tavc_env.preset("dahl2004_homogeneous")
    assert tavc_env.resolve_arena(config).config == config
    env = by_name.parallel_env(decision_interval_s=5.0)
    assert env.config == by_name.config and env.options.decision_interval_s == 5.0


def test_a_plain_mapping_keeps_a_scenarios_episode_with_env_options() -> None:
    env = make_env(scenario="priority_shifts", observation_mode="paper_id", max_cycles=50)
    assert isinstance(env, tavc_env.ScenarioEnv)
    assert env.options.max_sim_time_s == tavc_env.SCENARIOS["priority_shifts"].episode_s
    assert env.options.observation_mode == "paper_id" and env.options.max_cycles == 50
    arena, options = resolve_env_kwargs({"preset": "dahl2004", "dt": 0.05, "max_cycles": 9})
    assert arena.kwargs == {"preset": "dahl2004", "dt": 0.05} and options == {"max_cycles": 9}


def test_the_batched_view_takes_a_scenario() -> None:
    with BatchedArenaEnv(2, workers=0, env_kwargs={"scenario": "bad_start"}) as batch:
        _, infos = batch.reset(seed=0)
        assert infos["circuit"].tolist() == [[1, 1, 1, 0, 1, 1]] * 2  # the scenario's bad start


@pytest.mark.parametrize(
    ("spec", "overrides", "message"),
    [
        (
            {"scenario": "bad_start", "preset": "dahl2004"},
            {},
            r"^arena = \{'scenario': 'bad_start', 'preset': 'dahl2004'\} is invalid; allowed: "
            r"one of a scenario, a preset or a config",
        ),
        (
            "bad_start",
            {"dt": 0.05},
            r"^scenario 'bad_start' with arena overrides = \['dt'\] is invalid; allowed: a "
            r"scenario alone",
        ),
        ("tavc/bad_start-v7", {}, r"^arena = 'tavc/bad_start-v7' is invalid; allowed: a preset"),
        ({"preset": "nope"}, {}, r"^preset = 'nope' is invalid; allowed: one of \['dahl2004'"),
        ({"config": "dahl2004"}, {}, r"^config = 'dahl2004' is invalid; allowed: a tavc_env"),
        (3, {}, r"^arena = 3 is invalid; allowed: a preset"),
        (None, {"max_cycles": 5}, r"^arena overrides = \['max_cycles'\] is invalid; allowed: "),
        ({"dt": 0.05}, {"dt": 0.1}, r"^arena overrides = \['dt'\] is invalid; allowed: each key"),
    ],
)
def test_every_clash_is_refused_in_one_line(
    spec: Any, overrides: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValueError, match=message) as error:
        tavc_env.resolve_arena(spec, **overrides)
    assert "\n" not in str(error.value)


def test_a_scenario_refuses_another_env_factory() -> None:
    with pytest.raises(
        ValueError, match=r"^env factory = .* allowed: None for scenario 'bad_start'"
    ):
        tavc_env.resolve_arena("bad_start").parallel_env(factory=tavc_env.parallel_env)
