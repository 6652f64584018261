"""Seeding and reproducibility: same seed + same actions give identical trajectories, step for step
(observations, rewards, terminations, truncations, infos, `state()`, positions, simulated time);
a different seed gives a different trajectory; an env survives a pickle round trip mid-episode.

PettingZoo's `parallel_seed_test` is run in test_pettingzoo_api.py, but it stops after one step
(`any(truncations)` iterates over the dict's keys, which are truthy), so the long comparison is ours.
"""

from __future__ import annotations

import copy
import pickle
from typing import Any

import numpy as np
import pytest

import tavc_env
from tests.helpers import assert_same_step, lockstep, random_policy, run_env


def test_same_seed_same_actions_identical_for_200_steps() -> None:
    env_a, env_b = tavc_env.parallel_env(), tavc_env.parallel_env()
    reset_a = run_env(env_a, 0, seed=2024).reset
    reset_b = run_env(env_b, 0, seed=2024).reset
    assert_same_step(reset_a, reset_b, where="reset")
    start = (reset_a.obs, reset_a.infos)
    completions = lockstep(
        env_a, env_b, 200, start, policy=random_policy, policy_seed=5
    ).completions
    assert env_a.num_cycles == env_b.num_cycles == 200
    # The comparison covered a real trajectory, not 200 idle steps.
    assert completions >= 190
    assert env_a.sim.time_s > 45 * 60


def test_different_seed_gives_a_different_trajectory() -> None:
    run_a = run_env(tavc_env.parallel_env(), 30, seed=0, policy_seed=5)
    run_b = run_env(tavc_env.parallel_env(), 30, seed=1, policy_seed=5)
    # Headings at reset are drawn from the seed, so the global states differ from the start ...
    assert not np.array_equal(run_a.reset.state, run_b.reset.state)
    # ... and the trajectories never coincide again: different step times and positions.
    times_a = [r.time_s for r in run_a.steps]
    times_b = [r.time_s for r in run_b.steps]
    assert times_a != times_b
    assert all(
        not np.array_equal(a.positions, b.positions)
        for a, b in zip(run_a.steps, run_b.steps, strict=True)
    )


def test_reset_with_the_same_seed_replays_the_episode_on_a_used_env() -> None:
    """A used env reset with a seed behaves exactly like a fresh one (nothing leaks across
    episodes: world, schedules, speed noise, counters)."""
    env = tavc_env.parallel_env(
        breakdowns=(tavc_env.Breakdown(robot=1, at_s=200.0, repair_after_s=100.0),)
    )
    first = run_env(env, 40, seed=11, policy_seed=3)
    env.break_down("robot_4")  # leftover from the first episode, must not survive the reset
    second = run_env(env, 40, seed=11, policy_seed=3)
    fresh = run_env(
        tavc_env.parallel_env(
            breakdowns=(tavc_env.Breakdown(robot=1, at_s=200.0, repair_after_s=100.0),)
        ),
        40,
        seed=11,
        policy_seed=3,
    )
    assert len(first.records) == len(second.records) == len(fresh.records) == 41
    for k, (a, b, c) in enumerate(zip(first.records, second.records, fresh.records, strict=True)):
        assert_same_step(a, b, where=f"record {k} (first vs second episode)")
        assert_same_step(a, c, where=f"record {k} (used vs fresh env)")


def test_unseeded_reset_continues_the_seeded_generator() -> None:
    """`reset()` without a seed continues the generator of the last seeded reset: reproducible
    across envs, and a new episode (not a replay of the previous one)."""
    env_a, env_b = tavc_env.parallel_env(), tavc_env.parallel_env()
    first = run_env(env_a, 5, seed=9)
    run_env(env_b, 5, seed=9)
    second_a = run_env(env_a, 5, seed=None)
    second_b = run_env(env_b, 5, seed=None)
    for a, b in zip(second_a.records, second_b.records, strict=True):
        assert_same_step(a, b)
    assert not np.array_equal(first.reset.state, second_a.reset.state)


def _clone_by(method: str, env: Any) -> Any:
    if method == "pickle":
        return pickle.loads(pickle.dumps(env))
    return copy.deepcopy(env)


@pytest.mark.parametrize("method", ["pickle", "deepcopy"])
@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        # fixed-interval mode with a scheduled breakdown and its repair still pending
        {
            "decision_interval_s": 5.0,
            "breakdowns": (tavc_env.Breakdown(robot=2, at_s=160.0, repair_after_s=90.0),),
        },
    ],
    ids=["event_driven", "fixed_interval_with_breakdown"],
)
def test_round_trip_mid_episode_continues_identically(method: str, kwargs: dict) -> None:
    env = tavc_env.parallel_env(**kwargs)
    run = run_env(env, 25, seed=4, policy_seed=8)
    if "breakdowns" in kwargs:  # cloned before the breakdown: the schedule must travel along
        assert env.sim.time_s < 160.0
    clone = _clone_by(method, env)
    assert clone is not env and clone.sim is not env.sim
    assert np.array_equal(clone.state(), env.state())
    completions = lockstep(
        env, clone, 60, (run.last.obs, run.last.infos), policy=random_policy, policy_seed=9
    ).completions
    assert completions > 0
    if "breakdowns" in kwargs:  # ... and it fired (break at 160 s, repair at 250 s) in both
        assert clone.sim.time_s > 250.0
        assert clone.sim.tasks.phase[2] != 3 and clone.sim.tasks.completed[2] >= 1
