"""A long-run health check: 1.5 simulated hours of `dahl2004` with uniformly random choices.

Every robot keeps completing tasks (nobody jams), every step ends at a decision epoch (the step
cap is never hit), robots never overlap or leave the arena at step ends.

Gap bound: measured on seeds 0-2 of this run, the longest time between two completions of one
robot was 159-177 s (median about 95 s; a task alone takes 60-75 s, and a robot can wait behind
all five others at a source with 20 s loading each). 600 s is more than three times the longest
measured gap, and a robot stuck for good would exceed it within the run.
"""

from __future__ import annotations

import numpy as np
import pytest

import tavc_env
from tests.helpers import pairwise_min_distance, run_env

DURATION_S = 1.5 * 3600
MAX_GAP_S = 600.0


@pytest.mark.slow
def test_random_choices_for_one_and_a_half_hours_keep_everyone_working() -> None:
    env = tavc_env.parallel_env(max_sim_time_s=DURATION_S)
    run = run_env(env, 100_000, seed=0, policy_seed=0)
    cfg = env.config
    r = cfg.robot_radius
    assert env.agents == [] and run.last.time_s == pytest.approx(DURATION_S)

    last_done = np.zeros(cfg.n_robots)
    longest_gap = np.zeros(cfg.n_robots)
    completed = np.zeros(cfg.n_robots, dtype=int)
    per_circuit = np.zeros(cfg.n_circuits, dtype=int)
    for k, rec in enumerate(run.steps[:-1]):  # the last step is cut by the time limit
        assert any(i["action_required"] for i in rec.infos.values()), f"step {k} hit the cap"
        assert rec.duration_s < env.step_cap_s
    for rec in run.steps:
        for i, agent in enumerate(env.possible_agents):
            if rec.infos[agent]["task_time_s"] is not None:
                longest_gap[i] = max(longest_gap[i], rec.time_s - last_done[i])
                last_done[i] = rec.time_s
                completed[i] += 1
                per_circuit[rec.infos[agent]["circuit"]] += 1
        assert pairwise_min_distance(rec.positions) >= 2 * r - 0.03
        assert np.all(rec.positions >= r - 0.02)
        assert np.all(rec.positions <= np.array([cfg.width, cfg.height]) - r + 0.02)
    longest_gap = np.maximum(longest_gap, DURATION_S - last_done)  # the wait at the end counts
    assert longest_gap.max() <= MAX_GAP_S, longest_gap
    # ~95 s per task: about 55 each; random choices send everyone to both circuits
    assert completed.min() >= 30, completed
    assert per_circuit.min() >= 0.3 * per_circuit.sum()
    # the final info agrees with what was counted step by step
    assert [run.last.infos[a]["completed_tasks"] for a in env.possible_agents] == completed.tolist()
