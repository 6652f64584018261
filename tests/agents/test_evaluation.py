"""`tavc_agents.evaluate`: any agent scored on the suite's protocol.

A named allocator and the same decisions made by a PettingZoo-style policy on the plain scenario env
(`env.reset(seed=s)`) give the same value per hour, episode by episode: the evaluation seeds mean one
thing everywhere. Bad input is refused in one line naming the scenario, the episode and the robot.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tavc_agents
from tavc_agents.allocators.baselines import StayAllocator
from tavc_agents.evaluation import EvaluationError, evaluate, read_row
from tavc_agents.experiments.runner import run_trial
from tavc_agents.learners.network import Mlp, NetworkSet
from tavc_agents.learners.tavc import softmax_tavc
from tavc_env import RecordEpisodeStatistics
from tavc_env.scenarios import SCENARIOS, ScenarioEnv

SHORT = 0.2  # hours: the protocol's episodes, cut short (scores are not the leaderboard's)


def stay(observations: Mapping[str, Any], infos: Mapping[str, Mapping[str, Any]]) -> dict[str, int]:
    """The `stay` allocator as an RL researcher would write it for the parallel env."""
    return {a: int(i["circuit"]) for a, i in infos.items() if i["action_required"]}


@pytest.mark.parametrize("scenario", list(SCENARIOS))
def test_a_named_allocator_and_a_pettingzoo_policy_see_the_same_episodes(scenario: str) -> None:
    seeds = [SCENARIOS[scenario].eval_seeds[0], SCENARIOS[scenario].eval_seeds[-1]]
    named = evaluate("stay", scenario, seeds=seeds, episode_h=SHORT)
    plain = evaluate(stay, scenario, seeds=seeds, episode_h=SHORT)
    assert [e.value_per_hour for e in named.episodes] == [e.value_per_hour for e in plain.episodes]
    assert named.kind == "allocator" and plain.kind == "pettingzoo policy"


def test_the_last_infos_carry_the_episodes_statistics_and_score() -> None:
    scenario = SCENARIOS["priority_shifts"]  # values change mid-episode: paid when delivered
    env = RecordEpisodeStatistics(ScenarioEnv("priority_shifts", max_sim_time_s=SHORT * 3600))
    observations, infos = env.reset(seed=scenario.eval_seeds[0])
    while env.agents:
        assert all("episode_statistics" not in i for i in infos.values())
        observations, _, _, _, infos = env.step(stay(observations, infos))
    episode = infos["robot_0"]["episode_statistics"]
    assert all(i["episode_statistics"] == episode for i in infos.values())
    result = run_trial(
        lambda agent: StayAllocator(),
        seed=scenario.eval_seeds[0],
        convergence_s=0.0,
        measured_s=SHORT * 3600,
        snapshot_every_s=SHORT * 3600,
        arena={"scenario": "priority_shifts"},
    )
    assert episode["value"] == pytest.approx(sum(result.delivery_value), rel=0, abs=1e-9)
    assert episode["value_per_hour"] == pytest.approx(episode["value"] / SHORT)
    assert episode["score"] == pytest.approx(scenario.score(episode["value_per_hour"]))


def test_evaluate_is_importable_from_the_package_top_and_its_row_reads_back(tmp_path: Path) -> None:
    result = tavc_agents.evaluate("random", ["dahl2004", "passing"], seeds=3, episode_h=SHORT)
    assert len(result.episodes) == 6 and set(result.iqm) == {"dahl2004", "passing"}
    assert result.suite is not None and result.suite[1] <= result.suite[0] <= result.suite[2]
    for name, (point, low, high) in result.iqm.items():
        scores = result.scores(name)
        assert low <= point <= high and min(scores) <= point <= max(scores)
    row = read_row(result.save(tmp_path / "row.json"))
    assert row["name"] == "random" and len(row["episodes"]) == 6
    assert {"machine", "versions", "git"} <= set(row["metadata"])  # where and with what it ran


def test_a_policy_factory_and_a_sampled_network(tmp_path: Path) -> None:
    learner = evaluate(lambda agent: softmax_tavc(), "dahl2004", seeds=2, episode_h=SHORT)
    assert learner.kind == "policy factory" and len(learner.episodes) == 2
    config = SCENARIOS["dahl2004"].config()
    n, m = config.n_robots, config.n_circuits
    rng = np.random.default_rng(0)
    mlp = Mlp(
        [rng.normal(size=(8, n + m)), rng.normal(size=(m, 8))], [np.zeros(8), np.zeros(m)], "tanh"
    )
    path = tmp_path / "net.npz"
    mlp.save(path)
    sampled = evaluate(path, "dahl2004", seeds=2, episode_h=SHORT)
    again = evaluate(path, "dahl2004", seeds=2, episode_h=SHORT)
    greedy = evaluate(path, "dahl2004", seeds=2, episode_h=SHORT, readout="greedy")
    assert sampled.readout == "sampled" and greedy.readout == "greedy"
    assert sampled.episodes == again.episodes  # sampled from seeded generators: reproducible


def _raises(policy: Any) -> Any:
    def bad(observations: Mapping[str, Any], infos: Mapping[str, Mapping[str, Any]]) -> Any:
        return policy(infos)

    return bad


@pytest.mark.parametrize(
    ("agent", "kwargs", "message"),
    [
        ("stay", {"scenarios": "moon"}, "scenario 'moon' is unknown; allowed: one or more of"),
        ("no_such", {}, "allocator 'no_such' is unknown; allowed: one of"),
        ("stay", {"seeds": 0}, "seeds = 0 is invalid; allowed: 1 to 20"),
        (
            "stay",
            {"seeds": [7]},
            "seed 7 of scenario 'dahl2004' is invalid; allowed: its evaluation seeds",
        ),
        ("stay", {"seeds": 2.5}, "seeds = 2.5 is invalid"),
        (_raises(lambda infos: {a: 5 for a in infos}), {}, "action 5 for robot_0 is illegal"),
        (_raises(lambda infos: {}), {}, "no action for robot_0, which must decide"),
        (_raises(lambda infos: 1 / 0), {}, "the policy raised ZeroDivisionError"),
        (_raises(lambda infos: [0]), {}, "the policy returned list"),
    ],
)
def test_bad_input_is_refused_in_one_line_naming_where(
    agent: Any, kwargs: dict[str, Any], message: str
) -> None:
    options = {"scenarios": "dahl2004", "seeds": 1, "episode_h": SHORT, **kwargs}
    with pytest.raises(EvaluationError, match=r"^[^\n]*$") as error:
        evaluate(agent, **options)
    assert message in str(error.value)
    if callable(agent):
        assert "scenario 'dahl2004', episode 10000, t = " in str(error.value)


def test_a_network_for_another_arena_is_refused_before_any_episode(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    mlp = Mlp(
        [rng.normal(size=(4, 11)), rng.normal(size=(3, 4))], [np.zeros(4), np.zeros(3)], "tanh"
    )
    path = tmp_path / "other.npz"
    mlp.save(path)
    with pytest.raises(EvaluationError, match="trained for another arena"):
        evaluate(path, "dahl2004", seeds=1)


def test_a_network_set_for_another_team_size_is_refused_before_any_episode(
    tmp_path: Path,
) -> None:
    rng = np.random.default_rng(0)
    # dahl2004's shapes (8 inputs: 2 circuits + 6 robots; 2 scores), but sets for 5 robots
    mlps = tuple(
        Mlp([rng.normal(size=(4, 8)), rng.normal(size=(2, 4))], [np.zeros(4), np.zeros(2)])
        for _ in range(2)
    )
    path = NetworkSet(mlps, (0, 0, 1, 1, 1)).save(tmp_path / "five.npz")
    with pytest.raises(EvaluationError, match=r"routes 5 robots .* has 6: it was trained for"):
        evaluate(path, "dahl2004", seeds=1)


LEADERBOARD = Path(__file__).resolve().parents[2] / "benchmarks" / "results" / "leaderboard"


@pytest.mark.slow
@pytest.mark.parametrize("scenario", list(SCENARIOS))
def test_stay_on_the_plain_env_gives_the_committed_leaderboards_episodes(scenario: str) -> None:
    """For every evaluation seed s, `stay` written as a PettingZoo-style policy and run on the
    scenario's own env from `env.reset(seed=s)` gives exactly the committed leaderboard's value
    per hour for episode s: a user's seed and the leaderboard's mean the same episode."""
    import csv

    with (LEADERBOARD / "leaderboard.csv").open(encoding="utf-8") as f:
        committed = {
            int(r["seed"]): float(r["value_per_h"])
            for r in csv.DictReader(f)
            if r["scenario"] == scenario and r["allocator"] == "stay"
        }
    assert sorted(committed) == list(SCENARIOS[scenario].eval_seeds)
    mine = evaluate(stay, scenario)
    assert {e.seed: e.value_per_hour for e in mine.episodes} == committed


def test_a_named_allocator_that_fails_is_one_line_and_the_observation_can_be_chosen() -> None:
    observed = {"values": "observed"}  # the own-reward learner reading values from the observation
    with pytest.raises(EvaluationError, match=r"^own_reward, episode dahl2004__own_reward__10000"):
        evaluate("own_reward", "dahl2004", seeds=1, episode_h=0.05, params=observed)
    rich = evaluate(
        "own_reward", "priority_shifts", seeds=1, episode_h=0.1, params=observed,
        observation_mode="rich",
    )  # fmt: skip
    assert len(rich.episodes) == 1
    with pytest.raises(EvaluationError, match="observation_mode = 'x' is invalid"):
        evaluate("stay", "dahl2004", seeds=1, observation_mode="x")


def test_the_package_references_are_the_committed_reports() -> None:
    """The references the scenario envs and `evaluate` score with (package data) are those the
    leaderboards read from the scenarios study's committed report: one measurement, two files,
    written together by `benchmarks/scenarios.py --stage measure --update-reference`."""
    from tavc_agents.evaluation import references

    report = LEADERBOARD.parent / "scenarios" / "references.json"
    for name, ref in references(report).items():
        mine = SCENARIOS[name].references
        assert mine is not None
        assert (mine.random_per_h, mine.optimum_per_h) == (ref["random"], ref["optimum"])
