"""The fast paths of the engine agree exactly with the slow ones they replace.

* `World` reads positions and writes velocities through pymunk's batch API: the values must be
  those of per-body attribute access, also after robots leave and re-enter the space (which
  reorders pymunk's bodies).
* `navigation.steer_all_grid` finds each robot's neighbours on a grid: the commands must be
  exactly those of `steer_all`, which looks at every pair.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_env.engine.navigation import (
    _standard_normal_c,
    bit_generator_calls,
    grid_scratch,
    neighbour_cell_m,
    steer_all,
    steer_all_grid,
    steer_grid_into,
    steer_near_into,
)
from tavc_env.engine.simulation import Simulation
from tavc_env.engine.world import World


def per_body_positions(world: World) -> np.ndarray:
    return np.array([tuple(b.position) for b in world.bodies])


@pytest.mark.parametrize("preset", ["dahl2004", "three_circuits_three_classes"])
def test_batched_positions_and_velocities_match_per_body_access(preset: str) -> None:
    config = tavc_env.make_config(preset)
    world = World(config)
    rng = np.random.default_rng(5)
    n = world.n
    lo, hi = 1.0, np.array([config.width, config.height]) - 1.0
    world.place(np.column_stack([np.linspace(1.0, config.width - 1.0, n), np.full(n, 4.0)]))
    removed: list[int] = []
    for step in range(300):
        if step % 37 == 5:  # robots leave and come back, in an order that reshuffles pymunk's
            i = int(rng.integers(n))
            if world.in_space[i] and len(removed) < n - 1:
                world.remove_robot(i)
                removed.append(i)
            elif removed:
                world.restore_robot(removed.pop(0), rng)
        velocities = rng.uniform(-0.3, 0.3, size=(n, 2))
        world.set_velocities(velocities)
        for i in np.flatnonzero(world.in_space):
            assert tuple(world.bodies[i].velocity) == tuple(velocities[i])
        world.step(config.dt)
        assert np.array_equal(world.positions(), per_body_positions(world))
    assert np.all(per_body_positions(world) > lo - 1.0)
    assert np.all(per_body_positions(world) < hi + 1.0)


def test_grid_neighbour_search_gives_exactly_the_all_pairs_commands() -> None:
    rng = np.random.default_rng(3)
    radius, sensing, turn, w, h = 0.22, 1.0, 0.175, 30.0, 12.0
    cell = neighbour_cell_m(radius, sensing)
    for trial in range(100):
        n = int(rng.integers(2, 60))
        # crowded clusters and scattered robots, some just outside the walls' line
        pos = rng.uniform(-0.1, 1.0, size=(n, 2)) * np.array([w, h])
        if trial % 2:
            pos[: n // 2] = rng.normal([5.0, 5.0], 0.6, size=(n // 2, 2))
        heading = rng.uniform(-np.pi, np.pi, n)
        target = pos + rng.normal(scale=2.0, size=(n, 2))
        moving = rng.random(n) < 0.8
        speed = rng.uniform(0.2, 0.3, n)
        present = rng.random(n) < 0.9
        a_v, a_h = np.zeros((n, 2)), np.zeros(n)
        b_v, b_h = np.zeros((n, 2)), np.zeros(n)
        # every other trial with the clearance governor at its largest allowed range
        governor = (sensing - 2 * radius) * (trial % 2)
        overtaking = trial % 4 >= 2  # and overtaking on in half of each
        common = (pos, heading, target, moving, speed, present, radius, sensing, governor)
        common += (overtaking, turn, w, h)
        steer_all(*common, a_v, a_h)
        steer_all_grid(*common, b_v, b_h, cell)
        assert np.array_equal(a_v, b_v) and np.array_equal(a_h, b_h), trial


def test_simulation_with_and_without_the_grid_is_identical(monkeypatch: pytest.MonkeyPatch) -> None:
    import tavc_env.engine.simulation as simulation

    config = tavc_env.scaled_config(8)  # 24 robots: above GRID_MIN_ROBOTS

    def run() -> np.ndarray:
        sim = simulation.Simulation(config)
        sim.reset(np.random.default_rng(2))
        rng = np.random.default_rng(9)
        for i in range(config.n_robots):
            sim.choose(i, int(rng.integers(config.n_circuits)))
        trace = []
        for _ in range(40):
            out = sim.advance(30.0, stop_on_decision=False)
            for c in out.completions:
                sim.choose(c.robot, int(rng.integers(config.n_circuits)))
            trace.append(sim.positions())
        return np.array(trace)

    assert simulation.Simulation(config)._grid_cell > 0
    with_grid = run()
    monkeypatch.setattr(simulation, "GRID_MIN_ROBOTS", 10**9)
    assert simulation.Simulation(config)._grid_cell == 0
    assert np.array_equal(with_grid, run())


@pytest.mark.parametrize(("preset", "lanes"), [("dahl2004_congestion", None), ("dahl2004", 8)])
def test_compiled_tick_is_the_physics_of_its_commands(preset: str, lanes: int | None) -> None:
    """The compiled tick calls Chipmunk and pymunk's batch functions directly: every tick's
    velocity commands, replayed through pymunk's Python API on a fresh world, end exactly where
    the simulation ended; and running quiet ticks in bulk (no observer) or one by one (an
    observer) gives the same run, escapes and breakdowns included."""
    config = tavc_env.make_config(preset) if lanes is None else tavc_env.scaled_config(lanes)
    broken = config.replace(
        breakdowns=[tavc_env.Breakdown(at_s=300.0, robot=1, repair_after_s=200.0)]
    )

    class Recorder:
        def __init__(self) -> None:
            self.commands: list[np.ndarray] = []

        def on_tick(self, sim: Simulation, events: list[object]) -> None:
            self.commands.append(sim.world.velocity_out.copy())

    def run(config: tavc_env.ArenaConfig, recorder: Recorder | None) -> Simulation:
        sim = Simulation(config, jam_window_s=120.0)
        sim.reset(np.random.default_rng(3))
        if recorder is not None:
            sim.add_observer(recorder)
        rng = np.random.default_rng(4)
        while sim.time_s < 1200.0:
            for i in np.flatnonzero(sim.tasks.needs_decision()):
                sim.choose(int(i), int(rng.integers(config.n_circuits)))
            sim.advance(300.0)
        return sim

    observed, bulk = run(broken, Recorder()), run(broken, None)
    assert np.array_equal(observed.positions(), bulk.positions())
    assert np.array_equal(observed.headings, bulk.headings)
    assert (observed.ticks, observed.escapes) == (bulk.ticks, bulk.escapes)
    assert observed.time_s >= 1200.0 and observed.broken().sum() == 0  # repaired

    recorder = Recorder()
    recorded = run(config, recorder)
    start = Simulation(config)
    start.reset(np.random.default_rng(3))
    world = World(config)
    world.place(start.positions())
    for velocity in recorder.commands:
        for body, v in zip(world.bodies, velocity):
            body.velocity = tuple(v)
        world.space.step(config.dt)
    replayed = np.array([tuple(b.position) for b in world.bodies])
    assert np.array_equal(replayed, recorded.positions())


def _random_tick(
    rng: np.random.Generator,
    pos: np.ndarray,
    present: np.ndarray,
    radius: float,
    sensing: float,
    turn: float,
    w: float,
    h: float,
) -> tuple[tuple[Any, ...], np.ndarray, np.ndarray]:
    """One tick of random headings, targets, moving flags and speeds for robots at `pos`: the
    arguments every steering function shares, and `steer_all`'s commands for them (the
    reference the faster ones must equal)."""
    n = len(pos)
    heading = rng.uniform(-np.pi, np.pi, n)
    target = pos + rng.normal(scale=2.0, size=(n, 2))
    moving = rng.random(n) < 0.8
    speed = rng.uniform(0.2, 0.3, n)
    common = (pos, heading, target, moving, speed, present, radius, sensing, 0.0, False)
    common += (turn, w, h)
    a_v, a_h = np.zeros((n, 2)), np.zeros(n)
    steer_all(*common, a_v, a_h)
    return common, a_v, a_h


def test_the_grid_kept_from_tick_to_tick_gives_exactly_the_all_pairs_commands() -> None:
    """The compiled tick keeps the grid's sorted order from one tick to the next
    (`steer_grid_into`): robots moving between cells, leaving and re-entering the floor, and
    scratch left by another team leave the commands those of `steer_all`."""
    rng = np.random.default_rng(8)
    radius, sensing, turn, w, h = 0.22, 1.0, 0.175, 30.0, 12.0
    cell = neighbour_cell_m(radius, sensing)
    n = 40
    scratch = grid_scratch(n)
    pos = rng.uniform(0.0, 1.0, size=(n, 2)) * np.array([w, h])
    present = np.ones(n, dtype=bool)
    for tick in range(300):
        pos += rng.normal(scale=0.3 if tick % 50 else 3.0, size=(n, 2))  # now and then a jump
        if tick % 7 == 0:
            present = rng.random(n) < 0.85
        if tick == 150:
            scratch[3][:] = rng.permutation(n)  # another team's order, as many robots held
            scratch[6][0] = int(present.sum())
        common, a_v, a_h = _random_tick(rng, pos, present, radius, sensing, turn, w, h)
        b_v, b_h = np.zeros((n, 2)), np.zeros(n)
        steer_grid_into(*common, b_v, b_h, cell, *scratch[:7])
        assert np.array_equal(a_v, b_v) and np.array_equal(a_h, b_h), tick


@pytest.mark.parametrize("seed", range(40))
def test_the_compiled_normal_draw_is_numpys(seed: int) -> None:
    """The compiled tick draws a leg's speed noise from the user's generator itself
    (`navigation._standard_normal` through `bit_generator_calls`): the same values as
    `rng.standard_normal()`, bit for bit, tails included, and the generator ends where numpy's
    would."""
    draws = 5000  # about 35 per seed from the ziggurat's slower branches
    ours, theirs = np.random.default_rng(seed), np.random.default_rng(seed)
    calls = bit_generator_calls(ours)
    got = np.array([_standard_normal_c(calls) for _ in range(draws)])
    assert np.array_equal(got, theirs.standard_normal(draws))
    assert ours.bit_generator.state == theirs.bit_generator.state
    other = np.random.Generator(np.random.Philox(seed))  # any bit generator
    again = np.random.Generator(np.random.Philox(seed))
    calls = bit_generator_calls(other)
    assert [_standard_normal_c(calls) for _ in range(50)] == again.standard_normal(50).tolist()


@pytest.mark.parametrize("room", [None, 45])
def test_neighbour_lists_kept_over_ticks_give_exactly_the_all_pairs_commands(
    room: int | None,
) -> None:
    """The compiled tick steers large teams on neighbour lists kept over ticks
    (`steer_near_into`): robots drifting less than the skin between ticks (lists kept), jumping
    (lists made anew), leaving and re-entering the floor, and lists too long for their room
    (`room`: that tick falls back to the grid) leave the commands those of `steer_all`."""
    rng = np.random.default_rng(9)
    radius, sensing, turn, w, h = 0.22, 1.0, 0.175, 20.0, 8.0
    cell = neighbour_cell_m(radius, sensing)
    n = 40
    scratch = list(grid_scratch(n))
    if room is not None:
        scratch[7] = np.zeros(room, np.int64)
    pos = rng.uniform(0.0, 1.0, size=(n, 2)) * np.array([w, h])
    present = np.ones(n, dtype=bool)
    made = 0
    for tick in range(400):
        pos += rng.normal(scale=0.02 if tick % 40 else 2.0, size=(n, 2))
        if tick % 23 == 0:
            present = rng.random(n) < 0.85
        common, a_v, a_h = _random_tick(rng, pos, present, radius, sensing, turn, w, h)
        b_v, b_h = np.zeros((n, 2)), np.zeros(n)
        anchor_before = scratch[9].copy()
        steer_near_into(*common, b_v, b_h, cell, *scratch)
        made += not np.array_equal(anchor_before, scratch[9])
        assert np.array_equal(a_v, b_v) and np.array_equal(a_h, b_h), tick
    if room is None:
        assert 20 < made < 200  # kept over most ticks, made anew after jumps and drift
    else:
        assert scratch[11][0] == -1  # the lists did not fit: the grid steered


@pytest.mark.parametrize("speed_noise", [0.0, 0.1])
def test_the_compiled_tick_runs_the_task_rules_itself(
    speed_noise: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Arrivals, dockings and service ends run inside the compiled tick, and so do the speed
    draws of legs to the sink: it hands the tick back to Python at a completion (a decision
    epoch), not at every task event nor at a leg."""
    handbacks = []
    end_tick = Simulation._end_tick
    monkeypatch.setattr(
        Simulation, "_end_tick", lambda sim, *args: handbacks.append(1) or end_tick(sim, *args)
    )
    config = tavc_env.make_config("dahl2004", speed_noise=speed_noise)
    sim = Simulation(config, jam_window_s=math.inf)
    sim.reset(np.random.default_rng(2))
    choices = np.random.default_rng(3)
    while sim.time_s < 3600.0:
        for i in np.flatnonzero(sim.tasks.needs_decision()):
            sim.choose(int(i), int(choices.integers(config.n_circuits)))
        sim.advance(3600.0 - sim.time_s)
    tasks = int(sim.tasks.completed.sum())
    assert tasks > 100 and sim.escapes == 0
    # at most: events of one tick come back together
    assert len(handbacks) <= tasks + 1
