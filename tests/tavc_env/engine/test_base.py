"""What the engines share (`tavc_env.engine.base`): the schedule of breakdowns and repairs, written
once, and the `Engine` protocol the env drives, which the physics and the twin both implement."""

from __future__ import annotations

import pytest

import tavc_env
from tavc_env.engine.base import (
    Advance,
    Scheduled,
    ScheduleEntry,
    add_repair,
    breakdown_schedule,
    next_due_s,
    run_due,
    without_repairs,
)
from tavc_env.engine.simulation import Simulation
from tavc_env.env import ArenaEnv, TavcArenaEnv
from tavc_env.twin import InterferenceTables, TaskTimeProcess, TwinArenaEnv


class Robots:
    """A stand-in engine: which robots are broken, and what was done to them."""

    def __init__(self, n: int) -> None:
        self.down = [False] * n
        self.log: list[tuple[str, int]] = []

    def is_broken(self, robot: int) -> bool:
        return self.down[robot]

    def break_down(self, robot: int) -> None:
        self.down[robot] = True
        self.log.append(("break_down", robot))

    def repair(self, robot: int) -> None:
        self.down[robot] = False
        self.log.append(("repair", robot))


def test_the_schedule_runs_due_entries_in_order_and_schedules_repairs() -> None:
    config = tavc_env.make_config(
        breakdowns=(
            tavc_env.Breakdown(robot=2, at_s=50.0, repair_after_s=30.0),
            tavc_env.Breakdown(robot=1, at_s=10.0),
        )
    )
    schedule = breakdown_schedule(config)
    assert schedule == [
        ScheduleEntry(10.0, Scheduled.BREAK_DOWN, 1, -1.0),
        ScheduleEntry(50.0, Scheduled.BREAK_DOWN, 2, 30.0),
    ]
    robots, out = Robots(3), Advance()
    run_due(schedule, 9.0, robots, out)
    assert robots.log == [] and next_due_s(schedule) == 10.0
    run_due(schedule, 50.0 - 1e-10, robots, out)  # due within the tolerance
    assert robots.log == [("break_down", 1), ("break_down", 2)]
    assert (out.broken, out.repaired) == ([1, 2], [])
    assert schedule == [ScheduleEntry(80.0 - 1e-10, Scheduled.REPAIR, 2)]
    run_due(schedule, 80.0, robots, out)
    assert robots.log[-1] == ("repair", 2) and out.repaired == [2]
    assert next_due_s(schedule) == float("inf")


def test_a_repair_of_a_robot_that_is_not_broken_and_stale_repairs_do_nothing() -> None:
    schedule: list[ScheduleEntry] = []
    add_repair(schedule, 20.0, 0)
    add_repair(schedule, 5.0, 1)
    add_repair(schedule, 30.0, 0)
    assert [e.at_s for e in schedule] == [5.0, 20.0, 30.0]
    assert without_repairs(schedule, 0) == [ScheduleEntry(5.0, Scheduled.REPAIR, 1)]
    robots, out = Robots(2), Advance()
    run_due(schedule, 100.0, robots, out)  # nobody is broken: every repair is dropped
    assert robots.log == [] and out.repaired == [] and schedule == []


def tables(config: tavc_env.ArenaConfig) -> InterferenceTables:
    return InterferenceTables.from_function(config, 60.0, 5.0, 1.2)


def test_the_twin_builds_its_own_engine_and_no_physics(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_physics(*args: object, **kwargs: object) -> None:
        raise AssertionError("the twin built a physics Simulation")

    monkeypatch.setattr(Simulation, "__init__", no_physics)
    config = tavc_env.preset("dahl2004")
    env = tavc_env.twin_parallel_env(tables=tables(config), config=config)
    assert isinstance(env, ArenaEnv) and not isinstance(env, TavcArenaEnv)
    assert isinstance(env.sim, TaskTimeProcess) and env.process is env.sim
    env.reset(seed=0)
    env.step({a: 0 for a in env.agents})
    assert env.sim_time_s > 0


def test_both_engines_take_the_same_breakdowns_from_the_arena() -> None:
    config = tavc_env.make_config(
        breakdowns=(tavc_env.Breakdown(robot=0, at_s=100.0, repair_after_s=200.0),)
    )
    for env in (
        tavc_env.parallel_env(config=config, decision_interval_s=50.0),
        TwinArenaEnv(tables(config), config=config, decision_interval_s=50.0),
    ):
        env.reset(seed=1)
        broken = []
        while env.sim_time_s < 400.0:
            _, _, _, _, infos = env.step(
                {a: 0 for a in env.agents if infos_of(env, a)["action_required"]}
            )
            broken.append((env.sim_time_s, infos["robot_0"]["broken"]))
        down = [t for t, b in broken if b]
        assert down[0] == pytest.approx(100.0) and down[-1] == pytest.approx(250.0), type(env)


def infos_of(env: ArenaEnv[object], agent: str) -> dict[str, object]:
    return {"action_required": env.must_decide(agent)}


def test_the_tick_names_the_shared_types_it_uses() -> None:
    from tavc_env.engine import simulation

    assert simulation.Advance is Advance and simulation.ScheduleEntry is ScheduleEntry
