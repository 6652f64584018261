"""Timing the env: the PettingZoo env's speed with random choices, in CPU seconds of the measuring
process (`time.process_time`: on a shared machine wall time also counts the other processes' turns).

The bare-physics yardsticks it is set beside (`physics_replay`, `physics_floor`) and the recorder of
a run's velocity commands live with the engine's other measurements, in `tavc_env.measurement`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

import tavc_env
from tavc_env.config import ArenaConfig
from tavc_env.measurement import CommandRecorder


def random_choice_run(
    config: ArenaConfig,
    seed: int,
    sim_s: float,
    decision_interval_s: float | None = None,
    record: bool = False,
) -> dict[str, Any]:
    """Time `sim_s` simulated seconds of the PettingZoo parallel env (event-driven stepping, or
    every `decision_interval_s`), every robot that must decide picking a circuit uniformly at
    random (numpy Generator seeded [seed, 1]): CPU and wall seconds, simulated seconds, physics
    ticks and decisions. With `record`, also the run's physics (untimed: an observer reads every
    tick): `start` (positions after reset), `commands` (ticks, n, 2: every tick's velocity
    commands) and `end` (positions at the end), for `physics_replay`."""
    env = tavc_env.parallel_env(
        config=config,
        max_sim_time_s=sim_s,
        max_cycles=10**9,
        decision_interval_s=decision_interval_s,
    )
    m = config.n_circuits
    rng = np.random.default_rng([seed, 1])
    _, infos = env.reset(seed=seed)
    recorder = CommandRecorder(env.sim) if record else None
    decisions = 0
    cpu0, wall0 = time.process_time(), time.perf_counter()
    while env.agents:
        actions = {a: int(rng.integers(m)) for a in env.agents if infos[a]["action_required"]}
        decisions += len(actions)
        _, _, _, _, infos = env.step(actions)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    found: dict[str, Any] = {
        "cpu_s": cpu,
        "wall_s": wall,
        "sim_s": env.sim_time_s,
        "ticks": env.sim.ticks,
        "decisions": decisions,
    }
    if recorder is not None:
        found.update(recorder.recording(env.sim))
    return found


TEAM_SIZES = {6: None, 24: 8, 96: 32, 384: 128}
"""The team sizes the throughput benchmarks time: robots -> lanes of `tavc_env.scaled_config`
(None: the `dahl2004` preset)."""


def team_config(robots: int, dt: float | None = None) -> ArenaConfig:
    """`dahl2004` for 6 robots, `scaled_config(lanes, 3)` for more (`TEAM_SIZES`); with step `dt`
    if given."""
    if robots not in TEAM_SIZES:
        raise ValueError(f"robots = {robots!r} is invalid; allowed: one of {list(TEAM_SIZES)}")
    lanes = TEAM_SIZES[robots]
    config = tavc_env.make_config("dahl2004") if lanes is None else tavc_env.scaled_config(lanes, 3)
    return config if dt is None else config.replace(dt=dt)
