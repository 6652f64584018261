"""The interference analysis on hand-made runs and rows, where every number is known."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import arena_analysis as ia
from tavc_env.measurement import CountedTask, FixedAllocation, FixedRun, Mode


def _run(
    circuit_of: tuple[int, ...], classes: list[str], tasks: list[CountedTask], switcher: int = -1
) -> FixedRun:
    alloc = FixedAllocation(
        preset="dahl2004",
        circuit_of=circuit_of,
        seed=7,
        hours=1.0,
        warmup_s=0.0,
        skip_first=0,
        switcher=switcher,
    )
    ticks = np.zeros((len(circuit_of), len(Mode)))
    ticks[:, Mode.TRAVEL] = 3
    ticks[:, Mode.QUEUED] = 1  # a quarter of every robot's ticks queued
    return FixedRun(alloc, classes, tasks, ticks, wall_s=1.234)


def test_group_rows_summarise_each_circuit_class_and_kind() -> None:
    tasks = [
        CountedTask(0, "fast", 0, 60.0, 0.0, "own"),
        CountedTask(0, "fast", 0, 70.0, 0.0, "own"),
        CountedTask(1, "slow", 0, 90.0, 0.0, "own"),
        CountedTask(2, "slow", 1, 80.0, 0.0, "own"),
    ]
    run = _run((0, 0, 1), ["fast", "slow", "slow"], tasks)
    rows = {(r["circuit"], r["robot_class"]): r for r in ia.group_rows(run, "cross", "1:1")}
    assert set(rows) == {(0, "all"), (0, "fast"), (0, "slow"), (1, "all"), (1, "slow")}
    everyone = rows[(0, "all")]
    assert everyone["mean_task_time_s"] == pytest.approx(220.0 / 3)
    assert everyone["n_tasks"] == 3 and everyone["n_on_circuit"] == 2
    assert (everyone["n_fast_on_circuit"], everyone["n_slow_on_circuit"]) == (1, 1)
    assert everyone["queued_s_per_task"] == pytest.approx(0.25 * 220.0 / 3)
    assert everyone["travel_s_per_task"] == pytest.approx(0.75 * 220.0 / 3)
    assert rows[(0, "fast")]["sd_task_time_s"] == pytest.approx(np.std([60, 70], ddof=1))
    assert math.isnan(rows[(1, "slow")]["sd_task_time_s"])  # one task
    assert everyone["experiment"] == "cross" and everyone["label"] == "1:1"
    assert everyone["seed"] == 7 and everyone["run_wall_s"] == 1.23


def test_the_switcher_is_its_own_group_with_no_time_shares() -> None:
    tasks = [
        CountedTask(1, "medium", 0, 100.0, 0.0, "switch"),
        CountedTask(1, "medium", 0, 70.0, 0.0, "own"),
        CountedTask(0, "medium", 0, 65.0, 0.0, "own"),
    ]
    run = _run((0, 1), ["medium", "medium"], tasks, switcher=1)
    rows = ia.group_rows(run, "switch", "x")
    keys = [(r["robot_class"], r["task_kind"]) for r in rows]
    assert keys == [("all", "own"), ("medium", "own"), ("switcher", "own"), ("switcher", "switch")]
    assert all(r["n_on_circuit"] == 2 for r in rows)  # robot 0 and the switcher
    assert all("queued_s_per_task" not in r for r in rows)


def _row(**fields: Any) -> dict[str, Any]:
    base = {"robot_class": "all", "task_kind": "own", "n_tasks": 10, "label": ""}
    return {**base, **fields}


def test_t_n_curve_means_throughput_and_ratios() -> None:
    rows = []
    for seed, jitter in ((0, -1.0), (1, 1.0)):
        for c in (0, 1):
            for n in range(1, 7):
                t = 60.0 * 1.2 ** (n - 1) + jitter
                rows.append(
                    _row(
                        experiment="t_n",
                        seed=seed,
                        circuit=c,
                        n_on_circuit=n,
                        mean_task_time_s=t,
                        queued_s_per_task=5.0 * (n - 1),
                    )
                )
    summary, tn = ia.t_n_curve(rows, [0, 1], "h", np.random.default_rng(0))
    assert len(summary) == 2 * (6 * 3 + 5)
    assert tn[0][3] == [60.0 * 1.44 - 1.0, 60.0 * 1.44 + 1.0]
    get = {(r["quantity"], r["circuit"], r["n_on_circuit"]): r for r in summary}
    t4 = get[("mean task time (s)", 1, 4)]
    assert t4["mean"] == pytest.approx(60.0 * 1.2**3) and t4["n_seeds"] == 2 and t4["n_tasks"] == 20
    assert get[("time queued per task (s)", 0, 3)]["mean"] == pytest.approx(10.0)
    throughput = get[("circuit throughput n/t(n) (tasks/h)", 0, 1)]
    assert throughput["mean"] == pytest.approx(np.mean([3600 / 59.0, 3600 / 61.0]))
    ratio = get[("t(4)/t(3)", 0, 4)]
    assert ratio["section"] == "t_ratio" and ratio["mean"] == pytest.approx(1.2)
    assert ratio["ci95_low"] < 1.2 < ratio["ci95_high"]
    assert ratio["bootstrap_low"] <= 1.2 <= ratio["bootstrap_high"]


def test_switch_cost_is_paired_within_each_seed() -> None:
    case = ia.SwitchCase("switch", "others 2+3", 0, 3)
    rows = []
    for seed, own, switch in ((0, 70.0, 91.0), (1, 72.0, 90.0), (2, 71.0, 99.0)):
        for kind, t in (("own", own), ("switch", switch)):
            rows.append(
                _row(
                    experiment="switch",
                    label="others 2+3",
                    seed=seed,
                    circuit=0,
                    robot_class="switcher",
                    task_kind=kind,
                    mean_task_time_s=t,
                )
            )
    rows.append(
        _row(
            experiment="switch",
            label="others 2+3",
            seed=3,
            circuit=0,
            robot_class="switcher",
            task_kind="own",
            mean_task_time_s=50.0,
        )
    )  # unpaired
    out, info = ia.switch_cost(rows, [0, 1, 2, 3], "h", case)
    assert case.name == "others 2+3 into c0"
    assert [r["quantity"].split(": ")[1] for r in out] == [
        "own-circuit task time (s)",
        "switch task time (s)",
        "extra time (s)",
        "relative extra",
    ]
    assert info["own"]["mean"] == pytest.approx(71.0)  # seed 3 has no switch task: left out
    assert info["extra"]["mean"] == pytest.approx(np.mean([21.0, 18.0, 28.0]))
    assert info["rel_values"] == pytest.approx([21 / 70, 18 / 72, 28 / 71])
    assert info["n_switch_tasks"] == 30 and info["n_own_tasks"] == 30


def test_cross_matrices_index_circuit_one_by_the_robots_left_for_it() -> None:
    rows = [
        _row(
            experiment="cross",
            label=ia.cross_label(1, 2),
            seed=s,
            circuit=c,
            robot_class="fast",
            mean_task_time_s=100.0 * c + 60.0 + s,
        )
        for s in (0, 1)
        for c in (0, 1)
    ]
    out, times, queued = ia.cross_matrices(rows, [0, 1], "dahl2004")
    assert times[(0, "fast")][(1, 2)][0] == pytest.approx(60.5)
    assert times[(1, "fast")][(2, 1)][0] == pytest.approx(160.5)  # 3 - 1 fast, 3 - 2 slow
    assert math.isnan(times[(0, "slow")][(1, 2)][0])
    assert math.isnan(queued[(0, "fast")][(1, 2)][0])  # no time shares in these rows
    assert [(r["quantity"], r["circuit"]) for r in out] == [
        ("time queued per task (s)", 0),
        ("mean task time (s)", 0),
        ("time queued per task (s)", 1),
        ("mean task time (s)", 1),
    ]


def test_per_seed_refuses_two_rows_of_one_seed() -> None:
    rows = [_row(seed=0, circuit=0), _row(seed=0, circuit=0)]
    with pytest.raises(ValueError, match="seed 0"):
        ia.per_seed(rows, circuit=0)


def test_labels() -> None:
    assert ia.t_n_label(2) == "2+4"
    assert ia.switch_label(3) == "others 3+2"
    assert ia.cross_label(0, 3) == "0:3"
