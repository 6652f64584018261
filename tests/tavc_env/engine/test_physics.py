"""Physical rules: task times follow from path length, speed and station service; robots never
overlap and never leave the arena; broken robots stand still, are never asked to decide, free
their station, and come back through a decision epoch when repaired.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_env import PHASES, completed_task_s
from tavc_env.engine.tasks import Mode, Phase
from tests.helpers import (
    CONFIGS,
    CrowdTrace,
    constant_policy,
    lockstep,
    pairwise_min_distance,
    run_env,
)

OVERLAP_TOLERANCE_M = 0.03  # pymunk resolves contacts with a 2 mm slop; 3 cm is a real overlap
WALL_TOLERANCE_M = 0.02

# -- task time of a lone robot -----------------------------------------------------------------


def _lone_task_times(speed: float, n_tasks: int = 4, switch: bool = False) -> tuple[list, Any]:
    """Task times of a single robot (no speed noise) that keeps serving its start circuit (or,
    with `switch`, alternates circuits)."""
    env = tavc_env.parallel_env(speeds=[speed], speed_noise=0.0)
    _, infos = env.reset(seed=0)
    times = []
    for _ in range(n_tasks):
        info = infos["robot_0"]
        circuit = (1 - info["circuit"]) if switch else info["circuit"]
        _, _, _, _, infos = env.step({"robot_0": circuit})
        assert infos["robot_0"]["action_required"], "a lone robot's step ends at its epoch"
        times.append(float(infos["robot_0"]["task_time_s"]))
    return times, env


@pytest.mark.parametrize("speed", [0.2, 0.25, 0.3])
def test_lone_robot_task_time_is_travel_plus_service(speed: float) -> None:
    """Alone in the arena a robot's task time is its path (sink -> source -> sink, 2 x 5 m on the
    preset) over its speed, plus the loading and unloading times, plus a little turning and
    docking. Lower bound: it may stop up to `dock_tolerance_m` short of each dock. Upper bound:
    two turns on the spot (at most pi / max_turn_rate = 1.8 s each) and two slowed approaches
    (speed capped at distance / 1 s over the last metre, about 1 s each): 8 s covers both with
    margin and is at most 14 % of the nominal time."""
    times, env = _lone_task_times(speed)
    cfg = env.config
    circuit = cfg.circuits[0]
    path = 2 * math.dist(circuit.source, circuit.sink)
    service = cfg.source_service_s + cfg.sink_service_s
    nominal = path / speed + service
    lower = (path - 2 * cfg.dock_tolerance_m) / speed + service
    for t in times:
        assert lower <= t <= nominal + 8.0, (t, nominal)
        assert t == pytest.approx(nominal, rel=0.15)
    # no noise, no one else: every repetition of the same task takes the same time (to a tick)
    assert max(times[1:]) - min(times[1:]) <= cfg.dt + 1e-9


def test_task_time_scales_with_speed() -> None:
    """A 0.3 m/s robot beats a 0.2 m/s one by the travel-time difference path * (1/0.2 - 1/0.3)
    = 16.7 s (service and turning overheads are the same for both), within 15 %."""
    slow, env = _lone_task_times(0.2)
    fast, _ = _lone_task_times(0.3)
    circuit = env.config.circuits[0]
    path = 2 * math.dist(circuit.source, circuit.sink)
    expected = path * (1 / 0.2 - 1 / 0.3)
    gap = np.mean(slow) - np.mean(fast)
    assert gap == pytest.approx(expected, rel=0.15)


def test_switching_circuits_costs_more_than_staying() -> None:
    """Circuits are spatially classifiable: a task that starts at the other circuit's sink drives
    the long diagonal to the source, which costs clearly more than staying."""
    stay, env = _lone_task_times(0.25, n_tasks=2)
    switch, _ = _lone_task_times(0.25, n_tasks=2, switch=True)
    a, b = env.config.circuits
    extra = (math.dist(a.sink, b.source) - math.dist(a.sink, a.source)) / 0.25
    assert min(switch) > max(stay) + 0.8 * extra


def test_speed_noise_varies_task_times() -> None:
    """With the default 10 % speed noise the same lone task does not repeat to the tick."""
    env = tavc_env.parallel_env(speeds=[0.25])
    _, infos = env.reset(seed=1)
    times = set()
    for _ in range(5):
        _, _, _, _, infos = env.step({"robot_0": infos["robot_0"]["circuit"]})
        times.add(round(float(infos["robot_0"]["task_time_s"]), 6))
    assert len(times) >= 4


# -- crowding: no overlap, nothing leaves the arena --------------------------------------------


def test_robots_never_overlap_in_a_crowded_run(crowd_trace: CrowdTrace) -> None:
    """Six robots queueing at one circuit for 30 minutes, checked every physics tick."""
    r = crowd_trace.config.robot_radius
    pos = crowd_trace.pos
    diff = pos[:, :, None, :] - pos[:, None, :, :]
    dist = np.hypot(diff[..., 0], diff[..., 1])
    n = pos.shape[1]
    dist[:, np.arange(n), np.arange(n)] = np.inf
    worst = dist.min()
    tick = int(np.unravel_index(dist.argmin(), dist.shape)[0])
    assert worst >= 2 * r - OVERLAP_TOLERANCE_M, (
        f"centres {worst:.3f} m apart at t = {crowd_trace.time_s[tick]} s"
    )


def test_nothing_leaves_the_arena(crowd_trace: CrowdTrace) -> None:
    cfg = crowd_trace.config
    r = cfg.robot_radius
    x, y = crowd_trace.pos[..., 0], crowd_trace.pos[..., 1]
    assert x.min() >= r - WALL_TOLERANCE_M and x.max() <= cfg.width - r + WALL_TOLERANCE_M
    assert y.min() >= r - WALL_TOLERANCE_M and y.max() <= cfg.height - r + WALL_TOLERANCE_M
    assert np.all(np.isfinite(crowd_trace.pos))


def test_robots_crowding_stations_in_the_corners_stay_inside_the_walls() -> None:
    """Stations as close to the corners as the config allows (radius + 5 cm from two walls), all
    six robots on one circuit for 15 minutes, checked every tick: the discs press against the
    walls but their centres never come closer to a wall than a radius (minus 2 cm)."""
    circuits = (
        tavc_env.Circuit(source=(0.3, 7.7), sink=(0.3, 0.3), value=2200.0),
        tavc_env.Circuit(
            source=(11.7, 7.7), sink=(11.7, 0.3), value=2000.0, queue_direction=(-1.0, 0.0)
        ),
    )
    env = tavc_env.parallel_env(circuits=circuits, decision_interval_s=0.1, max_sim_time_s=900.0)
    obs, infos = env.reset(seed=0)
    cfg = env.config
    r = cfg.robot_radius
    low = np.array([r, r]) - WALL_TOLERANCE_M
    high = np.array([cfg.width, cfg.height]) - r + WALL_TOLERANCE_M
    while env.agents:
        obs, _, _, _, infos = env.step({a: 0 for a in obs if infos[a]["action_required"]})
        pos = env.sim.positions()
        assert np.all(pos >= low) and np.all(pos <= high), (env.sim.time_s, pos)
        assert pairwise_min_distance(pos) >= 2 * r - OVERLAP_TOLERANCE_M
    assert env.sim.tasks.completed.min() >= 3


def test_crowded_run_keeps_delivering(crowd_trace: CrowdTrace) -> None:
    """The crowd is slowed by the queue, not jammed: alone a task takes 60-75 s, so 30 minutes
    would allow about 25; six robots sharing one source with 20 s loading each can deliver at
    most 1800 / 20 = 90 tasks in total, 15 each. Each robot must manage a good part of that."""
    assert crowd_trace.completed.min() >= 8
    assert crowd_trace.completed.sum() <= 1800 / crowd_trace.config.source_service_s + 6
    assert crowd_trace.completed.max() - crowd_trace.completed.min() <= 3  # FCFS is fair
    assert np.all(crowd_trace.rewards > 0)


def test_robots_do_not_overlap_with_twelve_robots_on_three_circuits() -> None:
    """Twelve robots (six fast, six slow) choosing at random among three circuits: no two
    centres closer than a diameter (minus tolerance) after the first step (the start is checked
    elsewhere), over 20 simulated minutes, at every step."""
    env = tavc_env.parallel_env(**CONFIGS["three_circuits_12_robots"], max_sim_time_s=1200.0)
    run = run_env(env, 10_000, seed=3)
    assert env.agents == []
    r = env.config.robot_radius
    for rec in run.steps[1:]:
        assert pairwise_min_distance(rec.positions) >= 2 * r - OVERLAP_TOLERANCE_M


# -- breakdowns --------------------------------------------------------------------------------


def _until_loading_at_circuit_0(env: Any, obs: dict, infos: dict) -> tuple[int, dict, dict]:
    """Step `env` (everyone choosing circuit 0) until some robot is being loaded at circuit 0's
    source; returns it and the last observations and infos."""
    policy = constant_policy(0)
    rng = np.random.default_rng(0)
    tasks = env.sim.tasks
    for _ in range(200):
        obs, _, _, _, infos = env.step(policy(obs, infos, rng))
        occupant = tasks.stations[tasks.source_of(0)].occupant
        if occupant >= 0 and tasks.mode[occupant] == Mode.SERVICE:
            return occupant, obs, infos
    raise AssertionError("nobody was loaded at circuit 0's source")


def test_broken_robot_stands_still_is_never_asked_and_frees_its_dock() -> None:
    """All robots serve circuit 0. The robot being loaded at its source breaks down: the next in
    line takes the dock, the broken robot stays in `agents`, does not move, is never asked to
    decide, its actions are ignored, and the others keep completing tasks."""
    env, twin = tavc_env.parallel_env(), tavc_env.parallel_env()
    victim, obs, infos = _until_loading_at_circuit_0(env, *env.reset(seed=0))
    assert _until_loading_at_circuit_0(twin, *twin.reset(seed=0))[0] == victim
    name = f"robot_{victim}"
    source = env.sim.tasks.stations[env.sim.tasks.source_of(0)]
    assert source.line, "others are waiting behind the victim"
    head = source.line[0]
    frozen = env.sim.positions()[victim].copy()
    done_before = env.sim.tasks.completed.copy()
    env.break_down(name)
    twin.break_down(name)
    assert source.occupant == head, "the head of the line takes the freed dock"
    assert victim not in source.line

    actions = constant_policy(0)(obs, infos, np.random.default_rng(0))
    assert name not in actions
    obs, _, _, _, infos = env.step(actions)
    twin.step(actions)

    def policy(obs: dict, infos: dict, rng: np.random.Generator) -> dict:
        info = infos[name]  # at every step: present, broken, not asked, not paid a task
        assert info["phase"] == PHASES.index("broken") and info["broken"] is True
        assert info["action_required"] is False and completed_task_s(info) is None
        return constant_policy(0)(obs, infos, rng)

    def poke_the_broken_robot(obs: dict, infos: dict) -> dict:
        return {name: 1 - infos[name]["circuit"]}  # ignored: a broken robot takes no actions

    result = lockstep(twin, env, 30, (obs, infos), policy=policy, extra_b=poke_the_broken_robot)
    assert name in env.agents
    infos = result.infos
    info = infos[name]
    assert info["phase"] == PHASES.index("broken") and info["broken"] is True
    assert info["action_required"] is False and completed_task_s(info) is None
    assert np.array_equal(env.sim.positions()[victim], frozen)
    done = env.sim.tasks.completed - done_before
    assert done[victim] == 0
    assert all(done[i] >= 3 for i in range(6) if i != victim), done


def test_broken_robot_is_never_asked_over_a_run() -> None:
    env = tavc_env.parallel_env()
    obs, infos = env.reset(seed=1)
    env.break_down("robot_3")  # while it is deciding at reset: no action needed any more
    frozen = env.sim.positions()[3].copy()
    obs, _, _, _, infos = env.step({a: 0 for a in env.agents if a != "robot_3"})
    rng = np.random.default_rng(1)
    for _ in range(40):
        actions = {a: int(rng.integers(2)) for a in env.agents if infos[a]["action_required"]}
        assert "robot_3" not in actions
        obs, rewards, _, _, infos = env.step(actions)
        assert (
            infos["robot_3"]["phase"] == PHASES.index("broken")
            and not infos["robot_3"]["action_required"]
        )
        assert rewards["robot_3"] == 0.0
        assert np.array_equal(obs["robot_3"]["action_mask"], obs["robot_3"]["observation"])
        assert np.array_equal(env.sim.positions()[3], frozen)


def test_scheduled_breakdown_and_repair() -> None:
    """`Breakdown(robot=0, at_s=300, repair_after_s=600)`: broken from 300 s to 900 s; the repair
    is a decision epoch (the step ends there with robot_0 deciding); then it works again."""
    env = tavc_env.parallel_env(
        breakdowns=(tavc_env.Breakdown(robot=0, at_s=300.0, repair_after_s=600.0),)
    )
    obs, infos = env.reset(seed=0)
    rng = np.random.default_rng(0)
    repaired_at = None
    while env.sim.time_s < 1200.0:
        actions = {a: int(rng.integers(2)) for a in env.agents if infos[a]["action_required"]}
        obs, _, _, _, infos = env.step(actions)
        t, info = env.sim.time_s, infos["robot_0"]
        if t < 300.0 - 1e-9:
            assert info["phase"] != PHASES.index("broken")
        elif t < 900.0 - 1e-9:
            assert (
                info["phase"] == PHASES.index("broken")
                and info["broken"]
                and not info["action_required"]
            )
        elif repaired_at is None:
            repaired_at = t
            assert (
                info["action_required"]
                and info["phase"] == PHASES.index("deciding")
                and not info["broken"]
            )
            assert np.array_equal(obs["robot_0"]["action_mask"], [1, 1])
    assert repaired_at == pytest.approx(900.0)
    assert infos["robot_0"]["completed_tasks"] > 0
    assert env.sim.tasks.phase[0] != Phase.BROKEN


def test_manual_break_down_and_repair() -> None:
    env = tavc_env.parallel_env()
    env.reset(seed=2)
    _, _, _, _, infos = env.step(dict.fromkeys(env.agents, 1))
    env.break_down("robot_1")
    env.break_down("robot_1")  # idempotent
    _, _, _, _, infos = env.step({a: 1 for a in env.agents if infos[a]["action_required"]})
    assert infos["robot_1"]["broken"]
    env.repair("robot_1")
    before = env.sim.time_s
    _, _, _, _, infos = env.step({a: 1 for a in env.agents if infos[a]["action_required"]})
    assert env.sim.time_s - before == pytest.approx(env.config.dt), "the repair ends the step"
    assert infos["robot_1"]["action_required"] and infos["robot_1"]["phase"] == PHASES.index(
        "deciding"
    )
    # back to work: it completes a task on the circuit it chooses
    done = infos["robot_1"]["completed_tasks"]
    for _ in range(60):
        actions = {a: 0 for a in env.agents if infos[a]["action_required"]}
        _, _, _, _, infos = env.step(actions)
    assert infos["robot_1"]["completed_tasks"] > done
    # the repaired robot was put back without overlapping anyone
    assert pairwise_min_distance(env.sim.positions()) >= 2 * env.config.robot_radius - 0.03


@pytest.mark.parametrize("bad", ["robot_6", "robot_-1", "Robot_1", 1, None])
def test_break_down_and_repair_reject_unknown_robots(bad: Any) -> None:
    env = tavc_env.parallel_env()
    env.reset(seed=0)
    before = env.state().copy()
    with pytest.raises(ValueError, match=rf"agent {bad!r} is unknown; allowed: .*'robot_0'"):
        env.break_down(bad)
    with pytest.raises(ValueError, match=rf"agent {bad!r} is unknown"):
        env.repair(bad)
    assert np.array_equal(env.state(), before)


def test_repairing_a_working_robot_raises() -> None:
    env = tavc_env.parallel_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"agent = 'robot_1' is invalid; allowed: a robot that is"):
        env.repair("robot_1")


def test_all_robots_broken_steps_are_capped_and_a_repair_ends_one() -> None:
    env = tavc_env.parallel_env(step_cap_s=20.0)
    env.reset(seed=0)
    for a in env.agents:
        env.break_down(a)
    for k in range(1, 4):
        _, rewards, _, _, infos = env.step({})
        assert env.sim.time_s == pytest.approx(20.0 * k)
        assert not any(i["action_required"] for i in infos.values())
        assert all(i["broken"] for i in infos.values()) and not any(rewards.values())
    env.repair("robot_5")
    _, _, _, _, infos = env.step({})
    assert env.sim.time_s == pytest.approx(60.0 + env.config.dt)
    assert [a for a, i in infos.items() if i["action_required"]] == ["robot_5"]


def test_manual_breakdown_is_not_ended_by_a_stale_scheduled_repair() -> None:
    """Scheduled: break at 100 s, repair at 500 s. Repaired by hand at ~150 s, broken by hand at
    ~250 s (no repair scheduled for that one): it must stay broken until repaired by hand."""
    env = tavc_env.parallel_env(
        breakdowns=(tavc_env.Breakdown(robot=0, at_s=100.0, repair_after_s=400.0),)
    )
    _, infos = env.reset(seed=0)

    def go(until: float) -> dict:
        nonlocal infos
        while env.sim.time_s < until:
            actions = {a: 0 for a in env.agents if infos[a]["action_required"]}
            _, _, _, _, infos = env.step(actions)
        return infos

    assert go(150.0)["robot_0"]["broken"]
    env.repair("robot_0")
    assert not go(env.sim.time_s + 0.05)["robot_0"]["broken"]
    go(250.0)
    env.break_down("robot_0")
    assert go(700.0)["robot_0"]["broken"]


def test_a_knot_of_robots_is_dissolved_by_the_escape_behaviour() -> None:
    """Regression: with instant loading and unloading, six robots on one circuit once knotted
    below a dock for good (epsilon TAVC, seed 2: deliveries stopped at 5621 s). Stuck robots now
    back away after STUCK_PATIENCE_S, so everyone keeps delivering to the end."""
    from tavc_agents.experiments.registry import make_policy
    from tavc_agents.experiments.runner import run_trial

    result = run_trial(
        lambda agent: make_policy("epsilon_tavc", epsilon=0.1, init="scaled"),
        seed=2,
        convergence_s=6000.0,
        measured_s=1200.0,
        arena={"preset": "dahl2004", "source_service_s": 0.0, "sink_service_s": 0.0},
    )
    times = np.array(result.delivery_time_s)
    robots = np.array(result.delivery_robot)
    assert result.escapes > 0
    for i in range(6):
        assert np.any(times[robots == i] > 6000.0), f"robot {i} stopped delivering"


def test_the_escape_behaviour_never_fires_in_the_default_arena() -> None:
    """In the default arena robots wait in lines, not in knots: an hour of random choices needs no
    escape, so the escape behaviour leaves every default trajectory as it was."""
    env = tavc_env.parallel_env(preset="dahl2004", max_sim_time_s=3600.0)
    run_env(env, 10_000, seed=5)
    assert env.sim.escapes == 0
