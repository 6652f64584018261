"""`import tavc_env` alone registers the single-robot view's Gymnasium ids (issue 28, item 3):
Gymnasium 1.x has no plugin discovery, so the ids are registered from `tavc_env` with an
entry-point string (no import of `tavc_agents` until an env is made), and registering again from
`tavc_agents.envs` is silent."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import gymnasium

from tavc_env.registration import SINGLE_ROBOT_ENTRY_POINT, SINGLE_ROBOT_IDS
from tavc_env.scenarios import SCENARIOS


def _fresh(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-W", "error", "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_gymnasium_make_works_after_import_tavc_env_alone() -> None:
    done = _fresh(
        """
        import sys
        import gymnasium
        import tavc_env
        assert "tavc_agents" not in sys.modules, "tavc_env imported tavc_agents"
        env = gymnasium.make("tavc/dahl2004-v0", episode_s=600.0)
        observation, info = env.reset(seed=0)
        env.step(0)
        print(type(env.unwrapped).__name__, observation.shape)
        """
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["SingleRobotEnv", "(2,)"]


def test_registering_from_both_packages_is_silent_in_either_order() -> None:
    for first, second in (("tavc_env", "tavc_agents.envs"), ("tavc_agents.envs", "tavc_env")):
        done = _fresh(
            f"""
            import warnings
            warnings.simplefilter("error")
            import {first}
            import {second}
            from tavc_env.registration import register, SINGLE_ROBOT_IDS
            register()
            import gymnasium
            assert all(i in gymnasium.registry for i in SINGLE_ROBOT_IDS)
            """
        )
        assert done.returncode == 0, done.stderr
        assert done.stderr == ""


def test_every_scenario_has_an_id_naming_the_single_robot_view() -> None:
    assert {s.id for s in SCENARIOS.values()} == set(SINGLE_ROBOT_IDS)
    for env_id, kwargs in SINGLE_ROBOT_IDS.items():
        spec = gymnasium.spec(env_id)
        assert spec.entry_point == SINGLE_ROBOT_ENTRY_POINT
        assert spec.kwargs == dict(kwargs)
