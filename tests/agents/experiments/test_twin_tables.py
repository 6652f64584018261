"""Trials on the model twin (`run_trial(env_factory=...)`) and the twin's tables measured in the
physics (`tavc_env.twin.measure`): the default path is untouched, TAVC learners run 20
simulated hours on the twin in well under a second, and a tiny build from physics works."""

from __future__ import annotations

import functools
import json
import math
from typing import Any

import pytest

import tavc_env
from tavc_agents.experiments.registry import make_allocator
from tavc_agents.experiments.runner import Event, TrialResult, run_trial
from tavc_env.twin import (
    InterferenceTables,
    TwinArenaEnv,
    allocation_for,
    build_tables,
    random_allocation_run,
)

DAHL = tavc_env.preset("dahl2004")
SHORT = {"convergence_s": 300.0, "measured_s": 300.0}  # ten simulated minutes of physics


def mean_of(circuit: int, counts: tuple[int, ...], cls: str) -> float:
    lone = 60.0 if cls == "fast" else 80.0
    return lone * (1 + 0.2 * (sum(counts) - 1))


TABLES = InterferenceTables.from_function(DAHL, mean_of, 8.0, switch_cost=1.3)
TWIN = functools.partial(tavc_env.twin_parallel_env, tables=TABLES)


def comparable(result: TrialResult) -> dict[str, Any]:
    d = result.to_dict()
    d.pop("wall_s")
    return d


# -- run_trial on another env factory ------------------------------------------------------------


def test_the_default_factory_path_is_unchanged() -> None:
    softmax = make_allocator("softmax_tavc")
    default = run_trial(softmax, seed=3, arena="dahl2004", **SHORT)
    none = run_trial(softmax, seed=3, arena="dahl2004", env_factory=None, **SHORT)
    explicit = run_trial(
        softmax, seed=3, arena="dahl2004", env_factory=tavc_env.parallel_env, **SHORT
    )
    assert comparable(none) == comparable(default) == comparable(explicit)
    assert "env_factory" not in default.env_kwargs
    assert default.delivery_time_s  # the trial did something


def test_softmax_tavc_runs_twenty_hours_on_the_twin() -> None:
    results = [
        run_trial(make_allocator("softmax_tavc"), seed=0, env_factory=TWIN, arena="dahl2004")
        for _ in range(2)
    ]
    result = results[0]
    assert isinstance(result, TrialResult)
    assert comparable(results[1]) == comparable(result)  # the same seed, the same trial
    assert result.end_s == pytest.approx(20 * 3600.0)
    assert result.env_kwargs == {
        "preset": "dahl2004",
        "env_factory": "tavc_env.twin.twin_parallel_env",
    }
    assert len(result.delivery_time_s) > 3000
    assert len(result.q_snapshots) == 21
    assert set(result.learner_stats) == set(result.agents)
    assert result.jams == result.escapes == 0
    other = run_trial(make_allocator("softmax_tavc"), seed=1, env_factory=TWIN, arena="dahl2004")
    assert other.changes != result.changes
    # the record reads back
    assert TrialResult.from_dict(json.loads(json.dumps(result.to_dict()))).changes == result.changes


def test_events_and_team_allocators_on_the_twin() -> None:
    events = [
        Event(at_s=600.0, kind="break_down", robot=2),
        Event(at_s=1800.0, kind="repair", robot=2),
        Event(at_s=2400.0, kind="set_values", values=(1000.0, 3000.0)),
    ]
    result = run_trial(
        make_allocator("response_threshold"),
        seed=0,
        env_factory=TWIN,
        events=events,
        convergence_s=1800.0,
        measured_s=1800.0,
    )
    assert [e[1] for e in result.events] == ["break_down", "repair", "set_values"]
    down = [t for t, r in zip(result.delivery_time_s, result.delivery_robot) if r == 2]
    broken_s, repaired_s = result.events[0][0], result.events[1][0]
    assert not any(broken_s < t <= repaired_s for t in down)
    assert any(t > 1800.0 for t in down)
    applied = result.events[-1][0]  # at the first step boundary at or after 2400 s
    late = [v for t, v in zip(result.delivery_time_s, result.delivery_value) if t > applied]
    assert late and set(late) <= {1000.0, 3000.0}


def test_a_bad_factory_is_refused() -> None:
    with pytest.raises(ValueError, match=r"env_factory = 'twin'"):
        run_trial(make_allocator("random"), seed=0, env_factory="twin", **SHORT)
    with pytest.raises(ValueError, match=r"tables = "):
        run_trial(
            make_allocator("random"),
            seed=0,
            env_factory=TWIN,
            arena="dahl2004_homogeneous",
            **SHORT,
        )


# -- building tables from physics ----------------------------------------------------------------


def test_allocations_put_the_crowd_on_the_circuit_and_the_rest_on_the_next() -> None:
    classes = ("fast", "slow")
    assert allocation_for(DAHL, classes, 0, (2, 1)) == (0, 0, 1, 0, 1, 1)
    assert allocation_for(DAHL, classes, 1, (3, 0)) == (1, 1, 1, 0, 0, 0)
    three = tavc_env.preset("three_circuits_three_classes")
    assert allocation_for(three, ("fast", "medium", "slow"), 2, (0, 1, 3)) == (
        0,
        0,
        0,
        2,
        0,
        0,
        2,
        2,
        2,
    )


def test_a_tiny_build_from_physics() -> None:
    config = tavc_env.make_config("dahl2004", speeds=[0.3, 0.2])  # one fast, one slow robot
    lines: list[str] = []
    tables = build_tables(
        config, seeds=(0,), hours=0.15, warmup_s=0.0, switch_every=2, progress=lines.append
    )
    assert len(lines) == 4 + 2  # four allocations cover both circuits' cells; two switchers
    assert tables.classes == ("fast", "slow") and tables.team == (1, 1)
    assert len(tables.cells) == 8
    assert all(cell.n_tasks >= 2 for cell in tables.cells)
    for k in (0, 1):
        lone_fast = tables.cell(k, (1, 0), "fast").mean_s
        lone_slow = tables.cell(k, (0, 1), "slow").mean_s
        assert 40.0 < lone_fast < lone_slow < 120.0  # the slow robot drives 5 m legs slower
        assert tables.cell(k, (1, 1), "fast").mean_s > lone_fast  # it waits behind the other
    assert 1.0 < tables.switch_cost < 2.5  # the diagonal between lanes is the longer way
    assert "physics: 6 fixed-allocation runs" in tables.source
    assert InterferenceTables.from_dict(json.loads(json.dumps(tables.to_dict()))) == tables
    # the measured tables drive the twin of that arena
    env = TwinArenaEnv(tables, config=config, max_sim_time_s=3600.0)
    _, infos = env.reset(seed=0)
    while env.agents:
        _, _, _, _, infos = env.step({a: 0 for a in env.agents if infos[a]["action_required"]})
    assert env.process.tasks.completed[0] > 10


def test_build_refuses_what_it_cannot_measure() -> None:
    one = tavc_env.make_config("dahl2004", circuits=tavc_env.lane_circuits(1), speeds=[0.3, 0.2])
    with pytest.raises(ValueError, match=r"config\.circuits"):
        build_tables(one)
    two = tavc_env.make_config("dahl2004", speeds=[0.3, 0.2])
    with pytest.raises(ValueError, match=r"cell circuit 0, counts \(0, 1\), class 'slow'"):
        build_tables(two, seeds=(0,), hours=0.01, warmup_s=0.0)
    with pytest.raises(ValueError, match=r"hours = 0"):
        build_tables(two, hours=0)
    with pytest.raises(ValueError, match=r"seeds = \(\)"):
        build_tables(two, seeds=())
    assert math.isfinite(TABLES.switch_cost)


# -- random allocation on either engine ---------------------------------------------------------


def test_random_allocation_on_a_deterministic_twin_meets_its_cells_exactly() -> None:
    exact = InterferenceTables.from_function(DAHL, mean_of, 0.0, switch_cost=1.5)
    run = random_allocation_run(
        DAHL, seed=4, hours=2.0, warmup_s=600.0, engine="twin", tables=exact
    )
    switches = [t for t in run.tasks if t.switch]
    assert 0.3 < len(switches) / len(run.tasks) < 0.7  # two circuits: half the choices switch
    for task in run.tasks:
        cell = exact.cell(task.circuit, task.counts, task.robot_class)
        assert task.task_time_s == pytest.approx(cell.mean_s * (1.5 if task.switch else 1.0))
        assert sum(task.counts) >= 1 and task.counts[exact.classes.index(task.robot_class)] >= 1
    values = [c.value for c in DAHL.circuits]
    assert 0 < run.performance < 10.0 * len(DAHL.robots) / 60.0 * max(values)
    again = random_allocation_run(DAHL, 4, 2.0, 600.0, "twin", exact)
    assert again == run


def test_random_allocation_in_the_physics_counts_what_it_runs() -> None:
    run = random_allocation_run(DAHL, seed=1, hours=0.3, warmup_s=300.0)
    assert run.tasks and all(t.task_time_s > 0 for t in run.tasks)
    assert {t.robot_class for t in run.tasks} == {"fast", "slow"}
    assert 0.05 < run.performance < 0.2  # the paper's scale: about 0.1 per robot per 10 s
    assert random_allocation_run(DAHL, 1, 0.3, 300.0) == run
    with pytest.raises(ValueError, match=r"^tables = None is invalid"):
        random_allocation_run(DAHL, 1, 0.3, 300.0, engine="twin")
