"""The semi-MDP contract (docs/semi_mdp.md, DESIGN.md section 2.2): a robot's reward arrives in
the step that ends its task, which is its next decision epoch; `elapsed_s` there is the sojourn
time of the decision that earned it, and the sojourn times of a robot tile the episode; with
`reward="value"` the undiscounted return summed over robots, divided by the episode's hours, is
the delivered value per hour."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_env import completed_task_s
from tests.helpers import random_policy, run_env


def test_the_value_reward_pays_w_at_delivery_on_the_papers_trajectory() -> None:
    paper = run_env(tavc_env.parallel_env(), 40, seed=3, policy_seed=4)
    value = run_env(tavc_env.parallel_env(reward="value"), 40, seed=3, policy_seed=4)
    values = [c.value for c in tavc_env.preset("dahl2004").circuits]
    paid = 0
    for a_rec, b_rec in zip(paper.steps, value.steps, strict=True):
        assert a_rec.infos == b_rec.infos  # the same trajectory: only the rewards differ
        assert np.array_equal(a_rec.state, b_rec.state)
        for agent, info in b_rec.infos.items():
            t = completed_task_s(info)
            expected = 0.0 if t is None else values[info["circuit"]]
            assert b_rec.rewards[agent] == expected
            if t is not None:
                paid += 1
                assert a_rec.rewards[agent] == pytest.approx(expected / (1000.0 * t), rel=1e-12)
    assert paid > 10


def test_the_summed_value_return_per_hour_is_the_delivered_value_per_hour() -> None:
    """On a real hour with a priority change half-way (w swapped: the max stays 2200, so
    `delivered_value`, which counts w / max w, stays comparable), the robots' summed return
    divided by the hours equals the delivered value per hour counted from the infos with the
    values in force at each delivery, and from `env.delivered_value`."""
    env = tavc_env.parallel_env(reward="value", max_sim_time_s=3600.0)
    rng = np.random.default_rng(0)
    obs, infos = env.reset(seed=5)
    returns = dict.fromkeys(env.possible_agents, 0.0)
    counted = 0.0
    after_swap = set()
    swapped = False
    while env.agents:
        if not swapped and env.sim_time_s >= 1800.0:
            env.set_circuit_values((2000.0, 2200.0))
            swapped = True
        obs, rewards, _, _, infos = env.step(random_policy(obs, infos, rng))
        for agent, info in infos.items():
            returns[agent] += rewards[agent]
            if info["task_completed"]:
                counted += env.circuit_values[info["circuit"]]
                if swapped:
                    after_swap.add(info["circuit"])
    hours = env.sim_time_s / 3600.0
    assert hours == pytest.approx(1.0)
    assert after_swap == {0, 1}  # deliveries at both swapped values
    metric = sum(returns.values()) / hours
    assert metric == pytest.approx(counted / hours, rel=1e-12)
    assert metric == pytest.approx(env.delivered_value * 2200.0 / hours, rel=1e-12)
    assert 300_000 < metric < 700_000  # about 220 deliveries of 2000-2200 in the hour


def _epochs(run: Any) -> dict[str, list[tuple[float, float, bool]]]:
    """Each robot's semi-MDP transitions after the reset, read off a plain run as the contract
    says: (reward, elapsed_s, task completed) at every step that ends with it deciding, and the
    last, cut-off one at truncation."""
    out: dict[str, list[tuple[float, float, bool]]] = {a: [] for a in run.reset.infos}
    for rec in run.steps:
        for agent, info in rec.infos.items():
            truncated = rec.truncations[agent]
            if rec.rewards[agent] != 0.0:
                # paid only where the robot's task ended: at its next decision epoch
                assert info["task_completed"] and (info["action_required"] or truncated)
            if info["action_required"] or truncated:
                out[agent].append((rec.rewards[agent], info["elapsed_s"], info["task_completed"]))
    return out


@pytest.mark.parametrize("interval", [None, 5.0])
def test_sojourn_times_tile_the_episode_and_rewards_arrive_at_the_next_epoch(
    interval: float | None,
) -> None:
    """With a breakdown and a repair in the episode: every robot's `elapsed_s` at its decision
    epochs, plus the last one at truncation, add up to the episode's length (nothing is counted
    twice or lost, broken time included); a completed task's `elapsed_s` is its task time
    (event-driven) or that plus the wait for the step boundary (fixed interval)."""
    breakdown = tavc_env.Breakdown(robot=0, at_s=600.0, repair_after_s=300.0)
    env = tavc_env.parallel_env(
        max_sim_time_s=1800.0, decision_interval_s=interval, breakdowns=(breakdown,)
    )
    run = run_env(env, 10**6, seed=2)
    end = run.last.time_s
    assert end == pytest.approx(1800.0)
    for agent, epochs in _epochs(run).items():
        assert sum(tau for _, tau, _ in epochs) == pytest.approx(end, abs=1e-6), agent
    for rec in run.steps:
        for info in rec.infos.values():
            t = completed_task_s(info)
            if t is None:
                continue
            wait = info["elapsed_s"] - t
            if interval is None:
                assert wait == pytest.approx(0.0, abs=1e-9)
            else:
                assert -1e-9 <= wait < interval
    # the broken robot's abandoned task: its repair is an epoch paid nothing, whose sojourn runs
    # from the abandoned decision through the repair
    repairs = [e for e in _epochs(run)["robot_0"] if not e[2] and e[1] > breakdown.repair_after_s]
    assert len(repairs) == 1 and repairs[0][0] == 0.0


def test_value_reward_goes_through_the_deciders_only_view_unchanged() -> None:
    from tavc_env.adapters.deciders import DecidersOnly

    env = DecidersOnly(tavc_env.parallel_env(reward="value", max_sim_time_s=1200.0))
    obs, _ = env.reset(seed=1)
    total = 0.0
    while env.env.agents:
        obs, rewards, _, _, _ = env.step(dict.fromkeys(obs, 1))
        total += sum(rewards.values())
        assert all(r in (0.0, 2000.0) for r in rewards.values())  # one task per decision at most
    assert total == pytest.approx(env.env.delivered_value * 2200.0, rel=1e-12)
    assert not math.isnan(total) and total > 0
