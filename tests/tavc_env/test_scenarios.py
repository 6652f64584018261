"""The scenario suite (`tavc_env.scenarios`): every id builds and steps through `pettingzoo.make`,
PettingZoo's checkers pass, priority shifts happen exactly when planned and follow the seed, start
allocations put robots where they say, and bad scenario arguments are refused."""

from __future__ import annotations

import copy

import numpy as np
import pettingzoo
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test

import tavc_env
from tavc_env import SCENARIOS, Scenario, ScenarioEnv, ValueShifts
from tavc_env.engine.base import start_allocation
from tavc_env.twin import InterferenceTables
from tests.helpers import seed_spaces, strict_warnings

IDS = [s.id for s in SCENARIOS.values()]


def test_the_suite_has_at_least_six_versioned_ids() -> None:
    assert len(IDS) >= 6
    assert all(i.startswith("tavc/") and i.rsplit("-v", 1)[1].isdigit() for i in IDS)


@pytest.mark.parametrize("scenario_id", IDS)
def test_every_id_builds_resets_and_steps_in_both_views(scenario_id: str) -> None:
    parallel = pettingzoo.make("parallel", scenario_id, max_sim_time_s=600.0)
    name = scenario_id.split("/")[1].rsplit("-v", 1)[0]
    assert parallel.config == SCENARIOS[name].config()
    _, infos = parallel.reset(seed=1)
    steps = 0
    while parallel.agents:
        actions = {a: infos[a]["circuit"] for a in parallel.agents if infos[a]["action_required"]}
        _, _, _, _, infos = parallel.step(actions)
        steps += 1
    assert steps > 0 and parallel.sim_time_s == pytest.approx(600.0)
    aec = pettingzoo.make("aec", scenario_id, max_sim_time_s=300.0)
    aec.reset(seed=1)
    assert aec.possible_agents == parallel.possible_agents


def test_a_scenario_runs_its_episode_length_by_default() -> None:
    env = pettingzoo.make("parallel", "tavc/bad_start-v0")
    assert env.options.max_sim_time_s == SCENARIOS["bad_start"].episode_s


@pytest.mark.parametrize("name", ["priority_shifts", "breakdowns"])
def test_pettingzoo_checkers_pass_on_dynamic_scenarios(name: str) -> None:
    with strict_warnings():
        env = seed_spaces(ScenarioEnv(name, max_sim_time_s=3 * 3600.0), 7)
        env.reset(seed=5)
        parallel_api_test(env, num_cycles=60)
        parallel_seed_test(lambda: ScenarioEnv(name, max_sim_time_s=1800.0))
        api_test(tavc_env.scenarios.env(name, max_sim_time_s=1800.0), num_cycles=30)


def _short_shifts() -> Scenario:
    return Scenario(
        name="short_shifts",
        version=0,
        summary="values swap every 100-300 s",
        preset="dahl2004",
        model="dahl2004",
        arena={"values": (3000.0, 1000.0)},
        value_shifts=ValueShifts(((3000.0, 1000.0), (1000.0, 3000.0)), (100.0, 300.0)),
        episode_s=1200.0,
    )


def test_priority_shifts_happen_exactly_when_planned_and_pay_the_values_then_in_force() -> None:
    env = ScenarioEnv(_short_shifts())
    _, infos = env.reset(seed=3)
    plan = env.value_plan
    assert len(plan) >= 3 and [v for _, v in plan][:2] == [(1000.0, 3000.0), (3000.0, 1000.0)]
    seen = []
    while env.agents:
        values = env.circuit_values
        actions = {a: infos[a]["circuit"] for a in env.agents if infos[a]["action_required"]}
        _, rewards, _, _, infos = env.step(actions)
        for agent, info in infos.items():
            if info["task_completed"]:  # paid at the values in force during the step
                w = values[info["circuit"]]
                assert rewards[agent] == pytest.approx(w / (info["task_time_s"] * 1000.0))
        if env.circuit_values != values:
            seen.append((env.sim_time_s, env.circuit_values))
    assert [t for t, _ in seen] == pytest.approx([t for t, _ in plan], abs=1e-6)
    assert [v for _, v in seen] == [v for _, v in plan]


def test_the_plan_follows_the_seed_and_survives_copying() -> None:
    env = ScenarioEnv(_short_shifts())
    env.reset(seed=3)
    first = env.value_plan
    env.reset(seed=3)
    assert env.value_plan == first
    env.reset(seed=4)
    assert env.value_plan != first
    env.reset(seed=3)
    infos = env.reset(seed=3)[1]
    for _ in range(5):
        env.step({a: infos[a]["circuit"] for a in env.agents if infos[a]["action_required"]})
    twin = copy.deepcopy(env)
    assert twin.value_plan == env.value_plan and twin.circuit_values == env.circuit_values


def test_value_shift_plans_cover_the_episode_in_phases_of_the_given_lengths() -> None:
    shifts = ValueShifts(((1.0, 2.0), (2.0, 1.0), (3.0, 3.0)), (10.0, 20.0))
    plan = shifts.plan(np.random.default_rng(0), 200.0)
    times = [0.0] + [t for t, _ in plan]
    gaps = np.diff(times)
    assert all(10.0 <= g <= 20.0 for g in gaps) and 200.0 - times[-1] <= 20.0
    assert [v for _, v in plan][:3] == [(2.0, 1.0), (3.0, 3.0), (1.0, 2.0)]


def test_start_circuits_put_robots_where_they_say_in_physics_and_twin() -> None:
    start = (1, 1, 1, 0, 1, 1)
    env = tavc_env.parallel_env(preset="dahl2004", start_circuits=start)
    _, infos = env.reset(seed=0)
    assert tuple(infos[a]["circuit"] for a in env.possible_agents) == start
    assert start_allocation(env.config, np.random.default_rng(0)) == list(enumerate(start))
    tables = InterferenceTables.from_function(env.config, 100.0)
    twin = tavc_env.twin_parallel_env(tables=tables, config=env.config)
    _, infos = twin.reset(seed=0)
    assert tuple(infos[a]["circuit"] for a in twin.possible_agents) == start


def test_without_start_circuits_the_reset_is_unchanged() -> None:
    # the even spread drawn from the generator, as before start_circuits existed
    config = tavc_env.preset("dahl2004")
    order = np.random.default_rng(0).permutation(6)
    expected = sorted((int(i), rank % 2) for rank, i in enumerate(order))
    assert sorted(start_allocation(config, np.random.default_rng(0))) == expected


@pytest.mark.parametrize(
    ("start", "fragment"),
    [((0, 1), "6 circuit indices"), ((0, 1, 2, 0, 1, 0), "in [0, 1]"), (0, "a sequence")],
)
def test_bad_start_circuits_are_refused_by_name(start: object, fragment: str) -> None:
    with pytest.raises(ValueError, match="start_circuits") as error:
        tavc_env.make_config("dahl2004", start_circuits=start)
    assert fragment in str(error.value)


def test_scenario_envs_refuse_arena_overrides_and_unknown_names() -> None:
    with pytest.raises(ValueError, match="arena is fixed"):
        ScenarioEnv("dahl2004", speeds=[0.3] * 6)
    with pytest.raises(ValueError, match="one of"):
        ScenarioEnv("no_such_scenario")


@pytest.mark.parametrize("view", ["parallel", "aec"])
def test_a_scenario_argument_that_contradicts_the_id_is_refused(view: str) -> None:
    """issue 35: `pettingzoo.make('parallel', 'tavc/dahl2004-v0', scenario='bad_start')` built
    bad_start under the dahl2004 id."""
    with pytest.raises(ValueError) as error:
        pettingzoo.make(view, "tavc/dahl2004-v0", scenario="bad_start")
    assert str(error.value) == (
        "scenario = 'bad_start' is invalid for the id 'tavc/dahl2004-v0', which is scenario "
        "'dahl2004'; allowed: 'dahl2004' or no scenario argument; for scenario 'bad_start' use "
        "the id 'tavc/bad_start-v0'"
    )
    with pytest.raises(ValueError, match=r"^scenario = 'nowhere' is invalid for the id"):
        pettingzoo.make(view, "tavc/passing-v0", scenario="nowhere")
    same = pettingzoo.make(view, "tavc/bad_start-v0", scenario="bad_start")  # agrees: taken
    arena = same.unwrapped if view == "aec" else same
    assert arena.scenario.name == "bad_start"


def test_a_scenario_whose_first_profile_is_not_its_arena_values_is_refused() -> None:
    with pytest.raises(ValueError, match="profiles\\[0\\]"):
        Scenario(
            name="inconsistent",
            version=0,
            summary="",
            preset="dahl2004",
            model="dahl2004",
            value_shifts=ValueShifts(((1.0, 2.0), (2.0, 1.0)), (10.0, 20.0)),
        )


@pytest.mark.parametrize(
    ("profiles", "phase_s", "name"),
    [
        (((1.0, 2.0),), (1.0, 2.0), "profiles"),
        (((1.0, 2.0), (1.0,)), (1.0, 2.0), "profiles"),
        (((1.0, 2.0), (0.0, 1.0)), (1.0, 2.0), "profiles"),
        (((1.0, 2.0), (2.0, 1.0)), (2.0, 1.0), "phase_s"),
        (((1.0, 2.0), (2.0, 1.0)), (0.0, 1.0), "phase_s"),
    ],
)
def test_bad_value_shifts_are_refused(profiles: object, phase_s: object, name: str) -> None:
    with pytest.raises(ValueError, match=f"value_shifts.{name}"):
        ValueShifts(profiles, phase_s)  # type: ignore[arg-type]
