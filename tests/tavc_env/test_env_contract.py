"""The environment contract of DESIGN.md section 2: spaces, observations, action masks, infos,
rewards, the start, stepping (event-driven and fixed-interval), truncation, the global state and
the PettingZoo registry.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pettingzoo
import pytest
from gymnasium import spaces

import tavc_env
import tavc_env.v0
from tavc_env import PHASES, completed_task_s
from tests.helpers import (
    CONFIGS,
    REQUIRED_INFO_KEYS,
    constant_policy,
    lockstep,
    pairwise_min_distance,
    random_policy,
    run_env,
)

config_names = pytest.mark.parametrize("name", list(CONFIGS))


def _values(env: tavc_env.TavcArenaEnv) -> list[float]:
    return [c.value for c in env.config.circuits]


# -- spaces ------------------------------------------------------------------------------------


@config_names
def test_spaces_match_the_design_and_are_built_once(name: str) -> None:
    env = tavc_env.parallel_env(**CONFIGS[name])
    n, m = env.config.n_robots, env.config.n_circuits
    assert env.possible_agents == [f"robot_{i}" for i in range(n)]
    before = {a: (env.observation_space(a), env.action_space(a)) for a in env.possible_agents}
    run_env(env, 3)
    for a in env.possible_agents:
        obs_space, act_space = env.observation_space(a), env.action_space(a)
        assert obs_space is before[a][0] and act_space is before[a][1]
        assert obs_space is env.observation_space(a) and act_space is env.action_space(a)
        assert act_space == spaces.Discrete(m)
        assert isinstance(obs_space, spaces.Dict)
        assert set(obs_space.spaces) == {"observation", "action_mask"}
        assert obs_space["observation"] == spaces.Box(0.0, 1.0, (m,), np.float32)
        assert obs_space["action_mask"] == spaces.Box(0, 1, (m,), np.int8)
    assert isinstance(env.state_space, spaces.Box)
    assert env.state_space.shape == env.state().shape


def test_unknown_agent_has_no_space() -> None:
    env = tavc_env.parallel_env()
    for bad in ("robot_6", "player_0", 0):
        with pytest.raises(ValueError, match=rf"agent {bad!r} is unknown; allowed"):
            env.observation_space(bad)
        with pytest.raises(ValueError, match=rf"agent {bad!r} is unknown"):
            env.action_space(bad)


# -- the start ---------------------------------------------------------------------------------


@config_names
def test_every_robot_decides_at_reset(name: str) -> None:
    env = tavc_env.parallel_env(**CONFIGS[name])
    obs, infos = env.reset(seed=5)
    m = env.config.n_circuits
    assert env.agents == env.possible_agents
    assert set(obs) == set(infos) == set(env.agents)
    for a in env.agents:
        assert env.observation_space(a).contains(obs[a])
        assert np.array_equal(obs[a]["action_mask"], np.ones(m, np.int8))
        assert set(infos[a]) >= REQUIRED_INFO_KEYS
        info = infos[a]
        assert info["action_required"] is True
        assert PHASES[info["phase"]] == "deciding" and info["broken"] is False
        assert info["task_completed"] is False and info["task_time_s"] == 0.0
        assert info["elapsed_s"] == 0.0 and info["sim_time_s"] == 0.0
        onehot = np.zeros(m, np.float32)
        onehot[info["circuit"]] = 1.0
        assert np.array_equal(obs[a]["observation"], onehot)


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({}, [3, 3]),
        (CONFIGS["three_circuits_12_robots"], [4, 4, 4]),
        ({"speeds": [0.3] * 4 + [0.2] * 3}, [4, 3]),
        ({"circuits": tavc_env.lane_circuits(3), "speeds": [0.25] * 5}, [2, 2, 1]),
    ],
)
def test_start_spreads_robots_evenly_over_circuits(kwargs: dict, expected: list[int]) -> None:
    env = tavc_env.parallel_env(**kwargs)
    for seed in range(5):
        _, infos = env.reset(seed=seed)
        counts = np.bincount([i["circuit"] for i in infos.values()], minlength=len(expected))
        assert sorted(counts.tolist(), reverse=True) == expected


@config_names
def test_start_places_robots_at_or_queued_near_their_sink(name: str) -> None:
    env = tavc_env.parallel_env(**CONFIGS[name])
    cfg = env.config
    for seed in range(3):
        _, infos = env.reset(seed=seed)
        pos = env.sim.positions()
        for c, circuit in enumerate(cfg.circuits):
            members = [i for i, a in enumerate(env.possible_agents) if infos[a]["circuit"] == c]
            d = np.hypot(*(pos[members] - np.array(circuit.sink)).T)
            # one robot on the sink's dock, the others in its waiting line
            assert np.sum(d < 1e-9) == 1
            assert d.max() <= cfg.queue_offset_m + (len(members) - 2) * cfg.queue_spacing_m + 1e-9


@pytest.mark.parametrize("name", list(CONFIGS))
def test_start_positions_do_not_overlap(name: str) -> None:
    env = tavc_env.parallel_env(**CONFIGS[name])
    for seed in range(3):
        env.reset(seed=seed)
        assert pairwise_min_distance(env.sim.positions()) >= 2 * env.config.robot_radius


def test_start_allocation_is_drawn_from_the_seed_not_by_speed() -> None:
    env = tavc_env.parallel_env()  # robot_0..2 fast, robot_3..5 slow
    fast = {"robot_0", "robot_1", "robot_2"}
    allocations = []
    for seed in range(20):
        _, infos = env.reset(seed=seed)
        on_0 = frozenset(a for a, i in infos.items() if i["circuit"] == 0)
        allocations.append(on_0)
        _, again = env.reset(seed=seed)
        assert {a: i["circuit"] for a, i in again.items()} == {
            a: i["circuit"] for a, i in infos.items()
        }, "the same seed gives the same start"
    assert len(set(allocations)) >= 8, "the start varies with the seed"
    fast_split = sum(0 < len(fast & on_0) < 3 for on_0 in allocations)
    assert fast_split >= 10, "the fast robots are usually split over the circuits, not grouped"
    # each robot starts on each circuit for some seed
    for a in env.possible_agents:
        assert 0 < sum(a in on_0 for on_0 in allocations) < 20


# -- observations, masks, infos, rewards over a run -------------------------------------------


@config_names
def test_observations_masks_infos_and_rewards_over_a_run(name: str) -> None:
    env = tavc_env.parallel_env(**CONFIGS[name])
    run = run_env(env, 40, seed=21, policy_seed=2)
    values = _values(env)
    m = env.config.n_circuits
    completions = 0
    for k, rec in enumerate(run.steps):
        agents = set(env.possible_agents)
        for d in (rec.obs, rec.rewards, rec.terminations, rec.truncations, rec.infos):
            assert set(d) == agents, f"step {k}: every live agent in every dict"
        assert env.state_space.contains(rec.state), f"step {k}: state outside state_space"
        assert not any(rec.terminations.values())
        for a in agents:
            obs, info, reward = rec.obs[a], rec.infos[a], rec.rewards[a]
            assert env.observation_space(a).contains(obs)
            assert set(info) >= REQUIRED_INFO_KEYS
            assert info["phase"] in range(len(PHASES))
            assert info["action_required"] == (PHASES[info["phase"]] == "deciding")
            assert info["broken"] == (PHASES[info["phase"]] == "broken")
            assert info["sim_time_s"] == rec.time_s
            assert 0.0 <= info["elapsed_s"] <= rec.time_s
            # `circuit` is the robot's last choice (at a decision epoch: the one just delivered on)
            before = run.records[k].infos[a]
            chosen = rec.actions[a] if before["action_required"] else before["circuit"]
            assert info["circuit"] == chosen
            onehot = np.zeros(m, np.float32)
            onehot[info["circuit"]] = 1.0
            assert np.array_equal(obs["observation"], onehot)
            expected_mask = np.ones(m, np.int8) if info["action_required"] else onehot
            assert np.array_equal(obs["action_mask"], expected_mask.astype(np.int8))
            t = completed_task_s(info)
            if t is None:
                assert reward == 0.0
            else:
                completions += 1
                assert t > 0 and info["action_required"]
                assert t <= info["elapsed_s"] + 1e-9
                assert reward == pytest.approx(values[info["circuit"]] / (t * 1000.0), rel=1e-12)
        assert isinstance(rec.rewards["robot_0"], float)
    assert completions >= 30


def test_reward_is_paid_for_the_circuit_just_completed() -> None:
    """Robots that alternate circuits are paid each circuit's own value over the task time."""
    env = tavc_env.parallel_env()
    _, infos = env.reset(seed=8)
    choice: dict[str, int] = {}
    values = _values(env)
    seen = set()
    for _ in range(40):
        actions = {}
        for a, info in infos.items():
            if info["action_required"]:
                choice[a] = 1 - info["circuit"]
                actions[a] = choice[a]
        _, rewards, _, _, infos = env.step(actions)
        for a, info in infos.items():
            if (t := completed_task_s(info)) is not None:
                assert info["circuit"] == choice[a]
                assert rewards[a] == pytest.approx(values[choice[a]] / (1000.0 * t), rel=1e-12)
                seen.add(choice[a])
    assert seen == {0, 1}


def test_reward_time_unit_seconds_drops_the_factor_1000_and_nothing_else() -> None:
    env_ms = tavc_env.parallel_env()
    env_s = tavc_env.parallel_env(reward_time_unit="s")
    run_ms = run_env(env_ms, 30, seed=3, policy_seed=4)
    run_s = run_env(env_s, 30, seed=3, policy_seed=4)
    values = _values(env_s)
    paid = 0
    for a_rec, b_rec in zip(run_ms.steps, run_s.steps, strict=True):
        assert np.array_equal(a_rec.state, b_rec.state)
        assert a_rec.infos == b_rec.infos
        for a, info in b_rec.infos.items():
            t = completed_task_s(info)
            if t is None:
                assert b_rec.rewards[a] == 0.0
            else:
                paid += 1
                assert b_rec.rewards[a] == pytest.approx(values[info["circuit"]] / t, rel=1e-12)
                assert b_rec.rewards[a] == pytest.approx(1000.0 * a_rec.rewards[a], rel=1e-12)
    assert paid > 10


def test_reward_scale_in_ms_is_the_papers() -> None:
    """w / t_ms: for tasks of one to three minutes and w of about 2000, rewards of 0.01-0.04
    (the scale at which the softmax temperature 0.005 of the paper makes sense)."""
    run = run_env(tavc_env.parallel_env(), 30, seed=0)
    paid = [r for rec in run.steps for r in rec.rewards.values() if r]
    assert paid and all(0.005 < r < 0.06 for r in paid)


# -- stepping ----------------------------------------------------------------------------------


@pytest.mark.parametrize("extra", ["other_circuit", "out_of_space"])
def test_busy_robots_actions_are_ignored(extra: str) -> None:
    """Giving busy robots any action (even one outside the space) changes nothing compared with
    giving them none."""
    env, twin = tavc_env.parallel_env(), tavc_env.parallel_env()
    start = env.reset(seed=12)
    twin.reset(seed=12)

    def busy_actions(obs: dict[str, Any], infos: dict[str, Any]) -> dict[str, Any]:
        if extra == "other_circuit":
            return {a: 1 - i["circuit"] for a, i in infos.items() if not i["action_required"]}
        return {a: 99 for a, i in infos.items() if not i["action_required"]}

    assert lockstep(env, twin, 40, start, policy_seed=6, extra_b=busy_actions).completions > 0


def test_event_driven_steps_stop_at_the_first_decision_epoch() -> None:
    env = tavc_env.parallel_env()
    run = run_env(env, 120, seed=2)
    for k, rec in enumerate(run.steps):
        deciding = [a for a, i in rec.infos.items() if i["action_required"]]
        assert deciding or rec.duration_s >= env.step_cap_s - 1e-9, f"step {k}"
        assert 0 < rec.duration_s <= env.step_cap_s + 1e-9
        # the step returned in the tick of the epoch: completions happened at the step's end
        for a in deciding:
            t = rec.infos[a]["task_time_s"]
            assert t is not None and t == pytest.approx(rec.infos[a]["elapsed_s"], abs=1e-9)


def test_event_driven_step_cap_returns_with_nobody_deciding() -> None:
    env = tavc_env.parallel_env(step_cap_s=5.0)
    run = run_env(env, 20, seed=2)
    capped = [rec for rec in run.steps if not any(i["action_required"] for i in rec.infos.values())]
    assert capped, "with a 5 s cap most steps return before any task completes"
    for rec in run.steps:
        assert rec.duration_s <= 5.0 + 1e-9
    for rec in capped:
        assert rec.duration_s == pytest.approx(5.0)
        assert all(r == 0.0 for r in rec.rewards.values())


def test_fixed_interval_steps_advance_exactly_the_interval() -> None:
    env = tavc_env.parallel_env(decision_interval_s=30.0)
    run = run_env(env, 12, seed=4)
    waited = 0
    for k, rec in enumerate(run.steps, start=1):
        assert rec.time_s == pytest.approx(30.0 * k)
        for info in rec.infos.values():
            if info["task_time_s"] is not None:
                # the task ended inside the interval; the robot then waited for the step's end
                assert info["task_time_s"] <= info["elapsed_s"] + 1e-9
                waited += info["task_time_s"] < info["elapsed_s"] - 1e-9
    assert waited > 0


def test_fixed_interval_deciding_robot_waits_without_an_action_being_forced() -> None:
    """In fixed-interval mode a robot that completed its task stands still (deciding) until it is
    given an action; it is asked at every step until then."""
    env = tavc_env.parallel_env(decision_interval_s=10.0)
    env.reset(seed=0)
    _, _, _, _, infos = env.step(dict.fromkeys(env.agents, 0))
    while not any(i["action_required"] for i in infos.values()):
        _, _, _, _, infos = env.step({})
    deciding = next(a for a, i in infos.items() if i["action_required"])
    with pytest.raises(ValueError, match=f"missing action for {deciding}"):
        env.step({})


# -- truncation --------------------------------------------------------------------------------


@pytest.mark.parametrize("mode", [{}, {"decision_interval_s": 20.0}], ids=["event", "fixed"])
def test_truncation_by_max_cycles(mode: dict) -> None:
    env = tavc_env.parallel_env(max_cycles=3, **mode)
    run = run_env(env, 10, seed=1)
    assert len(run.steps) == 3
    for rec in run.steps[:2]:
        assert not any(rec.truncations.values()) and not any(rec.terminations.values())
    last = run.last
    assert set(last.truncations) == set(env.possible_agents)
    assert all(last.truncations.values()) and not any(last.terminations.values())
    assert not any(i["action_required"] for i in last.infos.values())
    assert env.agents == []
    obs, _ = env.reset(seed=1)
    assert env.agents == env.possible_agents and set(obs) == set(env.agents)
    assert env.num_cycles == 0


@pytest.mark.parametrize(
    ("mode", "limit"),
    [({}, 100.0), ({"decision_interval_s": 30.0}, 100.0), ({"step_cap_s": 7.0}, 50.0)],
    ids=["event", "fixed", "capped"],
)
def test_truncation_by_simulated_time(mode: dict, limit: float) -> None:
    env = tavc_env.parallel_env(max_sim_time_s=limit, **mode)
    run = run_env(env, 1000, seed=1)
    assert env.agents == []
    assert run.last.time_s == pytest.approx(limit)
    assert all(run.last.truncations.values())
    for rec in run.steps[:-1]:
        assert rec.time_s < limit and not any(rec.truncations.values())


def test_default_limits_allow_a_20_hour_trial_as_one_episode() -> None:
    env = tavc_env.parallel_env()
    # an event-driven step lasts about 15 simulated seconds, so 20 h take about 5000 steps
    assert env.max_sim_time_s >= 20 * 3600
    assert env.max_cycles * 10.0 >= 20 * 3600


# -- global state and registry -----------------------------------------------------------------


def test_state_encodes_positions_phases_and_stations() -> None:
    env = tavc_env.parallel_env()
    run = run_env(env, 25, seed=6)
    cfg = env.config
    n, m = cfg.n_robots, cfg.n_circuits
    per_robot = env.state().size - 4 * m
    assert per_robot % n == 0
    width = per_robot // n
    for rec in run.records:
        assert env.state_space.contains(rec.state)
        robots = rec.state[:per_robot].reshape(n, width)
        assert np.allclose(robots[:, 0], rec.positions[:, 0] / cfg.width, atol=1e-6)
        assert np.allclose(robots[:, 1], rec.positions[:, 1] / cfg.height, atol=1e-6)
        assert np.allclose(robots[:, 2] ** 2 + robots[:, 3] ** 2, 1.0, atol=1e-5)
        circuits = robots[:, 6 : 6 + m]
        assert np.array_equal(
            circuits.argmax(axis=1), [rec.infos[a]["circuit"] for a in env.possible_agents]
        )
        assert np.all(circuits.sum(axis=1) == 1.0)
        assert np.all(robots[:, 6 + m :].sum(axis=1) == 1.0)


def test_state_differs_after_a_step() -> None:
    env = tavc_env.parallel_env()
    run = run_env(env, 2, seed=0)
    assert not np.array_equal(run.records[0].state, run.records[2].state)


@pytest.mark.parametrize("kind", ["parallel", "aec"])
def test_pettingzoo_make_builds_working_envs(kind: str) -> None:
    env = pettingzoo.make(kind, tavc_env.REGISTRY_ID, preset="dahl2004_homogeneous")
    unwrapped = env.unwrapped
    assert isinstance(unwrapped, tavc_env.TavcArenaEnv)
    assert [r.speed for r in unwrapped.config.robots] == [0.25] * 6
    if kind == "parallel":
        obs, infos = env.reset(seed=0)
        for _ in range(5):
            obs, _, _, _, infos = env.step(random_policy(obs, infos, np.random.default_rng(0)))
        assert env.sim.time_s > 0
    else:
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        for _ in env.agent_iter(30):
            obs, _, term, trunc, _ = env.last()
            action = None if term or trunc else int(rng.choice(np.flatnonzero(obs["action_mask"])))
            env.step(action)
        assert unwrapped.sim.time_s > 0 and unwrapped.num_cycles == 5


def test_default_pettingzoo_make_is_the_dahl2004_preset() -> None:
    env = pettingzoo.make("parallel", tavc_env.REGISTRY_ID)
    assert [r.speed for r in env.unwrapped.config.robots] == [0.3] * 3 + [0.2] * 3
    assert [c.value for c in env.unwrapped.config.circuits] == [2200.0, 2000.0]


def test_preset_dahl2004_matches_the_paper() -> None:
    cfg = tavc_env.preset("dahl2004")
    assert (cfg.width, cfg.height) == (12.0, 8.0)
    assert cfg.n_circuits == 2 and [c.value for c in cfg.circuits] == [2200.0, 2000.0]
    assert [r.speed for r in cfg.robots] == [0.3] * 3 + [0.2] * 3
    assert [r.speed_class for r in cfg.robots] == ["fast"] * 3 + ["slow"] * 3
    assert cfg.robot_radius == pytest.approx(0.22, abs=0.03)
    # spatially classifiable: crossing from one sink to the other circuit's source is clearly
    # longer than staying on the circuit
    (a, b) = cfg.circuits
    stay = math.dist(a.sink, a.source)
    cross = math.dist(a.sink, b.source)
    assert cross > 1.5 * stay
    homogeneous = tavc_env.preset("dahl2004_homogeneous")
    assert [r.speed for r in homogeneous.robots] == [0.25] * 6


def test_keyword_overrides_and_full_config() -> None:
    env = tavc_env.parallel_env(preset="dahl2004_homogeneous", source_service_s=12.0)
    assert env.config.source_service_s == 12.0
    assert [r.speed for r in env.config.robots] == [0.25] * 6
    cfg = tavc_env.preset("dahl2004").replace(sink_service_s=6.0)
    env = tavc_env.parallel_env(config=cfg, speeds=[0.2, 0.3])
    assert env.config.sink_service_s == 6.0 and env.possible_agents == ["robot_0", "robot_1"]
    assert [r.speed_class for r in env.config.robots] == ["slow", "fast"]


def test_policy_helpers_are_sane() -> None:
    """The suite's own helper: a constant policy sends every deciding robot to one circuit."""
    env = tavc_env.parallel_env()
    run = run_env(env, 5, policy=constant_policy(1), seed=0)
    assert run.steps[0].actions == dict.fromkeys(env.possible_agents, 1)


@pytest.mark.parametrize("version", ["v1", "v0"])
def test_the_env_writes_its_own_infos_after_a_breakdown(version: str) -> None:
    """`current_infos()` is what the last step returned with a breakdown since written in by the
    env (in its own version's form), so no caller above the env writes an info."""
    make = tavc_env.parallel_env if version == "v1" else tavc_env.v0.parallel_env
    env = make(preset="dahl2004")
    _, infos = env.reset(seed=4)
    _, _, _, _, infos = env.step({a: 0 for a in env.agents if infos[a]["action_required"]})
    assert env.current_infos() == infos
    env.break_down("robot_2")
    now = env.current_infos()
    broken = "broken" if version == "v0" else tavc_env.PHASES.index("broken")
    assert now["robot_2"] == {
        **infos["robot_2"],
        "action_required": False,
        "broken": True,
        "phase": broken,
    }
    assert {a: i for a, i in now.items() if a != "robot_2"} == {
        a: i for a, i in infos.items() if a != "robot_2"
    }
