"""A decentralised, model-free own-reward learner built for the suite's metric: value per unit time.

Each robot sees only its own observation, its own infos and its own tasks. A decision is a
semi-MDP step: the robot picks a circuit, and the task ends `task_time_s` later (travel to it
included when it switched) paying `task_value` (the circuit's value `w` at delivery, the env's
`reward="value"` semantics, read from the infos whatever reward the env pays). The suite scores the
delivered value per hour, a *rate*; by the renewal-reward theorem the long-run rate of serving
circuit c is `E[w_c] / E[t_c]`, so the learner keeps, per circuit,

* the value it was last paid there (`w` is exact, not noisy; it changes only when the circuit's
  priority changes), or, with ``values="observed"``, the circuits' current values read from the
  `rich` observation (its last `n_actions` entries, the values over their maximum: only ratios
  matter), which also covers the circuits it is not serving;
* an exponentially recency-weighted mean of its own task time there (step size `recency`, the
  first task setting it outright), so it tracks congestion as the other robots move, breakdowns
  and repairs;

and picks the circuit of highest rate `w_c / t_c`: a rate-maximising (average-reward) bandit over
circuits, not a discounted Q-learner. Circuits it never served have an optimistic, infinite rate,
so each is tried once (ties broken at random); with probability `epsilon` it serves a uniformly
drawn allowed circuit instead, so its estimates of the others stay fresh under non-stationarity.
Switching costs a transit, paid in the next task's time: the robot leaves the circuit it is on
only for a rate more than `hysteresis` (relative) higher, so that noise alone does not make it
shuttle between circuits of about equal rate.

It differs from TAVC (`tavc_agents.learners.tavc`) in what it maximises: TAVC's Q-learning sums
`w / t` per decision with per-decision discounting, which weights a short task like a long one;
the rate `sum w / sum t` this learner maximises is the metric's own (docs/results/scenarios.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from tavc_agents.policy import allowed_actions, generator, state_of

VALUE_SOURCES = ("paid", "observed")


@dataclass(frozen=True)
class OwnRewardParams:
    """The learner's settings. The defaults are those `benchmarks/own_reward_search.py` chose on
    the scenarios' training seeds 0-2 (benchmarks/results/own_reward_search/: the best of 12 by
    mean normalised score); `values="observed"` needs the env's `rich` observation."""

    epsilon: float = 0.03
    recency: float = 0.2
    hysteresis: float = 0.0
    values: str = "paid"

    def __post_init__(self) -> None:
        checks = {
            "epsilon": (
                _number(self.epsilon) and 0 <= self.epsilon <= 1,
                "a probability in [0, 1]",
            ),
            "recency": (_number(self.recency) and 0 < self.recency <= 1, "a step size in (0, 1]"),
            "hysteresis": (
                _number(self.hysteresis) and 0 <= self.hysteresis < 10,
                "a relative margin in [0, 10)",
            ),
            "values": (self.values in VALUE_SOURCES, f"one of {list(VALUE_SOURCES)}"),
        }
        for name, (ok, allowed) in checks.items():
            if not ok:
                raise ValueError(f"{name} = {getattr(self, name)!r} is invalid; allowed: {allowed}")


def _number(x: object) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


class OwnRewardLearner:
    """One robot's own-reward rate learner (implements `tavc_agents.policy.Policy`)."""

    def __init__(self, params: OwnRewardParams | None = None) -> None:
        self.params = params if params is not None else OwnRewardParams()
        self.value = np.zeros(0)  # w per circuit: last paid (NaN: never served) or observed
        self.time_s = np.zeros(0)  # recency-weighted mean task time per circuit (NaN: never)
        self.updates = np.zeros(0, dtype=np.int64)
        self.choices = 0
        self.non_greedy_choices = 0
        self._rng: np.random.Generator | None = None

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        self._rng = rng
        self.value = np.full(n_actions, np.nan)
        self.time_s = np.full(n_actions, np.nan)
        self.updates = np.zeros(n_actions, dtype=np.int64)
        self.choices = 0
        self.non_greedy_choices = 0

    def rates(self, current: int | None = None) -> np.ndarray:
        """Each circuit's estimated value per second (inf: never served); the circuit the robot is
        on (`current`) raised by the hysteresis margin."""
        with np.errstate(invalid="ignore"):
            rate = np.where(np.isnan(self.time_s), np.inf, self.value / self.time_s)
        if current is not None and np.isfinite(rate[current]):
            rate[current] *= 1.0 + self.params.hysteresis
        return rate

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        rng = generator(self._rng, self)
        allowed = allowed_actions(action_mask)
        if self.params.values == "observed":
            self.value = observed_values(observation, self.value.size)
        rate = self.rates(state_of(observation))[allowed]
        best = allowed[rate == rate.max()]
        self.choices += 1
        if rng.random() < self.params.epsilon:
            action = int(rng.choice(allowed))
        else:
            action = int(best[0] if best.size == 1 else rng.choice(best))
        if action not in best:
            self.non_greedy_choices += 1
        return action

    def update(
        self,
        observation: np.ndarray,
        action: int,
        reward: float,
        next_observation: np.ndarray,
        info: dict[str, Any],
    ) -> None:
        """Learn from the task on `action` that just completed: its time and value from `info`
        (`reward`, whatever the env's reward mode, is not used)."""
        t = float(info["task_time_s"])
        if not t > 0:
            return
        if self.params.values == "paid":
            self.value[action] = float(info["task_value"])
        old = self.time_s[action]
        self.time_s[action] = t if np.isnan(old) else old + self.params.recency * (t - old)
        self.updates[action] += 1


def observed_values(observation: np.ndarray, n_actions: int) -> np.ndarray:
    """The circuits' current values over their maximum: the last `n_actions` entries of the
    `rich` observation (`tavc_env.observations`); a ValueError for any other observation."""
    obs = np.asarray(observation, dtype=float).ravel()
    values = obs[-n_actions:]
    if obs.size < 4 * n_actions + 7 or values.min() <= 0 or not np.isclose(values.max(), 1.0):
        raise ValueError(
            f"values = 'observed' reads the circuits' values from the observation, and this one "
            f"(size {obs.size}) does not end with them; allowed: the env's "
            "observation_mode='rich', or values='paid'"
        )
    return values


def own_reward(
    epsilon: float = OwnRewardParams.epsilon,
    recency: float = OwnRewardParams.recency,
    hysteresis: float = OwnRewardParams.hysteresis,
    values: str = OwnRewardParams.values,
) -> OwnRewardLearner:
    """A robot's own-reward rate learner (the allocator `own_reward`)."""
    return OwnRewardLearner(OwnRewardParams(epsilon, recency, hysteresis, values))
