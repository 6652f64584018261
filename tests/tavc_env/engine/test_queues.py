"""Queue mechanics (tavc_env.engine.tasks): a station serves one robot at a time, its line is first come
first served, and waiting robots stand at their slots (the queue forms in space).

First on `TaskCycle` alone (events called by hand, no physics), then on the crowded run of the
full simulation (six robots serving one circuit for 30 minutes, recorded every tick).
"""

from __future__ import annotations

import numpy as np
import pytest

import tavc_env
from tavc_env.engine.tasks import Mode, Phase, TaskCycle
from tavc_env.layout import ROW_PITCH
from tests.helpers import CONFIGS, CrowdTrace

# -- TaskCycle by hand -------------------------------------------------------------------------


def _cycle(n: int = 6) -> TaskCycle:
    config = tavc_env.parallel_env(speeds=[0.25] * n).config
    tasks = TaskCycle(config)
    for i in range(n):
        tasks.start(i, 0)
    return tasks


def _arrive_at_source(tasks: TaskCycle, robots: list[int], now: float = 0.0) -> None:
    """`robots`, in this order, choose circuit 0 and reach its source's join radius."""
    for i in robots:
        tasks.choose(i, 0, now)
    for i in robots:
        assert tasks.mode[i] == Mode.TRAVEL and tasks.trigger[i] == tasks.config.join_radius_m
        tasks.arrive(i, now)


def test_first_arrival_docks_later_ones_queue_at_successive_slots() -> None:
    tasks = _cycle()
    source = tasks.stations[tasks.source_of(0)]
    _arrive_at_source(tasks, [4, 1, 5, 0])
    assert source.occupant == 4 and tasks.mode[4] == Mode.DOCKING
    assert np.array_equal(tasks.target[4], source.dock)
    assert source.line == [1, 5, 0]
    for k, i in enumerate(source.line):
        assert tasks.mode[i] == Mode.QUEUED
        assert np.array_equal(tasks.target[i], source.slots[k])


def test_one_robot_served_at_a_time_and_the_line_is_first_come_first_served() -> None:
    tasks = _cycle()
    source = tasks.stations[tasks.source_of(0)]
    order = [3, 0, 5, 2, 1]
    _arrive_at_source(tasks, order)
    served = []
    now = 0.0
    while source.occupant >= 0:
        i = source.occupant
        assert tasks.mode[i] == Mode.DOCKING
        tasks.arrive(i, now)  # on the dock: loading starts
        assert tasks.mode[i] == Mode.SERVICE
        assert tasks.service_until[i] == pytest.approx(now + tasks.config.source_service_s)
        in_service = np.flatnonzero((tasks.mode == Mode.SERVICE) & (tasks.station == 0))
        assert in_service.tolist() == [i], "one robot served at a time"
        now = tasks.service_until[i]
        assert tasks.finish_service(i, now) is None  # loaded: off to the sink
        assert tasks.phase[i] == Phase.TO_SINK and tasks.station[i] == tasks.sink_of(0)
        served.append(i)
        # the line moved up: everyone waiting targets the slot of their rank
        for k, j in enumerate(source.line):
            assert np.array_equal(tasks.target[j], source.slots[k])
    assert served == order


def test_unloading_completes_the_task_at_the_decision_epoch() -> None:
    tasks = _cycle(n=2)
    tasks.choose(0, 0, now=10.0)
    tasks.arrive(0, 40.0)  # join the free source: dock
    tasks.arrive(0, 42.0)  # docked: loading
    assert tasks.finish_service(0, 62.0) is None
    tasks.arrive(0, 80.0)  # join the free sink: dock
    tasks.arrive(0, 81.0)  # docked: unloading
    completion = tasks.finish_service(0, 85.0)
    assert completion is not None
    assert (completion.robot, completion.circuit) == (0, 0)
    assert completion.task_time_s == pytest.approx(75.0)
    assert tasks.phase[0] == Phase.DECIDING and tasks.needs_decision()[0]
    assert tasks.completed[0] == 1
    assert tasks.stations[tasks.sink_of(0)].occupant == -1


def test_breaking_down_in_line_or_on_the_dock_moves_the_line_up() -> None:
    tasks = _cycle()
    source = tasks.stations[tasks.source_of(0)]
    _arrive_at_source(tasks, [0, 1, 2, 3])
    tasks.break_down(2)  # waiting second in line
    assert source.line == [1, 3]
    assert np.array_equal(tasks.target[3], source.slots[1])
    tasks.break_down(0)  # on the dock
    assert source.occupant == 1 and tasks.mode[1] == Mode.DOCKING
    assert source.line == [3] and np.array_equal(tasks.target[3], source.slots[0])
    for i in (0, 2):
        assert tasks.phase[i] == Phase.BROKEN and tasks.mode[i] == Mode.IDLE
        assert not tasks.needs_decision()[i]
    tasks.repair(2)
    assert tasks.phase[2] == Phase.DECIDING and tasks.needs_decision()[2]


@pytest.mark.parametrize("name", list(CONFIGS))
def test_waiting_slots_are_a_line_of_free_spots_inside_the_arena(name: str) -> None:
    cfg = tavc_env.parallel_env(**CONFIGS[name]).config
    r = cfg.robot_radius
    for k, (_, dock, _) in enumerate(cfg.stations()):
        slots = cfg.waiting_slots(k, cfg.n_robots - 1)
        assert len(slots) >= cfg.n_robots - 1
        assert np.all(slots >= r) and np.all(slots[:, 0] <= cfg.width - r)
        assert np.all(slots[:, 1] <= cfg.height - r)
        first = np.hypot(*(slots[0] - np.array(dock)))
        assert first == pytest.approx(cfg.queue_offset_m)
        everything = np.vstack([np.array(dock)[None], slots[: cfg.n_robots - 1]])
        diff = everything[:, None] - everything[None]
        dist = np.hypot(diff[..., 0], diff[..., 1]) + np.eye(len(everything)) * 1e9
        assert dist.min() >= 2 * r, "slots of one line do not overlap"


def test_a_line_that_would_leave_the_arena_snakes_into_rows_with_an_aisle_between() -> None:
    cfg = tavc_env.parallel_env(speeds=[0.25] * 13).config  # the most dahl2004's lines hold
    rows = cfg.waiting_rows(1, 12)  # the sink of circuit 0 (station 1)
    slots = cfg.waiting_slots(1, 12)
    r, spacing = cfg.robot_radius, cfg.queue_spacing_m
    assert [len(row) for row in rows] == [6, 6]
    assert len(np.unique(slots.round(6), axis=0)) == len(slots) == 12
    assert np.all(slots[:, 0] <= cfg.width - r) and np.all(slots[:, 1] >= r)
    # the second row stands two spacings in (an aisle one slot wide between the rows) ...
    assert rows[1][:, 1] - rows[0][0, 1] == pytest.approx([ROW_PITCH * spacing] * 6)
    # ... and runs back toward the dock: moving up the line is always one spacing
    steps = np.hypot(*np.diff(slots, axis=0).T)
    assert steps[:5] == pytest.approx([spacing] * 5)
    assert steps[5] == pytest.approx(ROW_PITCH * spacing)
    assert steps[6:] == pytest.approx([spacing] * 5)


def test_a_team_the_lines_cannot_hold_is_refused_naming_the_largest_team() -> None:
    with pytest.raises(ValueError, match=r"hold a team of at most 13 robots"):
        tavc_env.parallel_env(speeds=[0.25] * 14)


def test_a_robot_heads_for_the_end_of_a_line_that_spilled_beyond_its_first_row() -> None:
    tasks = _cycle(13)
    source = tasks.stations[tasks.source_of(0)]
    assert source.first_row == 6
    _arrive_at_source(tasks, list(range(7)))  # one docks, six wait: the first row is full
    tasks.choose(7, 0, 0.0)
    assert np.array_equal(tasks.target[7], source.slots[6]), "the end of the line"
    tasks.choose(8, 0, 0.0)
    tasks.arrive(7, 0.0)  # 7 joins: 8 is aimed one slot further
    assert np.array_equal(tasks.target[8], source.slots[7])
    # the line moves up into its first row: the robot still on its way drives at the dock again
    tasks.finish_service(0, 1.0)
    tasks.finish_service(1, 2.0)
    assert len(source.line) == 5 and np.array_equal(tasks.target[8], source.dock)
    assert tasks.trigger[8] == tasks.config.join_radius_m


@pytest.mark.parametrize("name", list(CONFIGS))
def test_waiting_areas_of_different_stations_do_not_overlap(name: str) -> None:
    """Each station's dock and the first `n_robots - 1` slots of its line (enough for every other
    robot to wait there) keep a robot diameter away from those of every other station."""
    env = tavc_env.parallel_env(**CONFIGS[name])
    cfg = env.config
    areas = [
        np.vstack([st.dock[None], st.slots[: cfg.n_robots - 1]]) for st in env.sim.tasks.stations
    ]
    for a in range(len(areas)):
        for b in range(a + 1, len(areas)):
            diff = areas[a][:, None] - areas[b][None]
            gap = np.hypot(diff[..., 0], diff[..., 1]).min()
            assert gap >= 2 * cfg.robot_radius, f"stations {a} and {b}: {gap:.2f} m"


# -- the crowded run ---------------------------------------------------------------------------


def test_a_station_never_serves_two_robots(crowd_trace: CrowdTrace) -> None:
    mode, station = crowd_trace.mode, crowd_trace.station
    owning = (mode == Mode.DOCKING) | (mode == Mode.SERVICE)
    for s in range(len(crowd_trace.slots)):
        assert ((mode == Mode.SERVICE) & (station == s)).sum(axis=1).max() <= 1
        assert (owning & (station == s)).sum(axis=1).max() <= 1
        # whoever is docking or served is the station's occupant
        ticks, robots = np.nonzero(owning & (station == s))
        assert np.array_equal(crowd_trace.occupant[ticks, s], robots)
    # the busy source really was contended: robots waited in line at it most of the time
    source_line = np.array([len(lines[0]) for lines in crowd_trace.lines])
    assert (source_line >= 2).mean() > 0.5


def test_the_line_is_first_come_first_served(crowd_trace: CrowdTrace) -> None:
    """The order in which robots reach a station (join its line, or dock at once) is the order
    in which they get its dock."""
    mode, station, occupant = crowd_trace.mode, crowd_trace.station, crowd_trace.occupant
    n_stations = occupant.shape[1]
    arrivals: list[list[int]] = [[] for _ in range(n_stations)]
    served: list[list[int]] = [[] for _ in range(n_stations)]
    for t in range(1, len(mode)):
        # robots joining in one tick are handled in index order, as np.flatnonzero lists them
        for i in np.flatnonzero(
            (mode[t - 1] == Mode.TRAVEL) & np.isin(mode[t], (Mode.QUEUED, Mode.DOCKING))
        ):
            arrivals[station[t, i]].append(int(i))
        for s in range(n_stations):
            if occupant[t, s] >= 0 and occupant[t, s] != occupant[t - 1, s]:
                served[s].append(int(occupant[t, s]))
    for s in range(n_stations):
        assert served[s] == arrivals[s][: len(served[s])], f"station {s}"
        assert len(arrivals[s]) - len(served[s]) <= crowd_trace.config.n_robots
    assert len(served[0]) >= 50  # circuit 0's source saw real traffic


def test_waiting_robots_stand_at_their_slots(crowd_trace: CrowdTrace) -> None:
    """A waiting robot drives to its slot and stands there. Whenever a robot has waited for the
    same slot long enough to drive there (its distance when the slot was assigned, at half its
    nominal speed - the lowest speed noise allows - plus 5 s to turn), it is within 5 cm of it."""
    trace = crowd_trace
    queued = trace.mode == Mode.QUEUED
    since = np.full(trace.pos.shape[1], np.nan)
    start_gap = np.zeros(trace.pos.shape[1])
    checked = set()
    for t in range(len(trace.time_s)):
        now = trace.time_s[t]
        for i in np.flatnonzero(queued[t]):
            gap = float(np.hypot(*(trace.pos[t, i] - trace.target[t, i])))
            new = (
                t == 0
                or not queued[t - 1, i]
                or not np.array_equal(trace.target[t, i], trace.target[t - 1, i])
            )
            if new:
                since[i], start_gap[i] = now, gap
                # the target is a slot of the line, at the robot's rank in it
                line = trace.lines[t][trace.station[t, i]]
                slot = trace.slots[trace.station[t, i]][line.index(i)]
                assert np.array_equal(trace.target[t, i], slot)
            elif now - since[i] >= start_gap[i] / (0.5 * trace.speeds[i]) + 5.0:
                assert gap <= 0.05, f"robot {i} {gap:.2f} m from its slot at t = {now:.1f} s"
                checked.add((i, since[i]))
    assert len(checked) >= 50, "enough waits were long enough to check"
