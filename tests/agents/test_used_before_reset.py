"""Nothing runs on a placeholder seed: a policy, a team or a simulation used before `reset` says
so, instead of silently drawing from some default generator."""

from __future__ import annotations

import numpy as np
import pytest

from tavc_agents.allocators.baselines import RandomAllocator
from tavc_agents.allocators.threshold import ResponseThresholdAllocator
from tavc_agents.learners.tavc import epsilon_tavc, softmax_tavc
from tavc_env import make_config
from tavc_env.engine.simulation import Simulation

MASK = np.ones(2, dtype=np.int8)
OBS = np.array([1.0, 0.0], dtype=np.float32)


@pytest.mark.parametrize("make", [softmax_tavc, epsilon_tavc, RandomAllocator])
def test_a_policy_used_before_reset_raises(make) -> None:
    policy = make()
    with pytest.raises(ValueError, match="used before reset"):
        policy.act(OBS, MASK)
    policy.reset(np.random.default_rng(0), 2)
    assert policy.act(OBS, MASK) in (0, 1)


def test_a_team_member_used_before_reset_raises() -> None:
    config = make_config("dahl2004")
    team = ResponseThresholdAllocator()
    members = team.policies([f"robot_{i}" for i in range(config.n_robots)], config)
    team.observe({}, [c.value for c in config.circuits])
    with pytest.raises(ValueError, match="used before reset"):
        members["robot_0"].act(OBS, MASK)


def test_a_simulation_used_before_reset_raises() -> None:
    sim = Simulation(make_config("dahl2004"))
    with pytest.raises(ValueError, match="reset"):
        sim.advance(1.0)
    with pytest.raises(ValueError, match="reset"):
        sim.choose(0, 0)
    with pytest.raises(ValueError, match="rng = 0 is invalid"):
        sim.reset(0)  # type: ignore[arg-type]
    sim.reset(np.random.default_rng(0))
    assert sim.advance(1.0).duration_s == pytest.approx(1.0)
