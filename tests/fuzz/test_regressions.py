"""Defects the fuzzing harness found, each pinned by a deterministic test (fails before its fix).

1. A crash (segmentation fault or abort in cpSpaceRemoveBody) when an arena's World was dropped:
   the World dies by reference count (an env's reset replaces it) and pymunk frees its space at
   once, walking the bodies still in it; pymunk's bodies live in reference cycles, so a garbage
   collection during that walk freed bodies the walk then visited. The fuzzer met it as a crash
   of the whole test process, depending on when collections happened; here a collection is forced
   inside the walk. Fixed in `World.__del__` (everything leaves the space first).
2. `reward_time_unit=["ms"]` raised a TypeError (unhashable) instead of a ValueError.
3. `jam_window_s=True` was accepted as a 1 s window, and `jam_window_s=np.int64(600)` refused.
4. `SingleRobotEnv(max_sim_time_s=...)` raised a TypeError (the argument is set from `episode_s`),
   and a non-callable `others` was accepted and failed with a TypeError at the first reset.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import tavc_env
from tavc_agents.envs.single_robot import SingleRobotEnv

COLLECT_DURING_SPACEFREE = textwrap.dedent(
    """
    import gc
    import pymunk.space
    import tavc_env
    from tavc_env.engine.world import World

    real = pymunk.space.lib

    class CollectingLib:
        # pymunk's C library, running a garbage collection each time pymunk's space finaliser asks
        # a body for its space (what any allocation in that loop may do)
        def __getattr__(self, name):
            attr = getattr(real, name)
            if name != "cpBodyGetSpace":
                return attr

            def get_space(body):
                gc.collect()
                return attr(body)

            return get_space

    config = tavc_env.make_config("dahl2004")
    for broken in (False, True):
        world = World(config)
        if broken:
            world.remove_robot(2)
        pymunk.space.lib = CollectingLib()
        try:
            del world
        finally:
            pymunk.space.lib = real
    env = tavc_env.parallel_env()
    env.reset(seed=0)
    pymunk.space.lib = CollectingLib()
    try:
        env.reset(seed=1)  # the first episode's World dies here
    finally:
        pymunk.space.lib = real
    print("ok")
    """
)


def test_dropping_a_world_survives_a_garbage_collection_inside_pymunks_space_finaliser() -> None:
    done = subprocess.run(
        [sys.executable, "-c", COLLECT_DURING_SPACEFREE],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0 and done.stdout.strip() == "ok", (
        f"exit {done.returncode} (-11: segmentation fault, -6: abort)\n{done.stderr[-2000:]}"
    )


@pytest.mark.parametrize("unit", [["ms"], {"ms": 1}, None, 1000.0])
def test_an_unhashable_or_non_text_reward_unit_is_a_value_error(unit: object) -> None:
    with pytest.raises(ValueError, match=r"^reward_time_unit = .* is invalid; allowed: "):
        tavc_env.parallel_env(reward_time_unit=unit)


@pytest.mark.parametrize("window", [True, False, np.True_, 0, -5.0, float("nan"), "600", None])
def test_the_jam_window_refuses_bools_and_non_durations(window: object) -> None:
    with pytest.raises(ValueError, match=r"^jam_window_s = .* is invalid; allowed: "):
        tavc_env.parallel_env(jam_window_s=window)


@pytest.mark.parametrize("window", [np.int64(600), np.float32(300.0), 450, float("inf")])
def test_the_jam_window_takes_numpy_numbers_and_infinity(window: object) -> None:
    env = tavc_env.parallel_env(jam_window_s=window)
    assert env.sim.jam_window_s == float(window)
    env.reset(seed=0)


def test_single_robot_env_refuses_max_sim_time_and_non_callable_others() -> None:
    with pytest.raises(ValueError, match=r"^max_sim_time_s = 100\.0 is invalid; allowed: "):
        SingleRobotEnv(max_sim_time_s=100.0)
    with pytest.raises(ValueError, match=r"^others = 5 is invalid; allowed: "):
        SingleRobotEnv(others=5)  # type: ignore[arg-type]
