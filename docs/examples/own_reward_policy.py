"""A PettingZoo-style policy of your own, scored on the scenario suite (docs/results/scenarios.md).

Each robot keeps, per circuit, the value it was paid per second of its own tasks there (the infos'
`task_value` / `task_time_s`), and picks the circuit where that rate is highest, exploring a random
one with probability 0.1. It sees its own infos only: no model, no other robot.

    tavc evaluate --policy docs/examples/own_reward_policy.py:policy --out my_row.json
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


class OwnRewardPolicy:
    def reset(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.rate: dict[str, np.ndarray] = {}

    def __call__(
        self, observations: Mapping[str, Any], infos: Mapping[str, Mapping[str, Any]]
    ) -> dict[str, int]:
        actions = {}
        for robot, info in infos.items():
            n = len(observations[robot]["action_mask"])  # the circuits
            rate = self.rate.setdefault(robot, np.full(n, np.inf))  # untried circuits first
            if info["task_completed"]:
                paid = info["task_value"] / info["task_time_s"]
                c = info["circuit"]
                rate[c] = paid if np.isinf(rate[c]) else 0.9 * rate[c] + 0.1 * paid
            if info["action_required"]:
                explore = self.rng.random() < 0.1
                actions[robot] = int(self.rng.integers(n) if explore else np.argmax(rate))
        return actions


policy = OwnRewardPolicy()
