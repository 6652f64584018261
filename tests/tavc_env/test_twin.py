"""The model twin (`tavc_env.twin`): the interference tables (validation, JSON), PettingZoo's
checkers, determinism, the task-time law (means and spreads of a fixed allocation converge to the
table's; the switch cost applies exactly; simultaneous deciders count each other), rewards,
truncation, breakdowns, priority changes and copying."""

from __future__ import annotations

import copy
import functools
import json
import math
import pickle
from collections import defaultdict
from typing import Any

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

import tavc_env
from tavc_env import PHASES, completed_task_s
from tavc_env.env import AecArenaEnv
from tavc_env.twin import (
    InterferenceTables,
    TaskTimeCell,
    TwinArenaEnv,
    required_cells,
    team_classes,
)
from tests.helpers import CONFIGS, seed_spaces, strict_warnings

DAHL = tavc_env.preset("dahl2004")
SWITCH = 1.3


def mean_of(circuit: int, counts: tuple[int, ...], cls: str) -> float:
    """Known means: a class's lone time, +20 % per extra robot on the circuit, +5 s on circuit 1+."""
    lone = 60.0 if cls in ("fast", "medium") else 80.0
    return lone * (1 + 0.2 * (sum(counts) - 1)) + 5.0 * circuit


def tables_for(config: tavc_env.ArenaConfig, sd: float = 8.0, switch: float = SWITCH) -> Any:
    return InterferenceTables.from_function(config, mean_of, sd, switch, source="test")


def twin(config: tavc_env.ArenaConfig = DAHL, sd: float = 8.0, **kwargs: Any) -> TwinArenaEnv:
    return tavc_env.twin_parallel_env(tables=tables_for(config, sd), config=config, **kwargs)


def first_choice(circuits: dict[str, int]) -> Any:
    """A policy: every deciding robot chooses its circuit in `circuits`."""

    def policy(obs: Any, infos: Any, rng: np.random.Generator) -> dict[str, int]:
        return {a: circuits[a] for a in obs if infos[a]["action_required"]}

    return policy


def random_policy(obs: Any, infos: Any, rng: np.random.Generator) -> dict[str, int]:
    return {
        a: int(rng.choice(np.flatnonzero(obs[a]["action_mask"])))
        for a in obs
        if infos[a]["action_required"]
    }


def trajectory(env: TwinArenaEnv, seed: int, steps: int, policy: Any = random_policy) -> list[Any]:
    """Everything the env returned, step by step (and its state), under `policy`."""
    rng = np.random.default_rng(99)
    obs, infos = env.reset(seed=seed)
    out: list[Any] = [(obs, infos, env.state())]
    for _ in range(steps):
        if not env.agents:
            break
        step = env.step(policy(obs, infos, rng))
        obs, infos = step[0], step[4]
        out.append((*step, env.state(), env.sim_time_s))
    return out


def completions(env: TwinArenaEnv, policy: Any, seed: int = 0) -> list[tuple[str, int, float]]:
    """(agent, circuit, task time) of every task completed until the episode ends."""
    rng = np.random.default_rng(0)
    obs, infos = env.reset(seed=seed)
    done = []
    while env.agents:
        obs, _, _, _, infos = env.step(policy(obs, infos, rng))
        for a, info in infos.items():
            if completed_task_s(info) is not None:
                done.append((a, info["circuit"], info["task_time_s"]))
    return done


# -- the tables ----------------------------------------------------------------------------------


def test_tables_cover_every_cell_and_round_trip_through_json() -> None:
    tables = tables_for(DAHL)
    assert team_classes(DAHL) == (("fast", "slow"), (3, 3))
    # per circuit: 15 crowds (f, s) != (0, 0); 12 with a fast robot, 12 with a slow one
    assert len(tables.cells) == len(required_cells(("fast", "slow"), (3, 3), 2)) == 48
    assert tables.cell(1, (2, 1), "slow").mean_s == mean_of(1, (2, 1), "slow")
    data = json.loads(json.dumps(tables.to_dict()))
    assert InterferenceTables.from_dict(data) == tables
    # the env takes the plain data too
    assert twin_from_dict(data).tables == tables


def twin_from_dict(data: dict[str, Any]) -> TwinArenaEnv:
    return tavc_env.twin_parallel_env(tables=data, preset="dahl2004")


def _cells(tables: InterferenceTables) -> list[TaskTimeCell]:
    return list(tables.cells)


def _replace_cell(data: dict[str, Any], k: int, **changes: Any) -> dict[str, Any]:
    data = copy.deepcopy(data)
    data["cells"][k].update(changes)
    return data


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: {**d, "cells": d["cells"][1:]}, r"cells = 47 cells is invalid: 1 missing"),
        (lambda d: _replace_cell(d, 3, mean_s=0.0), r"cells\[3\]: cell\.mean_s = 0\.0"),
        (lambda d: _replace_cell(d, 3, mean_s=-5.0), r"cells\[3\]: cell\.mean_s = -5\.0"),
        (lambda d: _replace_cell(d, 3, mean_s=math.inf), r"cells\[3\]: cell\.mean_s = inf"),
        (lambda d: _replace_cell(d, 5, sd_s=-1.0), r"cells\[5\]: cell\.sd_s = -1\.0"),
        (lambda d: _replace_cell(d, 0, counts=[4, 0]), r"cells\[0\]\.counts"),
        (lambda d: _replace_cell(d, 0, counts=[0, 0]), r"cells\[0\]\.counts"),
        (lambda d: _replace_cell(d, 0, robot_class="medium"), r"cells\[0\]\.robot_class"),
        (lambda d: _replace_cell(d, 0, circuit=2), r"cells\[0\]\.circuit"),
        (lambda d: {**d, "cells": [*d["cells"], d["cells"][0]]}, r"cells\[48\] = \(0, "),
        (lambda d: {**d, "switch_cost": 0.0}, r"switch_cost = 0\.0"),
        (lambda d: {**d, "team": [3, 0]}, r"team = \[3, 0\]"),
        (lambda d: {**d, "classes": ["fast", "fast"]}, r"classes = "),
        (lambda d: {k: v for k, v in d.items() if k != "switch_cost"}, r"tables = .*missing"),
        (lambda d: {**d, "extra": 1}, r"tables = .*unknown \['extra'\]"),
    ],
)
def test_bad_tables_are_refused_naming_the_field(change: Any, field: str) -> None:
    data = tables_for(DAHL).to_dict()
    with pytest.raises(ValueError, match=field):
        InterferenceTables.from_dict(change(data))


def test_bad_cells_are_refused_when_built_directly() -> None:
    with pytest.raises(ValueError, match=r"cell\.mean_s = -1"):
        TaskTimeCell(0, (1, 0), "fast", -1, 2.0)
    with pytest.raises(ValueError, match=r"cell\.sd_s = -0\.5"):
        TaskTimeCell(0, (1, 0), "fast", 60.0, -0.5)
    cells = _cells(tables_for(DAHL))
    with pytest.raises(ValueError, match=r"cells = 40 cells is invalid: 8 missing"):
        InterferenceTables(("fast", "slow"), (3, 3), 2, tuple(cells[8:]))


def test_tables_of_another_team_are_refused() -> None:
    homogeneous = tables_for(tavc_env.preset("dahl2004_homogeneous"))
    with pytest.raises(ValueError, match=r"tables = .*allowed: tables of this arena"):
        tavc_env.twin_parallel_env(tables=homogeneous, preset="dahl2004")
    with pytest.raises(ValueError, match=r"tables = .*allowed: tables of this arena"):
        tavc_env.twin_parallel_env(tables=tables_for(DAHL), preset="three_circuits_three_classes")
    with pytest.raises(ValueError, match=r"tables = "):
        tavc_env.twin_parallel_env(tables="dahl2004", preset="dahl2004")


def test_the_twin_refuses_rendering_and_snapshots_and_takes_the_envs_arguments() -> None:
    with pytest.raises(ValueError, match=r"render_mode = 'rgb_array'"):
        twin(render_mode="rgb_array")
    with pytest.raises(ValueError, match=r"max_cycles = 0"):
        twin(max_cycles=0)
    with pytest.raises(ValueError, match=r"unknown configuration key"):
        twin(no_such_field=1)
    env = twin()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="snapshot"):
        env.snapshot()
    with pytest.raises(ValueError, match=r"action of robot_0"):
        env.step({a: 5 for a in env.agents})


# -- PettingZoo's checkers -----------------------------------------------------------------------


def _seeded(name: str) -> TwinArenaEnv:
    kwargs = CONFIGS[name]
    config = tavc_env.make_config(
        kwargs.get("preset", "dahl2004"),
        **{k: v for k, v in kwargs.items() if k not in ("preset", "decision_interval_s")},
    )
    env = tavc_env.twin_parallel_env(tables=tables_for(config), **kwargs)
    env.reset(seed=123)
    seed_spaces(env, 7)
    return env


@pytest.mark.parametrize("name", list(CONFIGS))
def test_parallel_api_test(name: str) -> None:
    env = _seeded(name)
    with strict_warnings():
        parallel_api_test(env, num_cycles=1000)
    assert env.num_cycles == 1000 or env.sim_time_s >= env.max_sim_time_s - 1e-6
    assert env.agents == []


@pytest.mark.parametrize("name", ["dahl2004", "fixed_interval_30s"])
def test_parallel_seed_test_and_aec_api_test(name: str) -> None:
    with strict_warnings():
        parallel_seed_test(functools.partial(_seeded, name), num_cycles=200)
        api_test(OrderEnforcingWrapper(AecArenaEnv(_seeded(name))), num_cycles=50)


# -- determinism -----------------------------------------------------------------------------------


def test_same_seed_same_trajectory_other_seed_another() -> None:
    first = trajectory(twin(), seed=5, steps=300)
    again = trajectory(twin(), seed=5, steps=300)
    assert len(first) == len(again) == 301
    for a, b in zip(first, again):
        assert repr(a) == repr(b)  # floats and arrays to the last digit
    other = trajectory(twin(), seed=6, steps=300)
    assert repr(other) != repr(first)


def test_reset_with_a_seed_restarts_the_same_episode() -> None:
    env = twin()
    first = trajectory(env, seed=3, steps=100)
    assert repr(trajectory(env, seed=3, steps=100)) == repr(first)


# -- the task-time law -----------------------------------------------------------------------------


def test_a_fixed_allocations_task_times_converge_to_the_tables() -> None:
    # fast robots 0, 1 and slow robot 3 on circuit 0; the others on circuit 1
    on = {f"robot_{i}": c for i, c in enumerate((0, 0, 1, 0, 1, 1))}
    sd = 20.0
    env = twin(sd=sd, max_sim_time_s=100 * 3600.0)
    by_group: dict[tuple[int, str], list[float]] = defaultdict(list)
    seen: set[str] = set()
    for agent, circuit, t in completions(env, first_choice(on)):
        if agent in seen:  # a robot's first task may start on the other circuit (a switch)
            cls = DAHL.robots[int(agent.split("_")[1])].speed_class
            by_group[(circuit, cls)].append(t)
        seen.add(agent)
    crowds = {0: (2, 1), 1: (1, 2)}
    assert set(by_group) == {(0, "fast"), (0, "slow"), (1, "fast"), (1, "slow")}
    for (circuit, cls), times in by_group.items():
        expected = mean_of(circuit, crowds[circuit], cls)
        assert len(times) > 3000
        assert np.mean(times) == pytest.approx(expected, rel=0.01)
        assert np.std(times, ddof=1) == pytest.approx(sd, rel=0.05)
        assert min(times) > 0


def test_the_switch_cost_applies_to_tasks_that_start_on_another_circuit() -> None:
    lone = tavc_env.make_config("dahl2004", speeds=[0.3])  # one robot: its crowd is itself
    env = tavc_env.twin_parallel_env(tables=tables_for(lone, sd=0.0), config=lone)
    _, infos = env.reset(seed=0)
    last = infos["robot_0"]["circuit"]
    for choice in (0, 0, 1, 1, 1, 0, 1, 0, 0):
        _, rewards, _, _, infos = env.step({"robot_0": choice})
        info = infos["robot_0"]
        expected = mean_of(choice, (1,), "medium") * (SWITCH if choice != last else 1.0)
        assert info["task_time_s"] == pytest.approx(expected, rel=1e-12)
        assert info["circuit"] == choice
        assert rewards["robot_0"] == pytest.approx(DAHL.circuits[choice].value / (expected * 1e3))
        last = choice


def test_robots_deciding_together_count_each_other_and_themselves() -> None:
    env = twin(sd=0.0)
    _, infos = env.reset(seed=1)
    start = {a: infos[a]["circuit"] for a in env.agents}
    # everyone chooses circuit 0 at once: every first task sees all six robots there
    done: dict[str, float] = {}
    actions = dict.fromkeys(env.agents, 0)
    while len(done) < 6:
        _, _, _, _, infos = env.step(actions)
        actions = {}
        for a, info in infos.items():
            if completed_task_s(info) is not None and a not in done:
                done[a] = info["task_time_s"]
            if info["action_required"]:
                actions[a] = 1  # later tasks elsewhere, so the first ones are not disturbed
    for i, a in enumerate(env.possible_agents):
        cls = DAHL.robots[i].speed_class
        expected = mean_of(0, (3, 3), cls) * (SWITCH if start[a] != 0 else 1.0)
        assert done[a] == pytest.approx(expected, rel=1e-12)


def test_commitments_and_state() -> None:
    env = twin()
    _, infos = env.reset(seed=2)
    assert all(
        info["action_required"] and info["phase"] == PHASES.index("deciding")
        for info in infos.values()
    )
    assert env.state().shape == env.state_space.shape
    env.step({a: i % 2 for i, a in enumerate(env.agents)})
    committed = env.process.committed()
    assert committed.sum() == 5  # six chose; the first to finish is deciding again
    state = env.state()
    assert env.state_space.contains(state)


# -- rewards, time, truncation -----------------------------------------------------------------


def test_rewards_are_w_over_t_in_the_envs_time_unit() -> None:
    for unit, scale in (("ms", 1e3), ("s", 1.0)):
        env = twin(reward_time_unit=unit)
        _, infos = env.reset(seed=0)
        paid = 0
        for _ in range(50):
            _, rewards, _, _, infos = env.step(
                {a: 1 for a in env.agents if infos[a]["action_required"]}
            )
            for a, info in infos.items():
                t = completed_task_s(info)
                if t is None:
                    assert rewards[a] == 0.0
                else:
                    assert rewards[a] == pytest.approx(2000.0 / (t * scale))
                    paid += 1
        assert paid >= 50


def test_truncation_at_max_sim_time_and_max_cycles() -> None:
    env = twin(max_sim_time_s=3600.0)
    _, infos = env.reset(seed=0)
    while env.agents:
        _, _, _, truncations, infos = env.step(
            {a: 0 for a in env.agents if infos[a]["action_required"]}
        )
    assert env.sim_time_s == pytest.approx(3600.0)
    assert all(truncations.values())
    assert not any(info["action_required"] for info in infos.values())
    env = twin(max_cycles=7)
    env.reset(seed=0)
    infos = {a: {"action_required": True} for a in env.agents}
    while env.agents:
        _, _, _, _, infos = env.step({a: 0 for a in env.agents if infos[a]["action_required"]})
    assert env.num_cycles == 7


def test_fixed_interval_steps_and_step_cap() -> None:
    env = twin(decision_interval_s=30.0)
    _, infos = env.reset(seed=0)
    for k in range(1, 20):
        _, _, _, _, infos = env.step({a: 0 for a in env.agents if infos[a]["action_required"]})
        assert env.sim_time_s == pytest.approx(30.0 * k)
    # every robot broken: nothing happens, each event-driven step ends at the cap
    env = twin(step_cap_s=100.0)
    env.reset(seed=0)
    for a in env.agents:
        env.break_down(a)
    _, _, _, _, infos = env.step({})
    assert env.sim_time_s == pytest.approx(100.0)
    assert all(info["broken"] and not info["action_required"] for info in infos.values())


# -- breakdowns, repairs, priorities ---------------------------------------------------------------


def test_scheduled_breakdown_and_repair() -> None:
    config = DAHL.replace(
        breakdowns=(tavc_env.Breakdown(robot=0, at_s=500.0, repair_after_s=900.0),)
    )
    env = tavc_env.twin_parallel_env(tables=tables_for(config), config=config)
    _, infos = env.reset(seed=0)
    broken_at = repaired_at = None
    while env.sim_time_s < 3000.0:
        before = env.sim_time_s
        _, _, _, _, infos = env.step({a: 0 for a in env.agents if infos[a]["action_required"]})
        info = infos["robot_0"]
        if info["broken"] and broken_at is None:
            broken_at = env.sim_time_s
            # a breakdown is no decision epoch: it shows at the end of the step it fell in
            assert before < 500.0 <= broken_at
            assert info["phase"] == PHASES.index("broken") and not info["action_required"]
            assert env.process.committed()[0].sum() == 5 - sum(
                i["action_required"] for a, i in infos.items() if a != "robot_0"
            )
        if broken_at is not None and repaired_at is None and not info["broken"]:
            repaired_at = env.sim_time_s
            assert info["action_required"] and completed_task_s(info) is None
    assert broken_at is not None
    assert repaired_at == pytest.approx(1400.0)  # a repair is one: the step ends there


def test_break_down_and_repair_through_the_env() -> None:
    env = twin()
    _, infos = env.reset(seed=0)
    _, _, _, _, infos = env.step({a: 0 for a in env.agents})
    env.break_down("robot_1")
    assert env.process.committed()[0].sum() == 4  # five were working; robot_1 abandoned its task
    for _ in range(20):
        _, _, _, _, infos = env.step({a: 1 for a in env.agents if infos[a]["action_required"]})
        assert infos["robot_1"]["broken"] and completed_task_s(infos["robot_1"]) is None
    with pytest.raises(ValueError, match="a robot that is broken"):
        env.repair("robot_2")
    env.repair("robot_1")
    _, _, _, _, infos = env.step({a: 1 for a in env.agents if infos[a]["action_required"]})
    assert infos["robot_1"]["action_required"] and not infos["robot_1"]["broken"]


def test_priority_changes_pay_the_new_values() -> None:
    env = twin(sd=0.0)
    _, infos = env.reset(seed=0)
    env.set_circuit_values([100.0, 50.0])
    assert env.circuit_values == (100.0, 50.0)
    _, rewards, _, _, infos = env.step({a: 1 for a in env.agents})
    paid = {a: r for a, r in rewards.items() if completed_task_s(infos[a]) is not None}
    assert paid
    for a, r in paid.items():
        assert r == pytest.approx(50.0 / (infos[a]["task_time_s"] * 1e3))
    with pytest.raises(ValueError, match="circuit values"):
        env.set_circuit_values([1.0])


# -- copying -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_mid_episode_has_the_originals_future(how: str) -> None:
    env = twin()
    rng = np.random.default_rng(1)
    obs, infos = env.reset(seed=4)
    for _ in range(40):
        obs, _, _, _, infos = env.step(random_policy(obs, infos, rng))
    copied = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    for _ in range(60):
        actions = random_policy(obs, infos, rng)
        a_out, b_out = env.step(actions), copied.step(actions)
        assert repr(a_out) == repr(b_out)
        obs, infos = a_out[0], a_out[4]
    assert copied.sim_time_s == env.sim_time_s


# -- the physics paid as the twin pays -------------------------------------------------------------
def test_the_twin_paid_physics_moves_as_the_physics_and_pays_the_twins_times() -> None:
    """`twin_paid_parallel_env`: under the same seed and actions the robots are where the physics
    puts them, tick for tick, and complete the same tasks; each completed task reports the
    twin's time for its cell (tables without spread: the cell's mean, times the switch cost for
    a first task that left its start circuit) and pays w / t with it."""
    tables = tables_for(DAHL, sd=0.0)
    paid = tavc_env.twin.twin_paid_parallel_env(tables=tables, config=DAHL, max_sim_time_s=1800.0)
    physics = tavc_env.parallel_env(config=DAHL, max_sim_time_s=1800.0)
    agents = physics.possible_agents
    allocation = {a: i % 2 for i, a in enumerate(agents)}
    classes = [r.speed_class for r in DAHL.robots]
    on = {
        k: tuple(
            sum(allocation[a] == k and classes[i] == c for i, a in enumerate(agents))
            for c in tables.classes
        )
        for k in (0, 1)
    }
    values = [c.value for c in DAHL.circuits]
    _, infos = physics.reset(seed=3)
    paid.reset(seed=3)
    physics_times, paid_times = [], []
    while physics.agents:
        actions = {a: allocation[a] for a in agents if infos[a]["action_required"]}
        _, _, _, _, infos = physics.step(actions)
        _, rewards, _, _, paid_infos = paid.step(actions)
        assert np.array_equal(paid.sim.positions(), physics.sim.positions())
        for i, a in enumerate(agents):
            t = completed_task_s(paid_infos[a])
            assert (t is None) == (completed_task_s(infos[a]) is None)
            if t is None:
                continue
            k = paid_infos[a]["circuit"]
            mean = mean_of(k, on[k], classes[i])
            assert t == pytest.approx(mean) or t == pytest.approx(mean * SWITCH)
            assert rewards[a] == pytest.approx(values[k] / (t * 1000.0))
            paid_times.append(t)
            physics_times.append(completed_task_s(infos[a]))
    assert len(paid_times) >= 20 and paid_times != physics_times
