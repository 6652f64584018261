"""Measuring the engine: the observers count what a tick-by-tick reference counts and change no
trajectory; fixed-allocation runs count the tasks their rules say; the speed measurements run."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tavc_env
from arena_runs import random_choice_run
from tavc_env.engine.simulation import Simulation
from tavc_env.measurement import (
    FixedAllocation,
    Mode,
    ModeTicks,
    SpacingMonitor,
    compiled_floor,
    compiled_loop_timer,
    physics_floor,
    physics_replay,
    run_fixed,
    two_circuit_allocation,
)

DURATION_S = 900.0


def _started(preset: str, seed: int) -> Simulation:
    sim = Simulation(tavc_env.make_config(preset))
    sim.reset(np.random.default_rng(seed))
    for i in range(sim.config.n_robots):
        sim.choose(i, i % 2)
    return sim


def test_mode_ticks_count_the_mode_each_robot_moved_in_during_each_tick() -> None:
    # Reference: one tick per call, the modes read just before each tick (after the decisions).
    ref_sim = _started("dahl2004", 3)
    reference = np.zeros((6, len(Mode)))
    while ref_sim.time_s < DURATION_S:
        began = ref_sim.time_s
        modes = ref_sim.modes.copy()
        out = ref_sim.advance(ref_sim.config.dt)
        if 120.0 <= began < 600.0:
            reference[np.arange(6), modes] += 1
        for c in out.completions:
            ref_sim.choose(c.robot, 1 - c.circuit)
    sim = _started("dahl2004", 3)
    counter = ModeTicks(sim, 120.0, 600.0)
    sim.add_observer(counter)
    while sim.time_s < DURATION_S:
        out = sim.advance(DURATION_S - sim.time_s)  # many ticks per call
        for c in out.completions:
            sim.choose(c.robot, 1 - c.circuit)
    np.testing.assert_array_equal(counter.counts, reference)
    assert counter.counts.sum() == 6 * round(480.0 / sim.config.dt)
    assert counter.counts[:, Mode.QUEUED].sum() > 0  # six robots on two circuits do queue
    assert counter.counts[:, Mode.IDLE].sum() == 0  # everyone decides at once: never idle


def test_spacing_monitor_finds_the_closest_approach_of_any_tick() -> None:
    sim = _started("dahl2004", 1)
    monitor = SpacingMonitor(sim.config)
    sim.add_observer(monitor)
    closest, closest_wall = math.inf, math.inf
    cfg = sim.config
    while sim.time_s < 300.0:
        out = sim.advance(cfg.dt)
        pos = sim.positions()
        d = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
        closest = min(closest, float(d[np.triu_indices(6, 1)].min()))
        wall = np.minimum(np.minimum(pos[:, 0], cfg.width - pos[:, 0]), pos[:, 1])
        wall = np.minimum(wall, cfg.height - pos[:, 1])
        closest_wall = min(closest_wall, float(wall.min()) - cfg.robot_radius)
        for c in out.completions:
            sim.choose(c.robot, c.circuit)
    assert monitor.ticks == sim.ticks
    assert monitor.min_dist == closest
    assert monitor.min_wall == pytest.approx(closest_wall, abs=1e-12)
    assert monitor.min_dist < 2 * cfg.robot_radius + 0.1  # robots in a line come close
    i, j = monitor.min_dist_at["pair"]
    assert 0 <= i < j < 6


def test_observers_change_no_trajectory() -> None:
    watched, plain = _started("dahl2004_homogeneous", 5), _started("dahl2004_homogeneous", 5)
    watched.add_observer(ModeTicks(watched, 0.0, math.inf))
    watched.add_observer(SpacingMonitor(watched.config))
    for sim in (watched, plain):
        while sim.time_s < 600.0:
            for c in sim.advance(600.0).completions:
                sim.choose(c.robot, c.circuit)
    np.testing.assert_array_equal(watched.positions(), plain.positions())
    np.testing.assert_array_equal(watched.headings, plain.headings)


def _alloc(**changes: object) -> FixedAllocation:
    base = {
        "preset": "dahl2004_homogeneous",
        "circuit_of": two_circuit_allocation(3),
        "seed": 0,
        "hours": 0.2,
        "warmup_s": 120.0,
        "skip_first": 1,
    }
    return FixedAllocation(**{**base, **changes})  # type: ignore[arg-type]


def test_a_fixed_run_counts_tasks_by_its_rules() -> None:
    run = run_fixed(_alloc())
    assert run.classes == ["medium"] * 6
    assert run.tasks and all(t.kind == "own" for t in run.tasks)
    assert all(120.0 - 1e-9 <= t.decided_s <= 0.2 * 3600 + 1e-9 for t in run.tasks)
    assert all(t.circuit == (0 if t.robot < 3 else 1) for t in run.tasks)
    # the first task of each robot is skipped even where it would fall in the window
    assert all(t.task_time_s > 55.0 for t in run.tasks)
    assert run.mode_ticks.sum() == 6 * round((720.0 - 120.0) / 0.1)


def test_the_switcher_alternates_every_block() -> None:
    run = run_fixed(_alloc(circuit_of=(0,), switcher=0, switch_every=3, speeds=(0.25,), hours=0.3))
    kinds = [t.kind for t in run.tasks]
    circuits = [t.circuit for t in run.tasks]
    assert "switch" in kinds
    for k, (kind, c) in enumerate(zip(kinds, circuits)):
        if kind == "switch":
            assert circuits[k - 1] != c if k > 0 else True
            assert kinds[k + 1 : k + 3] in (["own", "own"], ["own"], [])
    switch_mean = np.mean([t.task_time_s for t in run.tasks if t.kind == "switch"])
    own_mean = np.mean([t.task_time_s for t in run.tasks if t.kind == "own"])
    assert switch_mean > 1.15 * own_mean  # from the other circuit's sink: a longer drive


def test_a_fixed_run_refuses_an_allocation_of_the_wrong_size() -> None:
    with pytest.raises(ValueError, match="circuit_of"):
        run_fixed(_alloc(circuit_of=(0, 1)))


def test_two_circuit_allocation() -> None:
    assert two_circuit_allocation(2) == (0, 0, 1, 1, 1, 1)
    assert two_circuit_allocation(0, 3) == (1, 1, 1)


def test_speed_measurements_run_as_many_ticks() -> None:
    config = tavc_env.make_config("dahl2004")
    env = random_choice_run(config, 0, 300.0)
    assert env["sim_s"] == pytest.approx(300.0) and env["ticks"] == 3000
    assert env["decisions"] >= 6 and env["wall_s"] > 0
    floor = physics_floor(config, 0, 500, each_tick=True)
    assert floor["ticks"] == 500 and floor["sim_s"] == pytest.approx(50.0)


@pytest.mark.parametrize("robots", [6, 24])
def test_the_physics_yardsticks_replay_the_env_exactly(robots: int) -> None:
    """The compiled floor and the Python replay end bit for bit where the env's run ended."""
    from arena_runs import team_config

    config = team_config(robots)
    recorded = random_choice_run(config, 3, 120.0, record=True)
    for replay in (compiled_floor, physics_replay):
        found = replay(config, recorded)
        assert found["exact"] and found["ticks"] == recorded["ticks"] == 1200


def test_the_compiled_loop_timer_times_a_part_of_a_run_and_changes_nothing() -> None:
    config = tavc_env.make_config("dahl2004")
    plain = random_choice_run(config, 3, 300.0)
    loop_before = tavc_env.engine.simulation.run_ticks
    with compiled_loop_timer() as spent:
        timed = random_choice_run(config, 3, 300.0)
    assert tavc_env.engine.simulation.run_ticks is loop_before  # restored
    assert (timed["ticks"], timed["decisions"]) == (plain["ticks"], plain["decisions"])
    assert 0.0 < spent[0] < timed["cpu_s"]
