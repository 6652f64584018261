"""Stations with several bays (`station_bays`): where the bays stand, that each serves one robot
while the others work beside it, that the line feeds whichever bay frees first, and that a
one-bay station is the one-robot dock it always was."""

from __future__ import annotations

import numpy as np
import pytest

import tavc_env
from tavc_env.engine.tasks import Mode, TaskCycle


def _cycle(bays: int, n: int = 6) -> TaskCycle:
    config = tavc_env.make_config("dahl2004", station_bays=bays)
    tasks = TaskCycle(config)
    for i in range(n):
        tasks.start(i, 0)
    return tasks


def _arrive(tasks: TaskCycle, robots: list[int], now: float = 0.0) -> None:
    for i in robots:
        tasks.choose(i, 0, now)
    for i in robots:
        tasks.arrive(i, now)


def test_bays_stand_along_the_wall_and_the_line_starts_beyond_them() -> None:
    one = tavc_env.preset("dahl2004")
    three = one.replace(station_bays=3)
    for k, (_, dock, direction) in enumerate(three.stations()):
        bays = three.bays(k)
        expected = np.asarray(dock) + np.outer(np.arange(3) * three.queue_spacing_m, direction)
        assert np.allclose(bays, expected)
        # the line keeps its distance from the last bay that it kept from the dock
        first_slot = three.waiting_slots(k, 1)[0]
        assert np.hypot(*(first_slot - bays[-1])) == pytest.approx(one.queue_offset_m)
    assert np.allclose(one.bays(0), [one.stations()[0][1]])


def test_bad_bay_counts_are_refused_with_what_is_allowed() -> None:
    for bad in (0, 9, 1.5, True):
        with pytest.raises(ValueError, match=r"^station_bays = .* is invalid; allowed: an integer"):
            tavc_env.make_config("dahl2004", station_bays=bad)
    with pytest.raises(
        ValueError,
        match=r"^circuits\[0\]\.source bays, circuits, station_bays, queue_spacing_m, "
        r"queue_offset_m, robot_radius, width, height = 'room for \d bays', '2 circuits', 8, 1\.2, "
        r"0\.9, 0\.22, 12\.0, 8\.0 is invalid; allowed: room for all 8",
    ):
        tavc_env.make_config("dahl2004", station_bays=8, queue_spacing_m=1.2)


def test_each_bay_serves_one_robot_and_the_line_takes_the_first_freed_bay() -> None:
    tasks = _cycle(bays=2)
    source = tasks.stations[tasks.source_of(0)]
    _arrive(tasks, [4, 1, 5, 0])
    assert source.occupants == [4, 1] and source.line == [5, 0]
    for bay, i in enumerate((4, 1)):
        assert tasks.mode[i] == Mode.DOCKING
        assert np.array_equal(tasks.target[i], source.docks[bay])
        tasks.arrive(i, 0.0)  # in the bay: served side by side
    in_service = np.flatnonzero((tasks.mode == Mode.SERVICE) & (tasks.station == 0))
    assert sorted(in_service.tolist()) == [1, 4]
    assert source.busy == 1.0
    # robot 1 (second bay) finishes first: the head of the line takes that bay
    assert tasks.finish_service(1, 20.0) is None
    assert source.occupants == [4, 5] and np.array_equal(tasks.target[5], source.docks[1])
    assert source.line == [0] and np.array_equal(tasks.target[0], source.slots[0])
    # a robot breaking down in its bay frees it too
    tasks.break_down(4)
    assert source.occupants == [0, 5] and source.line == []
    assert tasks.bay[4] == -1


def test_a_free_station_with_bays_takes_an_arrival_into_the_bay_nearest_the_dock() -> None:
    tasks = _cycle(bays=3)
    source = tasks.stations[tasks.source_of(0)]
    _arrive(tasks, [2])
    assert source.occupants == [2, -1, -1] and tasks.bay[2] == 0
    assert source.occupant == 2 and source.busy == pytest.approx(1 / 3)


def test_bays_let_more_robots_work_a_circuit_at_once() -> None:
    from tavc_agents.experiments.registry import make_allocator
    from tavc_agents.experiments.runner import run_trial

    def deliveries(bays: int) -> int:
        result = run_trial(
            make_allocator("random"),
            seed=0,
            arena={"preset": "dahl2004", "station_bays": bays, "source_service_s": 40.0},
            convergence_s=0.0,
            measured_s=3600.0,
        )
        assert result.jams == 0
        return len(result.delivery_time_s)

    # 40 s loading caps a one-bay source at 90 loads an hour per circuit; three bays lift that cap
    assert deliveries(3) > 1.2 * deliveries(1)
