"""The model twin of the arena: the decision process alone, with task times drawn from an arena's
measured interference tables instead of simulated by physics.

A research tool, for fast what-if studies and power analyses; never a replacement for the physics
(`tavc_env.parallel_env`), whose results are the ones to report.

## tavc_twin_v0

The same PettingZoo `ParallelEnv` as `tavc_arena_v1` (`TwinArenaEnv` and `TavcArenaEnv` are the
same adapter, `tavc_env.env.ArenaEnv`: same agents, observation and action spaces, rewards `w_i / t`
in the same time unit, info keys, truncation, `max_cycles`, stepping modes, breakdowns and repairs,
priority changes, copying), driving another engine behind the same protocol
(`tavc_env.engine.base.Engine`): `TaskTimeProcess`, an event-driven model, instead of the physics:

* at reset the robots stand at the circuits' sinks, spread evenly over the circuits in an order
  drawn from the env's generator (as in the physics), and all decide;
* when a robot chooses circuit `k`, it commits to `k`. Once every robot deciding at that moment has
  chosen, each draws its task time from the cell of `InterferenceTables` for its speed class and
  the numbers of robots of each class committed to `k` (itself and the others deciding at the same
  moment included), times `switch_cost` if `k` differs from the circuit of its last task;
* time jumps to the next completion (or scheduled breakdown or repair); the robot is paid
  `w_k / t` and decides again.

## Tables measured among learners

Tables from fixed allocations (`build_tables`) leave out what learners meet
(`learner_tables` measures it; `benchmarks/twin_learners.py` audits it mechanism by mechanism):

* **The first task.** Each robot's first task starts from the spread start allocation, before any
  crowd has formed, so it is shorter than the steady-state cells (in `dahl2004_passing` a fast
  robot that keeps its start circuit takes 162 s; drawn from the cells, 224 s). A learner with the
  scaled initialisation takes every Q entry from its first reward, and that level barely relaxes,
  so the first task sets each robot's Q level for the whole run. Tables with first-task cells
  (`first_own_cells`, `first_switch_cells`: by the cell at decision, staying on the start circuit
  or leaving it) draw each robot's first task from them.
* **Task times among moving learners.** Learners' crowds form and dissolve as robots come and go;
  the same (fast, slow) count on a circuit then costs other times than when it is held fixed (in
  crowded mixed cells the fast robots' lead shrinks). Cells measured among learners, by the count
  on the circuit at the task's decision (the moment the twin draws; conditioned so, the twin's
  task times by composition meet the physics' among learners), replace the fixed-allocation
  cells where learners met them often enough.
* **Class switch costs.** A switch costs each class its own factor (`class_switch_costs`).

Tables without these fields draw exactly as before (`tavc_twin_v0`'s trajectories unchanged).

Why they decide the direction of differentiation: near indifference a class prefers the
high-value circuit the more, the smaller its relative time penalty there, R = t(high) / t(low)
as the class meets it among moving learners. The paper's direction (fast robots on the
high-value circuit) needs R_fast < R_slow, with the classes' initial Q surpluses alike; where
R_fast > R_slow the robots differentiate in reverse.

## Distribution

Task times are lognormal with the cell's mean and standard deviation (moments matched:
`sigma^2 = ln(1 + (sd / mean)^2)`, `mu = ln(mean) - sigma^2 / 2`), not gamma. Both are positive and
right-skewed like queueing delays and nearly agree when the spread is small (the physics' cells
have sd / mean of about 0.1-0.4). They differ where it matters to learners paid `w / t`: a
lognormal's density vanishes at 0 whatever the spread, so E[1/t] = (1 + cv^2) / mean stays finite,
whereas a gamma with sd >= mean (shape <= 1, possible in a sparsely measured or jam-hit cell) has
its mode at 0 and an infinite E[1/t]: occasional near-zero task times would pay huge rewards that
no physical task can (every real task takes at least its travel and service times).

## Limits (what the model leaves out)

* A task's time is drawn once, at its decision, from the robots committed to its circuit then;
  robots joining or leaving that circuit during the task do not change it.
* Only robots on the same circuit interfere; traffic from other circuits enters only as it was
  present in the runs that measured the tables (`tavc_env.twin.measure`).
* Counts are per speed-class label (`Robot.speed_class`); robots of one class are alike.
* One switch cost per class (for every class, unless the tables give `class_switch_costs`), for
  every circuit; a repaired robot's next task counts as starting at the circuit of its
  abandoned task.
* Task times are independent draws: no serial correlation of one robot's successive tasks (the
  passing arena's physics has a lag-1 correlation of about -0.16).
* No space: no positions, no jams (`jammed` is always False, `jams`, `escapes` 0), no rendering
  (`render_mode` must be None); `state()` is the twin's own (circuits, phases, commitments) and
  `snapshot()` is refused. A working robot reports the phase `to_source` for its whole task.
* Time is continuous (physics advances in ticks of `dt`): completions fall between ticks.

What these limits cost was measured where they bite hardest, random allocation (crowds change at
every decision, half the tasks are switches; `benchmarks/twin_audit.py`): in the shipped arenas
the physics' own-circuit tasks are 3-13 % shorter than their cells, and its switch tasks cost less
extra than the tables' switch cost (measured by a robot alternating every 3 tasks), so the twin
underestimates random allocation's performance by 3-9 %. Learners, which settle and rarely switch,
are predicted more closely (the regime map).

## Where

`tables` (the tables), `measure` (measuring them in the physics: `build_tables`), `engine`
(`TaskTimeProcess`), `env` (`TwinArenaEnv`), `paid` (`TwinPaidArenaEnv`: the physics paying its
learners the twin's task times, a diagnostic of the twin); every public name is importable from
`tavc_env.twin` itself. The learner-aware batched twin is `tavc_agents.experiments.twin_batch`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from tavc_env.twin.engine import TaskTimeProcess, TwinTasks
from tavc_env.twin.env import TWIN_ENV_NAME, TwinArenaEnv
from tavc_env.twin.measure import (
    REFERENCE_PRESET,
    ObservedTask,
    RandomRun,
    allocation_for,
    build_tables,
    first_tasks,
    learner_tables,
    logged_tasks,
    random_allocation_run,
    switch_cost,
)
from tavc_env.twin.paid import (
    TWIN_PAID_ENV_NAME,
    TwinPaidArenaEnv,
    TwinPaidSimulation,
    twin_paid_parallel_env,
)
from tavc_env.twin.tables import (
    CellKey,
    InterferenceTables,
    TaskTimeCell,
    count_vectors,
    required_cells,
    team_classes,
)

__all__ = [
    "REFERENCE_PRESET",
    "TWIN_ENV_NAME",
    "TWIN_PAID_ENV_NAME",
    "CellKey",
    "InterferenceTables",
    "ObservedTask",
    "RandomRun",
    "TaskTimeCell",
    "TaskTimeProcess",
    "TwinArenaEnv",
    "TwinPaidArenaEnv",
    "TwinPaidSimulation",
    "TwinTasks",
    "allocation_for",
    "build_tables",
    "count_vectors",
    "first_tasks",
    "learner_tables",
    "logged_tasks",
    "random_allocation_run",
    "required_cells",
    "switch_cost",
    "team_classes",
    "twin_paid_parallel_env",
    "twin_parallel_env",
]


def twin_parallel_env(
    tables: InterferenceTables | Mapping[str, Any], **kwargs: Any
) -> TwinArenaEnv:
    """The twin as a PettingZoo ParallelEnv: `tables` plus `tavc_env.parallel_env`'s keyword
    arguments (see `TwinArenaEnv`)."""
    return TwinArenaEnv(tables, **kwargs)
