"""A long-run health check: 1.5 simulated hours of `dahl2004` with uniformly random choices.

Every robot keeps completing tasks (nobody jams), every step ends at a decision epoch (the step
cap is never hit), robots never overlap or leave the arena at step ends.

Gap bound: measured on seeds 0-2 of this run, the longest time between two completions of one
robot was 159-177 s (median about 95 s; a task alone takes 60-75 s, and a robot can wait behind
all five others at a source with 20 s loading each). 600 s is more than three times the longest
measured gap, and a robot stuck for good would exceed it within the run.

The study `benchmarks/long_run.py` (benchmarks/long_run.py) checks the same at length; a quick
run of it passes, and the same run judged with a one-minute limit fails.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import long_run as study
import tavc_env
from tavc_env import completed_task_s
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
            if completed_task_s(rec.infos[agent]) is not None:
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


ROOT = Path(__file__).resolve().parents[2]


def test_recorded_settings_are_those_of_the_committed_report() -> None:
    committed = json.loads((ROOT / "benchmarks" / "results" / "long_run.json").read_text())
    assert study.Settings().recorded() == committed["metadata"]["settings"]
    assert study.RUNS.key(study.LongRun(2, 15.0, "x")) == "seed2_15h"


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^max_gap_min = 0\.0 is invalid; allowed: > 0"):
        study.Settings(max_gap_min=0.0)


def test_quick_run_passes_and_a_tight_limit_fails(tmp_path: Path) -> None:
    command = [sys.executable, "benchmarks/long_run.py", "--quick", "--quiet", "--workers", "1"]
    command += ["--out", str(tmp_path)]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    said = done.stdout.splitlines()
    assert said[0] == f"Writing to {tmp_path}/"
    assert said[1].startswith("- **PASS**: longest gap")
    # a quick run is not compared with the committed full-size report
    assert "long_run.csv: not compared with the committed reference" in done.stdout
    summary = json.loads((tmp_path / "long_run.json").read_text())["summary"]
    seed = summary["per_seed"][0]
    assert seed["monitored_ticks"] == seed["ticks"] == 9000  # every tick of 0.25 h watched
    assert 0.40 < summary["min_center_distance_m"] < 1.0
    assert summary["capped_steps"] == 0 and summary["longest_gap"]["longest_gap_s"] < 600
    with open(tmp_path / "long_run_tasks_seed0.csv", encoding="utf-8") as fh:
        tasks = list(csv.DictReader(fh))
    with open(tmp_path / "long_run.csv", encoding="utf-8") as fh:
        robots = list(csv.DictReader(fh))
    assert len(robots) == 6 and sum(int(r["tasks"]) for r in robots) == len(tasks) > 30
    # The same seed with a 1-minute limit (resumed from the saved run): a robot waited longer.
    tight = subprocess.run(
        [*command, "--max-gap-min", "1"], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert tight.returncode == 1
    assert "FAIL: robot" in tight.stderr and "- **FAIL**" in tight.stdout


def test_any_preset_can_be_checked_and_a_bad_one_is_refused() -> None:
    with pytest.raises(ValueError, match=r"^preset = 'moon' is invalid; allowed: one of \["):
        study.Settings(preset="moon")
    s = study.Settings(preset="dahl2004_congestion", quick=True)
    assert s.recorded()["preset"] == "dahl2004_congestion"
    assert study.team_text("dahl2004") == "0-2 fast 0.3 m/s, 3-5 slow 0.2 m/s"
    assert study.team_text("three_circuits_three_classes").count("m/s") == 3
