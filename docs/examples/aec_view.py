"""The AEC view: robots act one at a time through PettingZoo's `agent_iter` loop (the parallel env
converted by PettingZoo's own `parallel_to_aec`), and back to parallel with `aec_to_parallel`.

    python docs/examples/aec_view.py
"""

from __future__ import annotations

import numpy as np
from pettingzoo.utils.conversions import aec_to_parallel

import tavc_env


def run_aec(hours: float = 0.5, seed: int = 0) -> dict[str, float]:
    """Random masked choices in the AEC loop; returns the rewards summed per agent."""
    env = tavc_env.env(preset="dahl2004", max_sim_time_s=hours * 3600.0)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    totals = dict.fromkeys(env.possible_agents, 0.0)
    for agent in env.agent_iter():
        observation, reward, termination, truncation, _ = env.last()
        totals[agent] += reward
        if termination or truncation:
            action = None
        else:
            action = int(rng.choice(np.flatnonzero(observation["action_mask"])))
        env.step(action)
    env.close()
    return totals


def round_trip_agents() -> list[str]:
    """AEC -> parallel again: the same agents, a working parallel API."""
    parallel = aec_to_parallel(tavc_env.env(preset="dahl2004", max_sim_time_s=600.0))
    parallel.reset(seed=1)
    return list(parallel.agents)


if __name__ == "__main__":
    print(run_aec())
    print(round_trip_agents())
