"""The TAVC robot: tabular Q-learning of task utilities with pluggable action selection.

Dahl, Mataric & Sukhatme (DARS 2004), section 4: the state is the circuit of the robot's last task,
the action the next circuit, the reward `w_i / t` (Equation 2); alpha 0.1, gamma 0.95, Q initialised
from U(-0.1, 0.1), epsilon 0.1 or softmax temperature 0.005, never decayed.

Two initialisations:

* ``"paper"``: Q from U(-0.1, 0.1), as printed. With rewards of about 0.03-0.05 (t in ms) and a
  softmax temperature of 0.005, the first choice in each state is greedy on the initial noise; the
  chosen entry then climbs toward r / (1 - gamma) (about 0.7) while the other stays where it
  started, so under softmax a robot can lock into its first choice (DESIGN.md section 3). Kept to
  measure exactly that.
* ``"scaled"``: every entry starts at the scale of the first observed return, `r0 / (1 - gamma)`,
  raised by `optimism` (relative) so untried actions look better than tried ones until tried, with
  relative noise `noise` far below any sensible temperature. Until the first reward all entries are
  equal (uniform choice).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from tavc_agents.learners.selection import EpsilonGreedy, Selection, Softmax, sample
from tavc_agents.policy import allowed_actions, generator, state_of

INITIALISATIONS = ("paper", "scaled")


@dataclass(frozen=True)
class TavcParams:
    """Learning parameters (defaults: the paper's) and the initialisation."""

    alpha: float = 0.1
    gamma: float = 0.95
    init: str = "scaled"
    init_range: float = 0.1
    optimism: float = 0.05
    noise: float = 1e-4

    def __post_init__(self) -> None:
        checks = {
            "alpha": (0 < self.alpha <= 1, "a learning rate in (0, 1]"),
            "gamma": (0 <= self.gamma < 1, "a discount in [0, 1)"),
            "init": (self.init in INITIALISATIONS, f"one of {list(INITIALISATIONS)}"),
            "init_range": (self.init_range >= 0, "a half-width >= 0"),
            "optimism": (self.optimism >= 0, "a relative optimism >= 0"),
            "noise": (0 <= self.noise < 0.01, "a relative noise in [0, 0.01)"),
        }
        for name, (ok, allowed) in checks.items():
            if not ok:
                raise ValueError(f"{name} = {getattr(self, name)!r} is invalid; allowed: {allowed}")

    def scaled_level(self, reward: Any) -> Any:
        """The level the `scaled` initialisation gives every Q entry from a first reward (a
        number or an array of them): its return at that rate, r / (1 - gamma), times
        (1 + optimism)."""
        return reward / (1.0 - self.gamma) * (1.0 + self.optimism)


class TavcLearner:
    """One robot's TAVC Q-learner (implements `tavc_agents.policy.Policy`)."""

    def __init__(self, selection: Selection, params: TavcParams | None = None) -> None:
        self.selection = selection
        self.params = params if params is not None else TavcParams()
        self.q = np.zeros((0, 0))
        self.updates = np.zeros((0, 0), dtype=np.int64)
        self.choices = 0
        self.non_greedy_choices = 0
        self._rng: np.random.Generator | None = None
        self._scaled_pending = False

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        self._rng = rng
        p = self.params
        if p.init == "paper":
            self.q = rng.uniform(-p.init_range, p.init_range, size=(n_actions, n_actions))
        else:
            self.q = np.zeros((n_actions, n_actions))
        self._scaled_pending = p.init == "scaled"
        self.updates = np.zeros((n_actions, n_actions), dtype=np.int64)
        self.choices = 0
        self.non_greedy_choices = 0

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        rng = generator(self._rng, self)
        s = state_of(observation)
        row = self.q[s]
        action = sample(self.selection.probabilities(row, action_mask), rng)
        allowed = allowed_actions(action_mask)
        self.choices += 1
        if row[action] < row[allowed].max():
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
        p = self.params
        if self._scaled_pending:
            level = p.scaled_level(reward)
            jitter = generator(self._rng, self).uniform(-p.noise, p.noise, size=self.q.shape)
            self.q = level * (1.0 + jitter)
            self._scaled_pending = False
        s, s_next = state_of(observation), state_of(next_observation)
        target = reward + p.gamma * self.q[s_next].max()
        self.q[s, action] += p.alpha * (target - self.q[s, action])
        self.updates[s, action] += 1

    @property
    def q_table(self) -> np.ndarray:
        return self.q.copy()


def softmax_tavc(temperature: float = 0.005, init: str = "scaled") -> TavcLearner:
    """The paper's modified TAVC robot (Boltzmann softmax selection)."""
    return TavcLearner(Softmax(temperature), TavcParams(init=init))


def epsilon_tavc(epsilon: float = 0.1, init: str = "scaled") -> TavcLearner:
    """The original TAVC robot (Greedy-epsilon selection)."""
    return TavcLearner(EpsilonGreedy(epsilon), TavcParams(init=init))
