"""Fuzzing action streams: valid, invalid and masked actions, None, floats, numpy integers, missing
agents and unknown keys. A step either runs (every deciding robot got a valid action, nothing
unknown) or raises a ValueError and changes nothing; the AEC view agrees with the parallel view
step for step; `SingleRobotEnv` takes integers only."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import tavc_env
from tavc_agents.envs.single_robot import SingleRobotEnv
from tavc_env.config import ArenaConfig
from tavc_env.env import _arena_digest
from tests.fuzz.strategies import (
    bad_actions,
    build_actions,
    fuzz_settings,
    integer_like,
    is_valid_action,
    plan_is_valid,
    step_plans,
    valid_config,
)


def _fingerprint(env: tavc_env.TavcArenaEnv) -> tuple[Any, ...]:
    return (_arena_digest(env.sim), env.num_cycles, tuple(env.agents), env.delivered_value)


@fuzz_settings(30)
@given(
    config=valid_config(),
    seed=st.integers(0, 2**32 - 1),
    per_step=st.sampled_from([1, 5, 20]),
    data=st.data(),
)
def test_a_step_runs_or_refuses_and_changes_nothing(
    config: ArenaConfig, seed: int, per_step: int, data: st.DataObject
) -> None:
    env = tavc_env.parallel_env(config=config, decision_interval_s=per_step * config.dt)
    _, infos = env.reset(seed=seed)
    m = config.n_circuits
    plans = data.draw(st.lists(step_plans(m), min_size=5, max_size=25), label="plans")
    for k, plan in enumerate(plans):
        deciding = [a for a in env.agents if infos[a]["action_required"]]
        idle = [a for a in env.agents if not infos[a]["action_required"]]
        actions = build_actions(plan, deciding, idle)
        before = _fingerprint(env)
        if plan_is_valid(plan, deciding, m):
            _, rewards, _, _, infos = env.step(actions)
            assert set(rewards) <= set(env.possible_agents)
        else:
            with pytest.raises(
                ValueError, match=r"is invalid; allowed: |is unknown; allowed|^missing action for"
            ):
                env.step(actions)
            assert _fingerprint(env) == before, f"step {k}: a refused step changed the env"
            # the same step with the bad parts mended goes through
            mended = {a: 0 for a in deciding}
            _, _, _, _, infos = env.step(mended)


@fuzz_settings(30)
@given(
    config=valid_config(),
    seed=st.integers(0, 2**32 - 1),
    per_step=st.sampled_from([1, 7, 30]),
    data=st.data(),
)
def test_the_aec_and_parallel_views_agree_step_for_step(
    config: ArenaConfig, seed: int, per_step: int, data: st.DataObject
) -> None:
    """The same decisions through both views (the AEC view also gets a bad action first at some
    deciding agents, which it must refuse at once, changing nothing); after every cycle the
    rewards, infos, terminations, truncations, observations and positions agree."""
    kwargs: dict[str, Any] = {
        "config": config,
        "decision_interval_s": per_step * config.dt,
        "max_cycles": 40,
    }
    par = tavc_env.parallel_env(**kwargs)
    aec = tavc_env.env(**kwargs)
    obs, infos = par.reset(seed=seed)
    aec.reset(seed=seed)
    m = config.n_circuits
    cycles = data.draw(st.integers(1, 40), label="cycles")
    for cycle in range(cycles):
        if not par.agents:
            break
        deciding = {a for a in par.agents if infos[a]["action_required"]}
        good = {a: data.draw(integer_like(0, m - 1)) for a in sorted(deciding)}
        bad = {a: data.draw(st.none() | bad_actions(m)) for a in sorted(deciding)}
        idle = {a: data.draw(st.none() | bad_actions(m)) for a in par.agents if a not in deciding}
        for agent in par.agents:  # the AEC cycle, in the same order
            assert aec.agent_selection == agent
            if agent in deciding:
                if bad[agent] is not None:
                    with pytest.raises(ValueError, match=rf"action of {agent} = "):
                        aec.step(bad[agent])
                    assert aec.agent_selection == agent
                aec.step(good[agent])
            else:
                aec.step(idle[agent])  # ignored, whatever it is
        obs, rewards, terms, truncs, infos = par.step({**idle, **good})
        where = f"cycle {cycle}"
        assert aec.rewards == rewards, where
        assert aec.infos == infos, where
        assert aec.terminations == terms and aec.truncations == truncs, where
        for agent, ob in obs.items():
            seen = aec.observe(agent)
            for key in ("observation", "action_mask"):
                assert np.array_equal(seen[key], ob[key]), where
        assert np.array_equal(aec.unwrapped.sim.positions(), par.sim.positions()), where


@fuzz_settings(20)
@given(
    actions=st.lists(st.one_of(integer_like(-2, 3), bad_actions(2)), min_size=1, max_size=6),
    seed=st.integers(0, 2**32 - 1),
)
def test_single_robot_env_takes_integer_actions_only(actions: list[Any], seed: int) -> None:
    env = SingleRobotEnv(episode_s=600.0)
    env.reset(seed=seed)
    for action in actions:
        if is_valid_action(action, 2):
            _, reward, _, truncated, _ = env.step(action)
            assert reward >= 0
            if truncated:
                env.reset(seed=seed)
        else:
            with pytest.raises(ValueError, match=r"^action = "):
                env.step(action)
