"""The model twin's interference tables, measured in the physics (`tavc_env.twin`).

    tables = build_tables(tavc_env.preset("dahl2004"), seeds=(0, 1, 2), hours=1.0)
    env = tavc_env.twin_parallel_env(tables=tables, preset="dahl2004")

Everything here needs only `tavc_env`: tables are made without the learners' package.

Two kinds of fixed-allocation runs (`tavc_env.measurement.run_fixed`), each repeated
for every seed:

* cells: for every circuit k and every vector of robots of each class up to the team's, that many
  robots (the lowest indices of each class) serve k and the others the next circuit, k + 1
  (wrapping). A run measures its two circuits' cells at once, so two circuits need
  prod(team + 1) allocations. A cell's mean and standard deviation pool the own-circuit task
  times of its class over seeds.
* switch cost: one robot of each class in turn alternates between circuits 0 and 1 every
  `switch_every` tasks while the others serve all circuits in turn; per run and circuit, the
  switcher's mean task time after a switch over its mean own-circuit task time into that circuit
  (the same crowd). The table's `switch_cost` is the mean of these ratios.

Runs have no breakdowns (the twin applies the arena's own schedule). One circuit cannot be
measured this way (every robot would always serve it), so the arena needs two or more.

`random_allocation_run` checks the tables where they are least like their measuring runs: every
robot picks a circuit at random at every decision, so crowds change all the time and half the
tasks are switches. It drives either engine, the physics or the twin's, with the same choices.
"""

from __future__ import annotations

import dataclasses
import math
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from tavc_env.config import ArenaConfig, preset_overrides
from tavc_env.engine.simulation import Simulation
from tavc_env.measurement import FixedAllocation, FixedRun, run_fixed
from tavc_env.twin.engine import TaskTimeProcess
from tavc_env.twin.tables import (
    CellKey,
    InterferenceTables,
    TaskTimeCell,
    required_cells,
    team_classes,
)
from tavc_env.validation import is_integer, is_number, require

REFERENCE_PRESET = "dahl2004"  # the runs' configurations are this preset with overrides


def allocation_for(
    config: ArenaConfig, classes: Sequence[str], circuit: int, counts: Sequence[int]
) -> tuple[int, ...]:
    """Each robot's circuit in the run that measures `counts` robots of each class on `circuit`:
    those robots (the lowest indices of each class) on it, the others on the next circuit."""
    other = (circuit + 1) % config.n_circuits
    left = dict(zip(classes, counts))
    circuit_of = []
    for robot in config.robots:
        if left[robot.speed_class] > 0:
            left[robot.speed_class] -= 1
            circuit_of.append(circuit)
        else:
            circuit_of.append(other)
    return tuple(circuit_of)


def _fixed(
    config: ArenaConfig,
    circuit_of: tuple[int, ...],
    seed: int,
    hours: float,
    warmup_s: float,
    skip_first: int,
    switcher: int = -1,
    switch_every: int = 3,
) -> FixedRun:
    """`run_fixed` on `config` (written as overrides of the reference preset)."""
    arena = preset_overrides(config, REFERENCE_PRESET)
    alloc = FixedAllocation(
        preset=REFERENCE_PRESET,
        circuit_of=circuit_of,
        seed=seed,
        hours=hours,
        warmup_s=warmup_s,
        skip_first=skip_first,
        switcher=switcher,
        switch_every=switch_every,
        arena=arena,
    )
    return run_fixed(alloc)


def build_tables(
    config: ArenaConfig,
    *,
    seeds: Sequence[int] = (0, 1, 2),
    hours: float = 1.0,
    warmup_s: float = 600.0,
    skip_first: int = 1,
    switch_every: int = 3,
    min_tasks: int = 2,
    progress: Callable[[str], None] | None = None,
) -> InterferenceTables:
    """Measure `config`'s interference tables in the physics (see the module's docstring).

    Each run lasts `hours` simulated hours and counts the tasks decided after `warmup_s`, except
    each robot's first `skip_first` (see `FixedAllocation`). A cell measured with fewer than
    `min_tasks` tasks, or no switch ratio at all, is a ValueError saying so (run longer or with
    more seeds). `progress`, if given, is called with a description of each run before it starts.
    """
    require(
        isinstance(config, ArenaConfig), "config", type(config).__name__, "a tavc_env.ArenaConfig"
    )
    require(
        config.n_circuits >= 2,
        "config.circuits",
        f"{config.n_circuits} circuit",
        "at least 2 circuits (with one, every robot always serves it: no smaller crowd to "
        "measure, no switch)",
    )
    ok = isinstance(seeds, Sequence) and len(seeds) >= 1 and all(is_integer(s) for s in seeds)
    require(ok, "seeds", seeds, "a non-empty sequence of integer seeds")
    require(is_number(hours) and hours > 0, "hours", hours, "a run length > 0 h")
    require(
        is_number(warmup_s) and 0 <= warmup_s < hours * 3600.0,
        "warmup_s",
        warmup_s,
        "a warm-up >= 0 s shorter than the run",
    )
    require(is_integer(skip_first) and skip_first >= 0, "skip_first", skip_first, "an integer >= 0")
    require(is_integer(min_tasks) and min_tasks >= 2, "min_tasks", min_tasks, "an integer >= 2")
    require(
        is_integer(switch_every) and switch_every >= 2,
        "switch_every",
        switch_every,
        "an integer >= 2 (a block of tasks per circuit: one switch, then own-circuit tasks)",
    )
    base = config.replace(breakdowns=())
    classes, team = team_classes(base)
    run = (float(hours), float(warmup_s), int(skip_first))
    runs = 0

    # cells: fixed allocations until every cell has been measured
    times: dict[CellKey, list[float]] = defaultdict(list)
    wanted = required_cells(classes, team, base.n_circuits)
    done: set[tuple[int, tuple[int, ...]]] = set()
    for circuit, counts, _ in wanted:
        if (circuit, counts) in done:
            continue
        circuit_of = allocation_for(base, classes, circuit, counts)
        on = {
            k: tuple(
                sum(1 for r, c in zip(base.robots, circuit_of) if c == k and r.speed_class == cls)
                for cls in classes
            )
            for k in set(circuit_of)
        }
        done.update(on.items())
        for seed in seeds:
            if progress is not None:
                progress(f"cells: circuits {circuit_of}, seed {seed}")
            runs += 1
            for task in _fixed(base, circuit_of, int(seed), *run).tasks:
                if task.kind == "own":
                    key = (task.circuit, on[task.circuit], task.robot_class)
                    times[key].append(task.task_time_s)
    cells = []
    for key in wanted:
        sample = times.get(key, [])
        c, counts, cls = key
        require(
            len(sample) >= min_tasks,
            f"cell circuit {c}, counts {counts}, class {cls!r}",
            f"{len(sample)} measured tasks",
            f"at least min_tasks = {min_tasks}: run longer (hours), with more seeds or a shorter "
            "warm-up",
        )
        cells.append(
            TaskTimeCell(
                c, counts, cls, float(np.mean(sample)), float(np.std(sample, ddof=1)), len(sample)
            )
        )

    # switch cost: a switcher of each class between circuits 0 and 1
    ratios = []
    for cls in classes:
        switcher = next(i for i, r in enumerate(base.robots) if r.speed_class == cls)
        circuit_of = tuple(
            0 if i == switcher else i % base.n_circuits for i in range(base.n_robots)
        )
        for seed in seeds:
            if progress is not None:
                progress(f"switch cost: robot {switcher} ({cls}) switching, seed {seed}")
            runs += 1
            result = _fixed(base, circuit_of, int(seed), *run, switcher, int(switch_every))
            mine = [t for t in result.tasks if t.robot == switcher]
            for k in (0, 1):
                own = [t.task_time_s for t in mine if t.circuit == k and t.kind == "own"]
                switch = [t.task_time_s for t in mine if t.circuit == k and t.kind == "switch"]
                if own and switch:
                    ratios.append(float(np.mean(switch) / np.mean(own)))
    require(
        bool(ratios),
        "switch cost",
        "no switcher run with both own-circuit and switch tasks into a circuit",
        "run longer (hours) or with more seeds",
    )
    seed_text = ", ".join(str(int(s)) for s in seeds)
    return InterferenceTables(
        classes=classes,
        team=team,
        n_circuits=base.n_circuits,
        cells=tuple(cells),
        switch_cost=float(np.mean(ratios)),
        source=(
            f"physics: {runs} fixed-allocation runs of {hours:g} h (warm-up {warmup_s:g} s, "
            f"first {skip_first} task(s) of each robot skipped), seeds {seed_text}; switch cost "
            f"from {len(ratios)} switcher ratios"
        ),
    )


# -- checking the tables under random allocation --------------------------------------------------
@dataclass(frozen=True)
class ObservedTask:
    """A task observed in a run (random allocation, or a learner trial's log): the robot's class,
    its circuit, the robots of each class working on that circuit once everyone deciding at that
    moment had chosen (itself included: the twin's cell), whether it switched circuits, its time,
    and whether it was the robot's first task (from the start allocation)."""

    robot_class: str
    circuit: int
    counts: tuple[int, ...]
    switch: bool
    task_time_s: float
    first: bool = False


@dataclass(frozen=True)
class RandomRun:
    """What `random_allocation_run` measured: the tasks decided in the window [warm-up, end) and
    completed by the end, and the value delivered per robot per 10 s within the window (each
    delivery w / max w, as `tavc_env.metrics`)."""

    tasks: tuple[ObservedTask, ...]
    performance: float


def random_allocation_run(
    config: ArenaConfig,
    seed: int,
    hours: float,
    warmup_s: float,
    engine: Literal["physics", "twin"] = "physics",
    tables: InterferenceTables | None = None,
) -> RandomRun:
    """Run `config` without breakdowns for `hours`, every deciding robot choosing a circuit
    uniformly at random (a generator seeded [seed, 1]; the engine's own is seeded `seed`), on
    the physics or on the twin with `tables`."""
    base = config.replace(breakdowns=())
    if engine == "twin":
        require(tables is not None, "tables", tables, "the twin's InterferenceTables")
        assert tables is not None
        sim: Simulation | TaskTimeProcess = TaskTimeProcess(base, tables)
    else:
        sim = Simulation(base)
    classes, _ = team_classes(base)
    robot_class = [r.speed_class for r in base.robots]
    values = [c.value for c in base.circuits]
    n, m = base.n_robots, base.n_circuits
    end_s = hours * 3600.0
    choices = np.random.default_rng([seed, 1])
    sim.reset(np.random.default_rng(seed))
    pending: dict[int, tuple[float, tuple[int, ...], bool]] = {}
    started: set[int] = set()  # robots whose first task has been completed

    def decide(robots: Sequence[int]) -> None:
        switched = {}
        for i in robots:
            k = int(choices.integers(m))
            switched[i] = k != int(sim.tasks.circuit[i])
            sim.choose(i, k)
        on = [int(k) for k in sim.tasks.circuit]
        for i in robots:
            k = on[i]
            counts = tuple(
                sum(1 for j in range(n) if on[j] == k and robot_class[j] == c) for c in classes
            )
            pending[i] = (sim.time_s, counts, switched[i])

    decide(range(n))
    tasks: list[ObservedTask] = []
    delivered = 0.0
    while sim.time_s < end_s:
        out = sim.advance(end_s - sim.time_s)
        for comp in out.completions:
            decided_s, counts, switch = pending.pop(comp.robot)
            if comp.time_s >= warmup_s:
                delivered += values[comp.circuit] / max(values)
            if decided_s >= warmup_s:
                tasks.append(
                    ObservedTask(
                        robot_class[comp.robot],
                        comp.circuit,
                        counts,
                        switch,
                        comp.task_time_s,
                        comp.robot not in started,
                    )
                )
            started.add(comp.robot)
        decide([comp.robot for comp in out.completions])
    performance = delivered / n / (end_s - warmup_s) * 10.0
    return RandomRun(tuple(tasks), performance)


# -- tasks of a logged trial, and tables measured among learners --------------------------------
def logged_tasks(
    config: ArenaConfig,
    initial_circuits: Sequence[int],
    changes: Sequence[Sequence[float]],
    delivery_time_s: Sequence[float],
    delivery_robot: Sequence[int],
    delivery_circuit: Sequence[int],
    delivery_task_time_s: Sequence[float],
) -> tuple[ObservedTask, ...]:
    """Every delivered task of a logged trial on `config`'s arena (a trial runner's record: the
    start allocation, every change of a robot's current circuit as (time, robot, circuit), and
    the deliveries), each with its cell at decision: the robots of each class whose current
    circuit was the task's once every change at that moment was made (the twin's cell)."""
    classes, _ = team_classes(config)
    robot_class = [classes.index(r.speed_class) for r in config.robots]
    m = config.n_circuits
    current = [int(c) for c in initial_circuits]
    require(
        len(current) == config.n_robots and all(0 <= c < m for c in current),
        "initial_circuits",
        initial_circuits,
        f"one circuit in [0, {m - 1}] per robot ({config.n_robots})",
    )
    # counts[k][circuit][class] after the k-th change (k = 0: the start)
    counts = np.zeros((len(changes) + 1, m, len(classes)), dtype=np.int64)
    for i, c in enumerate(current):
        counts[0, c, robot_class[i]] += 1
    times = np.empty(len(changes))
    for k, (t, robot, circuit) in enumerate(changes):
        counts[k + 1] = counts[k]
        counts[k + 1, current[int(robot)], robot_class[int(robot)]] -= 1
        counts[k + 1, int(circuit), robot_class[int(robot)]] += 1
        current[int(robot)] = int(circuit)
        times[k] = t
    last = [int(c) for c in initial_circuits]
    tasks = []
    seen: set[int] = set()
    for done, robot, circuit, task_s in sorted(
        zip(delivery_time_s, delivery_robot, delivery_circuit, delivery_task_time_s)
    ):
        robot, circuit = int(robot), int(circuit)
        decided = done - task_s
        # the changes made at the decision (robots deciding together) count; 2 ms: a log's
        # times rounded to 1 ms (physics decides at ticks of dt, 0.1 s or so, apart)
        at = int(np.searchsorted(times, decided + 2e-3, side="right"))
        tasks.append(
            ObservedTask(
                classes[robot_class[robot]],
                circuit,
                tuple(int(n) for n in counts[at, circuit]),
                circuit != last[robot],
                float(task_s),
                robot not in seen,
            )
        )
        seen.add(robot)
        last[robot] = circuit
    return tuple(tasks)


def first_tasks(
    config: ArenaConfig, seeds: Sequence[int], hours: float = 0.25
) -> tuple[ObservedTask, ...]:
    """Every robot's first task in physics runs of `config` (no breakdowns) from the start
    allocation, each robot choosing its first circuit uniformly at random, as a learner does
    while its Q entries are all equal (`random_allocation_run` for `hours`, one run per seed)."""
    ok = isinstance(seeds, Sequence) and len(seeds) >= 1 and all(is_integer(s) for s in seeds)
    require(ok, "seeds", seeds, "a non-empty sequence of integer seeds")
    return tuple(
        task
        for seed in seeds
        for task in random_allocation_run(config, int(seed), hours, 0.0).tasks
        if task.first
    )


def _moments_cell(key: CellKey, sample: Sequence[float]) -> TaskTimeCell:
    c, counts, cls = key
    return TaskTimeCell(
        c, counts, cls, float(np.mean(sample)), float(np.std(sample, ddof=1)), len(sample)
    )


def switch_cost(
    tasks: Sequence[ObservedTask], tables: InterferenceTables, robot_class: str
) -> tuple[float, int]:
    """What switching costs a class: its switch tasks' (after the first) total time over their
    cells' total mean time in `tables`, and how many there are (nan and 0 where none)."""
    paid = [
        (t.task_time_s, tables.cell(t.circuit, t.counts, t.robot_class).mean_s)
        for t in tasks
        if t.switch and not t.first and t.robot_class == robot_class
    ]
    if not paid:
        return math.nan, 0
    return sum(t for t, _ in paid) / sum(m for _, m in paid), len(paid)


def learner_tables(
    fixed: InterferenceTables,
    tasks: Sequence[ObservedTask],
    starts: Sequence[ObservedTask],
    *,
    min_tasks: int = 20,
    min_first: int = 5,
    source: str = "",
) -> InterferenceTables:
    """The twin's tables among moving learners (see `tavc_env.twin`), from learner trials' tasks
    (`logged_tasks`) and first tasks from the start allocation (`first_tasks`):

    * cells: the learners' own-circuit tasks after their first, by the cell at decision, where a
      cell has at least `min_tasks` of them; `fixed`'s cell (fixed allocations) elsewhere;
    * class switch costs: per class, the learners' switch tasks' total time over their cells'
      (these tables') total mean time;
    * first-task cells, staying and leaving: the first tasks of `starts` by their cell, where it
      has at least `min_first`; elsewhere the moments of all first tasks of that class and kind.
    """
    require(is_integer(min_tasks) and min_tasks >= 2, "min_tasks", min_tasks, "an integer >= 2")
    require(is_integer(min_first) and min_first >= 2, "min_first", min_first, "an integer >= 2")
    own: dict[CellKey, list[float]] = defaultdict(list)
    for t in tasks:
        if not (t.first or t.switch):
            own[(t.circuit, t.counts, t.robot_class)].append(t.task_time_s)
    cells = tuple(
        _moments_cell(c.key, own[c.key]) if len(own.get(c.key, ())) >= min_tasks else c
        for c in fixed.cells
    )
    costs = []
    among_learners = dataclasses.replace(fixed, cells=cells)
    for cls in fixed.classes:
        cost, n_switches = switch_cost(tasks, among_learners, cls)
        require(
            n_switches >= min_tasks,
            f"switch tasks of class {cls!r}",
            n_switches,
            f"at least min_tasks = {min_tasks} (log more learner trials)",
        )
        costs.append(cost)
    by_cell: dict[tuple[bool, CellKey], list[float]] = defaultdict(list)
    by_class: dict[tuple[bool, str], list[float]] = defaultdict(list)
    for t in starts:
        require(t.first, "starts", t, "first tasks only (ObservedTask.first)")
        by_cell[(t.switch, (t.circuit, t.counts, t.robot_class))].append(t.task_time_s)
        by_class[(t.switch, t.robot_class)].append(t.task_time_s)
    first: dict[bool, list[TaskTimeCell]] = {False: [], True: []}
    for switch in (False, True):
        for c in fixed.cells:
            sample = by_cell.get((switch, c.key), [])
            if len(sample) < min_first:
                sample = by_class.get((switch, c.robot_class), [])
                require(
                    len(sample) >= 2,
                    f"first tasks of class {c.robot_class!r} ({'leaving' if switch else 'staying'})",
                    len(sample),
                    "at least 2 (more start runs)",
                )
            first[switch].append(_moments_cell(c.key, sample))
    n_learned = sum(1 for a, b in zip(cells, fixed.cells) if a is not b)
    return dataclasses.replace(
        fixed,
        cells=cells,
        class_switch_costs=tuple(costs),
        first_own_cells=tuple(first[False]),
        first_switch_cells=tuple(first[True]),
        source=source
        or (
            f"learners: {n_learned} of {len(cells)} cells and the class switch costs from "
            f"{len(tasks)} learner tasks, first tasks from {len(starts)} starts; other cells: "
            f"{fixed.source}"
        ),
    )
