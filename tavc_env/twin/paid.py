"""The physics paying its learners as the twin pays (`tavc_twin_paid_v0`): a diagnostic of the
twin. Robots move, queue and decide exactly as in the physics (`tavc_env.Simulation`), but each
task reports a time drawn from the twin's tables for its cell at decision, so a learner's reward
w / t is the twin's. Run beside the physics on the same seeds, it tells what the twin gets wrong:
if a learner trial paid this way lands on the twin's prediction, the twin's pay is what differs;
if it stays on the physics, the twin's motion or decision timing is.

    env = tavc_env.twin.twin_paid_parallel_env(tables=tables, preset="dahl2004")

The draws come from a generator jumped 2^127 steps ahead of the env's own, which leaves the
physics' draws untouched: under the same seed and actions the robots are where the physics puts
them, tick for tick (the task times and rewards differ)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from tavc_env.config import ArenaConfig
from tavc_env.engine.base import Advance
from tavc_env.engine.simulation import Simulation
from tavc_env.engine.tasks import Phase
from tavc_env.env import TavcArenaEnv
from tavc_env.twin.engine import TaskTimeProcess
from tavc_env.twin.tables import InterferenceTables, as_tables

TWIN_PAID_ENV_NAME = "tavc_twin_paid_v0"
_DECIDING, _BROKEN = int(Phase.DECIDING), int(Phase.BROKEN)


class TwinPaidSimulation(Simulation):
    """The physics whose tasks report the twin's times (`TaskTimeProcess.task_time`: the robot's
    class, the circuit, the robots of each class working there once everyone deciding had
    chosen, switch and first task)."""

    def __init__(
        self, config: ArenaConfig, tables: InterferenceTables, jam_window_s: float
    ) -> None:
        super().__init__(config, jam_window_s=jam_window_s)
        self.payer = TaskTimeProcess(config, tables)
        self._classes = np.asarray(self.payer.robot_class)
        self._pay_rng: np.random.Generator | None = None
        self._undrawn: list[tuple[int, bool]] = []
        self._first = [True] * config.n_robots
        self._paid = [math.nan] * config.n_robots

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self._pay_rng = np.random.Generator(rng.bit_generator.jumped())  # type: ignore[attr-defined]
        self._undrawn = []
        self._first = [True] * self.config.n_robots
        self._paid = [math.nan] * self.config.n_robots

    def choose(self, robot: int, circuit: int) -> None:
        switch = int(self.tasks.circuit[robot]) != circuit
        super().choose(robot, circuit)
        self._undrawn.append((robot, switch))

    def pay(self, robot: int, circuit: int, switch: bool, first: bool, drawn_s: float) -> float:
        """The time `robot`'s task, just decided on `circuit` (at `time_s`), will report, from
        the twin's draw `drawn_s`: the draw itself. A hook for a subclass that pays otherwise
        (e.g. by when or how the task was decided)."""
        return drawn_s

    def advance(self, max_duration_s: float, stop_on_decision: bool = True) -> Advance:
        # drawn once everyone deciding has chosen: the twin's cell (`TaskTimeProcess._draw`)
        if self._undrawn:
            assert self._pay_rng is not None
            phase, circuit = np.asarray(self.tasks.phase), np.asarray(self.tasks.circuit)
            working = (phase != _DECIDING) & (phase != _BROKEN)
            for i, switch in self._undrawn:
                k = int(circuit[i])
                here = working & (circuit == k)
                counts = tuple(
                    int(np.sum(here & (self._classes == c))) for c in range(len(self.payer.classes))
                )
                drawn = self.payer.task_time(
                    int(self._classes[i]), k, counts, switch, self._first[i], self._pay_rng
                )
                self._paid[i] = self.pay(i, k, switch, self._first[i], drawn)
                self._first[i] = False
            self._undrawn = []
        out = super().advance(max_duration_s, stop_on_decision)
        out.completions = [
            dataclasses.replace(c, task_time_s=self._paid[c.robot]) for c in out.completions
        ]
        return out


class TwinPaidArenaEnv(TavcArenaEnv):
    """`tavc_env.TavcArenaEnv` on `TwinPaidSimulation`: the physics env whose task times and
    rewards are the twin's.

    Args:
        tables: the arena's `InterferenceTables` (or their `to_dict()`).
        **env_kwargs: `TavcArenaEnv`'s arguments.
    """

    metadata: ClassVar[dict[str, Any]] = {**TavcArenaEnv.metadata, "name": TWIN_PAID_ENV_NAME}

    def __init__(self, tables: InterferenceTables | Mapping[str, Any], **env_kwargs: Any) -> None:
        self.tables = as_tables(tables)
        super().__init__(**env_kwargs)

    def _new_engine(self) -> Simulation:
        return TwinPaidSimulation(self.config, self.tables, self.options.jam_window_s)


def twin_paid_parallel_env(
    tables: InterferenceTables | Mapping[str, Any], **kwargs: Any
) -> TwinPaidArenaEnv:
    """The physics paid as the twin pays, as a PettingZoo ParallelEnv: `tables` plus
    `tavc_env.parallel_env`'s keyword arguments (see `TwinPaidArenaEnv`)."""
    return TwinPaidArenaEnv(tables, **kwargs)
