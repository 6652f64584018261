"""The `agent_names` option: robots named by index (`robot_i`, the default) or by speed class
(`fast_0`, ...), so that libraries that group agents by name prefix (TorchRL, BenchMARL) make one
group per class. Either way agent `i` is robot `i` and the env behaves the same."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test

import tavc_env
from tavc_env import EnvOptions
from tavc_env.adapters.deciders import DecidersOnly
from tavc_env.config import Robot
from tests.helpers import seed_spaces


def test_default_names_are_by_index_and_speed_class_names_count_within_each_class() -> None:
    assert EnvOptions().agent_names == "index"
    assert tavc_env.parallel_env().possible_agents == [f"robot_{i}" for i in range(6)]
    env = tavc_env.parallel_env(agent_names="speed_class")
    assert env.possible_agents == ["fast_0", "fast_1", "fast_2", "slow_0", "slow_1", "slow_2"]
    # classes interleaved: numbered in robot order within each class
    mixed = tavc_env.parallel_env(speeds=[0.3, 0.2, 0.3, 0.2, 0.25], agent_names="speed_class")
    assert mixed.possible_agents == ["fast_0", "slow_0", "fast_1", "slow_1", "medium_0"]


def test_the_env_is_the_same_under_either_naming() -> None:
    plain = tavc_env.parallel_env(observation_mode="rich")
    named = tavc_env.parallel_env(observation_mode="rich", agent_names="speed_class")
    obs_a, infos_a = plain.reset(seed=3)
    obs_b, infos_b = named.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(40):
        for a, b in zip(plain.possible_agents, named.possible_agents):
            np.testing.assert_array_equal(obs_a[a]["observation"], obs_b[b]["observation"])
            np.testing.assert_array_equal(obs_a[a]["action_mask"], obs_b[b]["action_mask"])
            assert infos_a[a] == infos_b[b]
        choices = rng.integers(2, size=6)
        obs_a, rew_a, _, _, infos_a = plain.step({a: int(c) for a, c in zip(plain.agents, choices)})
        obs_b, rew_b, _, _, infos_b = named.step({b: int(c) for b, c in zip(named.agents, choices)})
        assert list(rew_a.values()) == list(rew_b.values())


def test_the_pettingzoo_checkers_pass_with_class_names() -> None:
    env = tavc_env.parallel_env(agent_names="speed_class")
    env.reset(seed=1)
    parallel_api_test(seed_spaces(env, 7), num_cycles=30)
    aec = tavc_env.env(agent_names="speed_class")
    aec.reset(seed=1)
    api_test(seed_spaces(aec, 7), num_cycles=30)


def test_the_deciders_view_and_bad_keys_use_the_class_names() -> None:
    env = tavc_env.parallel_env(agent_names="speed_class")
    view = DecidersOnly(env)
    obs, _ = view.reset(seed=0)
    assert set(obs) <= set(env.possible_agents) and obs
    with pytest.raises(ValueError, match=r"robot_0' is unknown; allowed: \['fast_0'"):
        env.step({"robot_0": 0})


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"agent_names": "class"}, r"^agent_names = 'class' is invalid; allowed: \['index', "),
        (
            {"agent_names": "speed_class", "robots": (Robot(0.3), Robot(0.2))},
            r"^agent_names = 'speed_class' is invalid; .*robots\[0\]\.speed_class is ''",
        ),
        (
            {"agent_names": "speed_class", "robots": (Robot(0.3, "very_fast"), Robot(0.2, "s"))},
            r"no '_'.*robots\[0\]\.speed_class is 'very_fast'",
        ),
    ],
)
def test_a_bad_naming_is_refused_naming_the_option(kwargs: dict[str, object], pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        tavc_env.parallel_env(**kwargs)
