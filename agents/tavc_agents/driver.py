"""Driving policies from an env's outputs: the bookkeeping between PettingZoo's step dicts and the
`Policy` protocol, shared by the trial runner and `tavc_agents.envs.single_robot.SingleRobotEnv`.

At every step, each agent whose info says `action_required` first learns from the task it chose
last time (if that task completed: a repaired robot abandoned its task and learns nothing from
it), then chooses the next circuit.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tavc_agents.policy import Policy
from tavc_env.env import completed_task_s


class PolicyDriver:
    """The actions of the agents in `policies` for one step, updating them as they go."""

    def __init__(self, policies: Mapping[str, Policy]) -> None:
        self.policies = dict(policies)
        self._pending: dict[str, tuple[np.ndarray, int]] = {}

    def actions(
        self,
        observations: Mapping[str, Mapping[str, np.ndarray]],
        rewards: Mapping[str, float],
        infos: Mapping[str, Mapping[str, Any]],
    ) -> dict[str, int]:
        """One action per driven agent that must decide now (in the order of `policies`)."""
        actions: dict[str, int] = {}
        for agent, policy in self.policies.items():
            info = infos[agent]
            if not info["action_required"]:
                continue
            seen = observations[agent]
            previous = self._pending.pop(agent, None)
            if previous is not None and completed_task_s(info) is not None:
                policy.update(
                    previous[0], previous[1], rewards[agent], seen["observation"], dict(info)
                )
            action = int(policy.act(seen["observation"], seen["action_mask"]))
            actions[agent] = action
            self._pending[agent] = (seen["observation"], action)
        return actions
