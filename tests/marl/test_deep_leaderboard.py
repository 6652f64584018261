"""The deep leaderboard at a tiny budget: a run end to end (training, curve, evaluation, both
read-outs, report), resume without retraining or reading out again, and settings it refuses
(marker `marl`: needs TorchRL)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import deep_leaderboard as study

pytestmark = pytest.mark.marl
pytest.importorskip("torchrl")


def tiny(out: Path, **changes: Any) -> study.Settings:
    """One IPPO run on the paper's scenario: 300 decisions, 2 evaluation seeds of 0.2 h."""
    fields: dict[str, Any] = {
        "out": out,
        "workers": 1,
        "algorithms": ("ippo",),
        "scenarios": ("dahl2004",),
        "seeds": 1,
        "decisions": 300,
        "batch": 150,
        "curve_points": 1,
        "eval_seeds": 2,
        "episode_h": 0.2,
        "resamples": 100,
    }
    return study.Settings(**{**fields, **changes})


def test_a_tiny_run_trains_evaluates_reports_and_resumes_without_training(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    outcome = study.run(tiny(tmp_path))
    saved = json.loads((tmp_path / "runs" / "dahl2004__ippo__seed0.json").read_text())["result"]
    assert saved["decisions"] >= 300
    assert saved["curve"][0]["decisions"] == 0  # the untrained network first
    assert saved["curve"][-1]["decisions"] == saved["decisions"]
    assert len(saved["eval_values_per_h"]) == 2
    assert (tmp_path / "networks" / "dahl2004__ippo__seed0.npz").stat().st_size < 100_000
    for readout in ("sampled", "greedy"):  # the saved network read out both ways
        path = tmp_path / "readouts" / f"dahl2004__ippo__seed0__{readout}.json"
        assert len(json.loads(path.read_text())["result"]["eval_values_per_h"]) == 2
    assert "| tavc/dahl2004-v0 | ippo | 1 |" in outcome.text
    assert (tmp_path / "deep_leaderboard.csv").is_file()

    from tavc_agents.learners import torchrl_ppo

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("a saved run was trained again")

    monkeypatch.setattr(torchrl_ppo, "train", refuse)
    again = study.run(tiny(tmp_path))
    assert again.text == outcome.text


def test_the_smdp_route_trains_with_the_contract_ppo_and_resumes_without_training(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from tavc_agents.learners import smdp_ppo, torchrl_ppo

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("trained on the wrong route, or a saved run again")

    monkeypatch.setattr(torchrl_ppo, "train", refuse)
    settings = tiny(tmp_path, algorithms=("mappo",), route="smdp", n_envs=2, arena_steps=100)
    assert settings.reference_name() == "deep_leaderboard_smdp"
    ablation = tiny(tmp_path, route="smdp", discount="step", rows="all")
    assert ablation.reference_name() == "deep_leaderboard_smdp_per_step_all_rows"
    assert dict(ablation.ppo())["gamma_step"] == 0.99 and dict(ablation.ppo())["rows"] == "all"
    outcome = study.run(settings)
    saved = json.loads((tmp_path / "runs" / "dahl2004__mappo__seed0.json").read_text())
    assert saved["record"]["route"] == "smdp"
    assert dict(saved["record"]["ppo"])["steps_per_batch"] == 100
    result = saved["result"]
    assert result["decisions"] >= 300 and result["steps"] % 200 == 0
    assert result["curve"][0]["decisions"] == 0
    assert "semi-MDP contract's PPO" in outcome.text
    assert "| tavc/dahl2004-v0 | mappo | 1 |" in outcome.text
    monkeypatch.setattr(smdp_ppo, "train", refuse)
    assert study.run(settings).text == outcome.text


def test_another_entropy_bonus_is_a_search_run_in_a_folder_of_its_own(tmp_path: Path) -> None:
    from tavc_agents.learners import smdp_ppo

    assert smdp_ppo.PpoSettings().entropy == study.DEFAULT_ENTROPY  # the contract's runs' value
    assert "entropy" not in dict(tiny(tmp_path, route="smdp").ppo())
    search = tiny(tmp_path, route="smdp", entropy=0.03)
    assert search.reference_name() == "deep_leaderboard_smdp_entropy0.03"
    assert dict(search.ppo())["entropy"] == 0.03
    for bad in (-0.1, float("nan"), "0.1"):
        with pytest.raises(ValueError, match=r"entropy = .* is invalid; allowed: "):
            tiny(tmp_path, route="smdp", entropy=bad)
    with pytest.raises(ValueError, match=r"entropy = 0\.03 is invalid"):
        tiny(tmp_path, entropy=0.03)  # the pettingzoo route has its own learner


def test_per_class_parameters_are_saved_as_one_set_and_read_out(tmp_path: Path) -> None:
    from tavc_agents.learners.network import NetworkSet

    settings = tiny(
        tmp_path, algorithms=("mappo",), route="smdp", n_envs=2, arena_steps=100, parameters="class"
    )
    assert settings.reference_name() == "deep_leaderboard_smdp_per_class"
    assert dict(settings.ppo())["parameters"] == "class"
    assert "parameters" not in dict(tiny(tmp_path, route="smdp").ppo())  # the contract's record
    outcome = study.run(settings)
    saved = json.loads((tmp_path / "runs" / "dahl2004__mappo__seed0.json").read_text())
    assert dict(saved["record"]["ppo"])["parameters"] == "class"
    network = NetworkSet.load(tmp_path / "networks" / "dahl2004__mappo__seed0.npz")
    assert network.group_of is not None and len(network.mlps) >= 2
    for readout in ("sampled", "greedy"):
        path = tmp_path / "readouts" / f"dahl2004__mappo__seed0__{readout}.json"
        assert len(json.loads(path.read_text())["result"]["eval_values_per_h"]) == 2
    assert "one actor per speed class (ablation" in outcome.text


def test_team_credit_gives_every_robot_the_steps_mean_reward_and_trains(tmp_path: Path) -> None:
    from tavc_agents.learners import torchrl_ppo
    from tavc_env.scenarios import ScenarioEnv

    def rewards(credit: str) -> Any:
        env = ScenarioEnv("dahl2004", observation_mode="paper_id", reward="value")
        wrapped = torchrl_ppo.make_env(env, 0, 1e-3, credit)
        actions = wrapped.full_action_spec.zero()  # everyone on circuit 0: the same steps
        return wrapped.rollout(60, policy=lambda td: td.update(actions))["next", "robot", "reward"]

    own, team = rewards("own"), rewards("team")
    assert own.sum() > 0 and (own != own[..., :1, :]).any()  # deliveries, not all alike
    assert (team == own.mean(-2, keepdim=True)).all()
    outcome = study.run(tiny(tmp_path, credit="team"))
    assert "each robot on the team's" in outcome.text


def test_the_report_renders_with_no_run_saved(tmp_path: Path) -> None:
    outcome = study.run(tiny(tmp_path, max_jobs=0))
    assert "| tavc/dahl2004-v0 | ippo | 0 | 0 | - |" in outcome.text
    assert "(no run saved yet)" in outcome.text


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("algorithms", ("dqn",)),
        ("scenarios", ("nowhere",)),
        ("seeds", 0),
        ("decisions", 0),
        ("batch", 1),
        ("eval_seeds", 0),
        ("episode_h", -1.0),
        ("max_jobs", -1),
        ("credit", "shared"),
        ("route", "rllib"),
        ("gamma_h", 0.0),
        ("n_envs", 0),
        ("arena_steps", 1),
        ("discount", "linear"),
        ("rows", "some"),
        ("parameters", "team"),
        ("parameters", "class"),  # on the pettingzoo route
        ("references", Path("/nonexistent/references.json")),
    ],
)
def test_bad_settings_are_refused_by_name(tmp_path: Path, field: str, value: Any) -> None:
    with pytest.raises(ValueError, match=f"{field} = .* is invalid; allowed: "):
        tiny(tmp_path, **{field: value})
