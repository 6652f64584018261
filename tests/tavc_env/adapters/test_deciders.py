"""The deciders-only (semi-Markov) view: who appears, what they are paid, and bad input."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_env.adapters.deciders import DecidersOnly
from tests.tavc_env.test_twin import tables_for


class PerRobotChoices:
    """Each robot's k-th choice drawn from its own generator: the same choices whichever view
    asks for them."""

    def __init__(self, env: Any, seed: int) -> None:
        m = env.config.n_circuits
        self.rngs = {a: np.random.default_rng([seed, i]) for i, a in enumerate(env.possible_agents)}
        self.m = m

    def __call__(self, agents: list[str]) -> dict[str, int]:
        return {a: int(self.rngs[a].integers(self.m)) for a in agents}


def _plain(seed: int, **kwargs: Any) -> tuple[dict[str, float], int, int]:
    env = tavc_env.parallel_env(**kwargs)
    choose = PerRobotChoices(env, seed)
    _, infos = env.reset(seed=seed)
    earned = dict.fromkeys(env.possible_agents, 0.0)
    decisions = rows = 0
    while env.agents:
        deciders = [a for a in env.agents if infos[a]["action_required"]]
        decisions += len(deciders)
        rows += len(env.agents)
        _, rewards, _, _, infos = env.step(choose(deciders))
        for a, r in rewards.items():
            earned[a] += r
    return earned, decisions, rows


def _deciders(seed: int, **kwargs: Any) -> tuple[dict[str, float], int, int]:
    view = DecidersOnly(tavc_env.parallel_env(**kwargs))
    choose = PerRobotChoices(view.env, seed)
    obs, infos = view.reset(seed=seed)
    earned = dict.fromkeys(view.possible_agents, 0.0)
    decisions = rows = 0
    last_decision = dict.fromkeys(view.possible_agents, 0.0)
    while True:
        assert set(obs) == set(infos) == set(view.agents)
        for a in view.agents:
            assert infos[a]["action_required"]
            assert view.observation_space(a).contains(obs[a])
            # the sojourn time: since this robot's previous decision
            assert infos[a]["elapsed_s"] == pytest.approx(infos[a]["sim_time_s"] - last_decision[a])
            last_decision[a] = infos[a]["sim_time_s"]
        decisions += len(view.agents)
        obs, rewards, terms, truncs, infos = view.step(choose(view.agents))
        rows += len(obs)
        for a, r in rewards.items():
            earned[a] += r
        if any(truncs.values()):
            assert set(truncs) == set(view.possible_agents) and all(truncs.values())
            assert not any(terms.values()) and view.agents == []
            return earned, decisions, rows


@pytest.mark.parametrize(
    "kwargs",
    [{"max_sim_time_s": 1800.0}, {"max_sim_time_s": 600.0, "decision_interval_s": 1.0}],
    ids=["event_driven", "every_second"],
)
def test_rewards_handed_out_add_up_to_the_plain_envs(kwargs: dict[str, Any]) -> None:
    plain, plain_decisions, plain_rows = _plain(11, **kwargs)
    semi, decisions, rows = _deciders(11, **kwargs)
    assert decisions == plain_decisions  # the same trajectory: the same decisions
    assert sum(plain.values()) > 0
    for a in plain:
        assert semi[a] == pytest.approx(plain[a], rel=1e-12, abs=1e-15)
    # the point of the view: far fewer rows than the plain env stores
    assert rows < plain_rows / 3


def test_only_deciders_may_act() -> None:
    view = DecidersOnly(tavc_env.parallel_env())
    view.reset(seed=0)
    view.step(dict.fromkeys(view.agents, 0))
    idle = sorted(set(view.possible_agents) - set(view.agents))[0]
    with pytest.raises(ValueError, match=rf"actions for \['{idle}'\] are invalid.*must decide"):
        view.step({idle: 1})
    with pytest.raises(ValueError, match="a tavc_env arena env"):
        DecidersOnly("tavc_arena_v1")  # type: ignore[arg-type]


def test_the_twin_has_the_same_view() -> None:
    env = tavc_env.twin_parallel_env(
        tables=tables_for(tavc_env.preset("dahl2004")), max_sim_time_s=900.0
    )
    view = DecidersOnly(env)
    obs, _ = view.reset(seed=3)
    steps = 0
    while view.agents:
        obs, *_ = view.step(dict.fromkeys(view.agents, 1))
        steps += 1
    assert steps > 5 and set(obs) == set(view.possible_agents)
