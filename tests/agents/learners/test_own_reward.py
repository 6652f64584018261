"""The own-reward rate learner (`tavc_agents.learners.own_reward`): it learns the circuit of the
highest value per second (not the highest value per task), tracks a value change it observes, is
reproducible from its seed, and refuses bad settings and an observation it cannot read."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tavc_agents.experiments.registry import make_allocator, make_policy
from tavc_agents.experiments.runner import run_trial
from tavc_agents.learners.own_reward import OwnRewardLearner, OwnRewardParams, own_reward
from tavc_agents.policy import Policy

MASK2 = np.ones(2, np.int8)


def onehot(i: int, n: int = 2) -> np.ndarray:
    v = np.zeros(n, np.float32)
    v[i] = 1.0
    return v


def play(
    learner: Any, values: tuple[float, float], times: tuple[float, float], decisions: int, seed: int
) -> list[int]:
    """A two-circuit semi-MDP bandit: circuit c pays `values[c]` after about `times[c]` s (noisy)
    plus a 30-s transit when the robot switches. The actions chosen, in order."""
    noise = np.random.default_rng(seed + 1000)
    learner.reset(np.random.default_rng(seed), 2)
    obs, chosen = onehot(0), []
    for _ in range(decisions):
        a = learner.act(obs, MASK2)
        t = times[a] * noise.uniform(0.8, 1.2) + (30.0 if a != int(np.argmax(obs)) else 0.0)
        info = {"task_time_s": t, "task_value": values[a], "circuit": a}
        learner.update(obs, a, values[a] / t, onehot(a), info)
        obs = onehot(a)
        chosen.append(a)
    return chosen


def test_it_learns_the_higher_rate_not_the_higher_value_per_task() -> None:
    # circuit 1 pays more per task (3000 vs 2000) but less per second (15 vs 20 /s)
    ends_best = []
    for seed in range(20):
        chosen = play(own_reward(), (2000.0, 3000.0), (100.0, 200.0), 300, seed)
        ends_best.append(np.mean(np.array(chosen[-100:]) == 0))
    assert np.mean(ends_best) > 0.9  # random would be 0.5


def test_paid_values_track_a_priority_change_through_exploration() -> None:
    learner = own_reward(epsilon=0.1, recency=0.2)
    learner.reset(np.random.default_rng(0), 2)
    values = [4000.0, 1000.0]
    obs = onehot(0)
    late = []
    for k in range(600):
        if k == 300:
            values = [1000.0, 4000.0]  # the priorities swap
        a = learner.act(obs, MASK2)
        learner.update(obs, a, 0.0, onehot(a), {"task_time_s": 100.0, "task_value": values[a]})
        obs = onehot(a)
        if k >= 500:
            late.append(a)
    assert np.mean(np.array(late) == 1) > 0.85


def rich(last: int, values: tuple[float, ...]) -> np.ndarray:
    """A stand-in for the rich observation: 4 m + 7 + 2 entries, the values over their maximum
    last."""
    m = len(values)
    obs = np.zeros(4 * m + 9, np.float32)
    obs[last] = 1.0
    obs[-m:] = np.asarray(values) / max(values)
    return obs


def test_observed_values_switch_without_serving_the_other_circuit_again() -> None:
    learner = own_reward(epsilon=0.0, values="observed")
    learner.reset(np.random.default_rng(0), 2)
    for a in (0, 1):  # serve each once: equal task times
        learner.act(rich(a, (4000.0, 1000.0)), MASK2)
        learner.update(
            rich(a, (4000.0, 1000.0)), a, 0.0, rich(a, (4000, 1000)), {"task_time_s": 60.0}
        )
    assert learner.act(rich(0, (4000.0, 1000.0)), MASK2) == 0
    assert learner.act(rich(0, (1000.0, 4000.0)), MASK2) == 1  # seen in the observation


def test_observed_values_refuse_the_default_observation() -> None:
    learner = own_reward(values="observed")
    learner.reset(np.random.default_rng(0), 2)
    with pytest.raises(ValueError, match="observation_mode='rich'"):
        learner.act(onehot(0), MASK2)


def test_reproducible_from_its_seed() -> None:
    a = play(own_reward(), (2200.0, 2000.0), (100.0, 95.0), 200, seed=3)
    b = play(own_reward(), (2200.0, 2000.0), (100.0, 95.0), 200, seed=3)
    c = play(own_reward(), (2200.0, 2000.0), (100.0, 95.0), 200, seed=4)
    assert a == b and a != c


def test_a_short_trial_is_reproducible_and_registered() -> None:
    assert isinstance(make_policy("own_reward", epsilon=0.05), Policy)
    runs = [
        run_trial(
            make_allocator("own_reward"),
            arena={"scenario": "dahl2004"},
            seed=0,
            convergence_s=0.0,
            measured_s=900.0,
            snapshot_every_s=900.0,
        )
        for _ in range(2)
    ]
    assert runs[0].changes == runs[1].changes
    assert runs[0].delivery_time_s == runs[1].delivery_time_s and runs[0].delivery_time_s


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"epsilon": 1.5}, r"epsilon = 1.5 is invalid; allowed: a probability in \[0, 1\]"),
        ({"epsilon": float("nan")}, "epsilon = nan is invalid"),
        ({"recency": 0.0}, r"recency = 0.0 is invalid; allowed: a step size in \(0, 1\]"),
        ({"hysteresis": -0.1}, "hysteresis = -0.1 is invalid"),
        ({"values": "seen"}, r"values = 'seen' is invalid; allowed: one of \['paid', 'observed'\]"),
    ],
)
def test_refuses_bad_settings(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        OwnRewardParams(**kwargs)
    with pytest.raises(ValueError, match=message):
        make_policy("own_reward", **kwargs)


def test_used_before_reset_is_refused() -> None:
    with pytest.raises(ValueError, match="before reset"):
        OwnRewardLearner().act(onehot(0), MASK2)
