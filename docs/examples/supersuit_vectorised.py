"""Vectorise the arena with SuperSuit: every robot becomes one sub-environment of a Gymnasium
vector env, and several arenas are concatenated, the shape most single-agent RL libraries train on
(parameter sharing across robots).

    pip install supersuit
    python docs/examples/supersuit_vectorised.py
"""

from __future__ import annotations

import numpy as np
import supersuit as ss

import tavc_env


def make_vector_env(arenas: int = 2, hours: float = 1.0):
    env = tavc_env.parallel_env(preset="dahl2004", max_sim_time_s=hours * 3600.0)
    per_robot = ss.pettingzoo_env_to_vec_env_v1(env)  # 6 robots -> 6 sub-environments
    return ss.concat_vec_envs_v1(per_robot, arenas, num_cpus=0, base_class="gymnasium")


def run(steps: int = 200, seed: int = 0) -> dict[str, float]:
    """Random masked actions; returns the reward collected and how many steps ran."""
    venv = make_vector_env()
    rng = np.random.default_rng(seed)
    obs, _ = venv.reset(seed=seed)
    total = 0.0
    for _ in range(steps):
        # a robot may choose among the circuits its mask allows (busy robots: only their own)
        masks = obs["action_mask"]
        actions = np.array([rng.choice(np.flatnonzero(m)) for m in masks])
        obs, rewards, _, _, _ = venv.step(actions)
        total += float(np.sum(rewards))
    venv.close()
    return {"sub_envs": float(venv.num_envs), "steps": float(steps), "reward": total}


if __name__ == "__main__":
    print(run())
