"""The twin among moving learners (`tavc_env.twin`, issue 40): first-task cells and class switch
costs in the tables (validation, JSON, older tables unchanged), in both twins (the engine and the
batched one), the tasks of a logged trial and their cells, and `learner_tables`."""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np
import pytest

import tavc_env
from arena_runs import Learner, run_batch
from tavc_agents.experiments.registry import make_allocator
from tavc_agents.experiments.runner import run_trial
from tavc_env.twin import (
    InterferenceTables,
    ObservedTask,
    TaskTimeCell,
    learner_tables,
    logged_tasks,
    required_cells,
)

DAHL = tavc_env.preset("dahl2004")
FIRST = {"fast": 500.0, "slow": 700.0}  # first tasks staying; leaving: + 100 s
COSTS = (0.8, 1.5)  # fast, slow


def mean_of(circuit: int, counts: tuple[int, ...], cls: str) -> float:
    lone = 60.0 if cls == "fast" else 80.0
    return lone * (1 + 0.25 * (sum(counts) - 1)) * (1.2 if circuit == 0 else 1.0)


def index(agent: str) -> int:
    return int(agent.split("_")[1])


def first_cells(switch: bool, sd: float = 0.0) -> tuple[TaskTimeCell, ...]:
    return tuple(
        TaskTimeCell(k, counts, cls, FIRST[cls] + 100.0 * switch + k + sum(counts), sd)
        for k, counts, cls in required_cells(("fast", "slow"), (3, 3), 2)
    )


def learner_style(sd: float = 0.0) -> InterferenceTables:
    """Tables with first-task cells and class switch costs (`sd` on every cell)."""
    base = InterferenceTables.from_function(DAHL, mean_of, sd, switch_cost=1.3)
    return dataclasses.replace(
        base,
        class_switch_costs=COSTS,
        first_own_cells=first_cells(False, sd),
        first_switch_cells=first_cells(True, sd),
    )


def test_the_new_tables_round_trip_and_older_tables_keep_their_data() -> None:
    old = InterferenceTables.from_function(DAHL, mean_of, 5.0, switch_cost=1.3)
    assert set(old.to_dict()) == {"classes", "team", "n_circuits", "switch_cost", "source", "cells"}
    assert old.first_cell(0, (1, 1), "fast", False) is None
    assert old.class_switch_cost("slow") == 1.3
    new = learner_style(5.0)
    assert InterferenceTables.from_dict(new.to_dict()) == new
    assert new.class_switch_cost("fast") == 0.8 and new.class_switch_cost("slow") == 1.5
    cell = new.first_cell(1, (2, 1), "slow", True)
    assert cell is not None and cell.mean_s == 700.0 + 100.0 + 1 + 3


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"class_switch_costs": (1.0,)}, "class_switch_costs"),
        ({"class_switch_costs": (1.0, -2.0)}, "class_switch_costs"),
        ({"first_switch_cells": ()}, "first_own_cells"),
        ({"first_own_cells": first_cells(False)[:-1]}, "first_own_cells"),
    ],
)
def test_bad_learner_fields_are_refused_naming_them(change: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=rf"^{field} = .* is invalid"):
        dataclasses.replace(learner_style(), **change)


def test_the_engine_draws_first_tasks_and_class_switch_costs() -> None:
    """Deterministic tables: every first task takes its first cell (no switch cost on top), every
    later switch its class's cost, every later own task its cell."""
    tables = learner_style()
    env = tavc_env.twin_parallel_env(tables=tables, config=DAHL, max_sim_time_s=3 * 3600.0)
    rng = np.random.default_rng(3)
    _, infos = env.reset(seed=2)
    last = {a: infos[a]["circuit"] for a in env.agents}
    pending: dict[str, tuple[int, tuple[int, ...], bool, bool]] = {}
    classes = [r.speed_class for r in DAHL.robots]
    seen: set[str] = set()
    checked = {"first": 0, "switch": 0, "own": 0}
    while env.agents:
        actions = {a: int(rng.integers(2)) for a in env.agents if infos[a]["action_required"]}
        _, _, _, _, infos = env.step(actions)
        last_before = dict(last)
        last.update(actions)  # every robot works on its last choice: the cells count them all
        for a, choice in actions.items():
            counts = tuple(
                sum(1 for b, k in last.items() if k == choice and classes[index(b)] == cls)
                for cls in ("fast", "slow")
            )
            pending[a] = (choice, counts, choice != last_before[a], a not in seen)
            seen.add(a)
        for a, info in infos.items():
            if tavc_env.completed_task_s(info) is None:
                continue
            circuit, counts, switch, first = pending.pop(a)
            cls = classes[index(a)]
            if first:
                cell = tables.first_cell(circuit, counts, cls, switch)
                assert cell is not None
                expected, kind = cell.mean_s, "first"
            else:
                factor = tables.class_switch_cost(cls) if switch else 1.0
                expected = tables.cell(circuit, counts, cls).mean_s * factor
                kind = "switch" if switch else "own"
            assert info["task_time_s"] == pytest.approx(expected, rel=1e-9)
            checked[kind] += 1
    assert checked["first"] == 6 and min(checked.values()) >= 6, checked


def test_a_logged_trials_tasks_meet_their_cells() -> None:
    """A trial of the trial runner on deterministic tables: every task `logged_tasks`
    reconstructs from the record (start, changes, deliveries) has exactly its cell's time."""
    tables = learner_style()
    result = run_trial(
        make_allocator("softmax_tavc", temperature=0.01),
        seed=4,
        convergence_s=3600.0,
        measured_s=3600.0,
        env_factory=functools.partial(tavc_env.twin_parallel_env, tables=tables),
        arena="dahl2004",
    )
    tasks = logged_tasks(
        DAHL,
        result.initial_circuits,
        result.changes,
        result.delivery_time_s,
        result.delivery_robot,
        result.delivery_circuit,
        result.delivery_task_time_s,
    )
    assert len(tasks) == len(result.delivery_time_s) > 100
    assert sum(t.first for t in tasks) == 6
    assert any(t.switch and not t.first for t in tasks)
    for t in tasks:
        if t.first:
            cell = tables.first_cell(t.circuit, t.counts, t.robot_class, t.switch)
            assert cell is not None
            expected = cell.mean_s
        else:
            factor = tables.class_switch_cost(t.robot_class) if t.switch else 1.0
            expected = tables.cell(t.circuit, t.counts, t.robot_class).mean_s * factor
        assert t.task_time_s == pytest.approx(expected, rel=1e-9), t


def test_learner_tables_take_what_learners_met_and_keep_the_rest() -> None:
    fixed = InterferenceTables.from_function(DAHL, mean_of, 5.0, switch_cost=1.3)
    own = [ObservedTask("fast", 0, (2, 1), False, 100.0 + k % 3) for k in range(30)]
    few = [ObservedTask("slow", 1, (0, 1), False, 999.0) for _ in range(5)]
    switches = [ObservedTask("fast", 0, (2, 1), True, 202.0) for _ in range(20)]
    switches += [ObservedTask("slow", 1, (1, 1), True, 0.5 * mean_of(1, (1, 1), "slow"))] * 20
    starts = [ObservedTask("fast", 1, (1, 0), False, 50.0 + k, first=True) for k in range(5)]
    starts += [ObservedTask("slow", 0, (0, 2), True, 300.0, first=True)] * 2
    starts += [ObservedTask("slow", 1, (0, 1), True, 100.0, first=True)] * 2
    starts += [ObservedTask(c, 0, (1, 1), False, 10.0, first=True) for c in ("fast", "slow")] * 2
    starts += [ObservedTask("fast", 0, (1, 1), True, 10.0, first=True)] * 2
    new = learner_tables(fixed, own + few + switches, starts)
    assert new.cell(0, (2, 1), "fast").mean_s == pytest.approx(101.0)
    assert new.cell(0, (2, 1), "fast").n_tasks == 30
    assert new.cell(1, (0, 1), "slow") == fixed.cell(1, (0, 1), "slow")  # 5 < min_tasks
    assert new.class_switch_costs == pytest.approx((2.0, 0.5))
    assert new.first_cell(1, (1, 0), "fast", False).mean_s == pytest.approx(52.0)  # type: ignore[union-attr]
    # a cell with fewer than min_first first tasks: its class and kind's moments
    pooled = new.first_cell(0, (0, 1), "slow", True)
    assert pooled is not None and pooled.mean_s == pytest.approx(200.0) and pooled.n_tasks == 4
    with pytest.raises(ValueError, match=r"^switch tasks of class 'slow' = 0 is invalid"):
        learner_tables(fixed, own + switches[:20], starts)


def test_the_batched_twin_draws_first_tasks_and_class_switch_costs() -> None:
    """First tasks longer than the run: no delivery in the window; with them, what the batched
    twin measures agrees with the Policy-based twin in distribution (as for older tables)."""
    hours: dict[str, Any] = {"convergence_s": 300.0, "measured_s": 200.0}
    slow_start = dataclasses.replace(
        learner_style(),
        first_own_cells=tuple(dataclasses.replace(c, mean_s=600.0) for c in first_cells(False)),
        first_switch_cells=tuple(dataclasses.replace(c, mean_s=600.0) for c in first_cells(True)),
    )
    batch = run_batch(DAHL, slow_start, Learner("random"), 20, np.random.default_rng(0), **hours)
    assert (batch.performance == 0).all()
    old = dataclasses.replace(slow_start, first_own_cells=(), first_switch_cells=())
    assert (
        run_batch(DAHL, old, Learner("random"), 20, np.random.default_rng(0), **hours).performance
        > 0
    ).all()
