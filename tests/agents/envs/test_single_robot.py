"""`SingleRobotEnv`: one robot of the arena as a Gymnasium env. Gymnasium's own checker passes;
one step is one of the learner's tasks, paid `w / t`; the other robots keep working under their
own policies; same seed, same episode; bad actions are refused."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from tavc_agents.allocators.baselines import FixedAllocator, RandomAllocator
from tavc_agents.envs.single_robot import SingleRobotEnv
from tavc_env import completed_task_s


def episode(env: SingleRobotEnv, seed: int, policy: list[int]) -> list[tuple[float, float]]:
    env.reset(seed=seed)
    out = []
    for k in range(len(policy)):
        _, reward, terminated, truncated, info = env.step(policy[k])
        out.append((reward, info["sim_time_s"]))
        if terminated or truncated:
            break
    return out


def test_gymnasium_checker_passes() -> None:
    check_env(SingleRobotEnv(episode_s=900.0), skip_render_check=True)


def test_a_step_is_one_task_paid_w_over_t() -> None:
    env = SingleRobotEnv(episode_s=3600.0, others=lambda agent: FixedAllocator(1))
    obs, info = env.reset(seed=0)
    assert info["action_required"] and obs.shape == (2,)
    for _ in range(5):
        obs, reward, terminated, truncated, info = env.step(0)
        assert not terminated and not truncated
        assert info["action_required"] and completed_task_s(info) is not None
        assert reward == pytest.approx(2200.0 / (info["task_time_s"] * 1000.0))
        assert obs.tolist() == [1.0, 0.0]  # its last circuit: the one it served


def test_other_robots_work_meanwhile_and_episodes_end() -> None:
    env = SingleRobotEnv(episode_s=1800.0, others=lambda agent: RandomAllocator())
    env.reset(seed=1)
    completed = env.env.sim.tasks.completed
    steps = 0
    truncated = False
    while not truncated:
        _, _, _, truncated, _ = env.step(1)
        steps += 1
    assert 5 < steps < 60
    assert completed[1:].sum() > completed[0]  # five others delivered more than the learner


def test_same_seed_same_episode_and_bad_actions() -> None:
    env = SingleRobotEnv(episode_s=1800.0)
    plan = [0, 1, 1, 0, 1, 0, 0, 1, 0, 1]
    assert episode(env, 3, plan) == episode(env, 3, plan)
    assert episode(env, 3, plan) != episode(env, 4, plan)
    env.reset(seed=0)
    with pytest.raises(
        ValueError, match=r"action = 2 is invalid; allowed: a circuit index in \[0, 1\]"
    ):
        env.step(2)
    with pytest.raises(ValueError, match="robot = 'robot_9' is invalid"):
        SingleRobotEnv(robot="robot_9")
    with pytest.raises(ValueError, match="episode_s = 0 is invalid"):
        SingleRobotEnv(episode_s=0)
    assert np.array_equal(env.observation_space.high, np.ones(2, np.float32))
