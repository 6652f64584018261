"""Team allocators: baselines that decide with more than one robot's own experience.

Each is an `tavc_agents.policy.Team`: it makes the robots' policies for a trial and keeps, through the
documented `observe` channel, what the environment publicly reports (each robot's current circuit,
whether it is broken, completed tasks, the circuits' values). A robot that must decide asks its
team. What each allocator is allowed to know beyond that is stated in its docstring:

* `StaticAllocator`: a fixed circuit per robot, by default the TAVC model's optimum.
* `GreedyAllocator`: the model's slot values given the current allocation (the paper's suggestion).
* `AuctionAllocator` (in `tavc_agents.allocators.market`) and `ResponseThresholdAllocator` (in
  `tavc_agents.allocators.threshold`) build on `TeamAllocator` here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tavc_agents.model import CompletionModel, SpeedClasses, as_model, robot_circuits
from tavc_agents.policy import Policy, allowed_actions, state_of
from tavc_env.config import ArenaConfig
from tavc_env.validation import is_integer, require


class TeamAllocator:
    """Shared machinery: per-robot member policies, the current allocation as announced by the
    members' own choices, and who is broken (from the infos).

    Subclasses implement `choose(robot, allowed)` and may override `setup`, `learn` and
    `on_observe`.
    """

    def __init__(self) -> None:
        self.agents: list[str] = []
        self.config: ArenaConfig | None = None
        self.classes = SpeedClasses((), (), ())
        self.current: list[int] = []
        self.broken: list[bool] = []
        self.values: list[float] = []
        self.now = 0.0
        self.rngs: list[np.random.Generator | None] = []
        self.n_actions = 0

    # -- the Team protocol ----------------------------------------------------------------------
    def policies(self, agents: list[str], config: ArenaConfig) -> dict[str, Policy]:
        self.agents = list(agents)
        self.config = config
        self.classes = SpeedClasses.of(config)
        n = len(agents)
        self.current = [-1] * n  # -1: has not chosen yet
        self.broken = [False] * n
        self.values = [c.value for c in config.circuits]
        self.rngs = [None] * n  # each member's own stream, set by its reset
        self.n_actions = config.n_circuits
        self.now = 0.0
        self.setup()
        return {agent: Member(self, i) for i, agent in enumerate(agents)}

    def observe(
        self, infos: Mapping[str, Mapping[str, Any]], circuit_values: Sequence[float]
    ) -> None:
        self.values = [float(w) for w in circuit_values]
        for i, agent in enumerate(self.agents):
            info = infos.get(agent)
            if info is not None:
                self.broken[i] = bool(info["broken"])
                self.now = float(info["sim_time_s"])
        self.on_observe(infos)

    # -- for subclasses -------------------------------------------------------------------------
    def setup(self) -> None:
        """Prepare for a trial (called once `agents`, `config` and `classes` are known)."""

    def on_observe(self, infos: Mapping[str, Mapping[str, Any]]) -> None:
        """React to the infos of a step (after `current`, `broken`, `values`, `now` are updated)."""

    def choose(self, robot: int, allowed: np.ndarray) -> int:
        raise NotImplementedError

    def learn(
        self, robot: int, previous: int, action: int, reward: float, info: Mapping[str, Any]
    ) -> None:
        """Robot `robot` completed a task on `action`, chosen when its last circuit was
        `previous`, and was paid `reward`."""

    def groups(self, exclude: int | None = None) -> list[list[int]]:
        """Robots per class on each circuit now, counting only working robots that have chosen,
        without robot `exclude`."""
        counts = [[0] * len(self.classes.labels) for _ in range(self.n_actions)]
        for j, (circuit, broken) in enumerate(zip(self.current, self.broken)):
            if j != exclude and circuit >= 0 and not broken:
                counts[circuit][self.classes.of_robot[j]] += 1
        return counts

    # -- called by the members ------------------------------------------------------------------
    def decide(self, robot: int, action_mask: np.ndarray) -> int:
        allowed = allowed_actions(action_mask)
        choice = int(self.choose(robot, allowed))
        require(
            choice in allowed,
            f"{type(self).__name__}'s choice for robot {robot}",
            choice,
            f"a circuit the action mask allows, {allowed.tolist()}",
        )
        self.current[robot] = choice
        return choice


class Member:
    """One robot's policy in a team: it defers every decision to the team."""

    def __init__(self, team: TeamAllocator, robot: int) -> None:
        self.team = team
        self.robot = robot

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        self.team.rngs[self.robot] = rng

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return self.team.decide(self.robot, action_mask)

    def update(
        self,
        observation: np.ndarray,
        action: int,
        reward: float,
        next_observation: np.ndarray,
        info: dict[str, Any],
    ) -> None:
        self.team.learn(self.robot, state_of(observation), action, reward, info)


class StaticAllocator(TeamAllocator):
    """Static allocation: every robot always serves one pre-assigned circuit.

    The pre-programmed system of Dahl, Mataric & Sukhatme (ICRA 2003, "Multi-robot task-allocation
    through vacancy chains"), set at the best a designer could choose: the TAVC model's optimal
    allocation (`model`, see `tavc_agents.model`), robots of each class filling circuit 0's places first.
    Or give `circuits`, one per robot. Knows: the model and every robot's speed class. It never
    adapts: a broken robot's place stays empty, and a priority change is ignored.
    """

    def __init__(
        self,
        model: CompletionModel | Mapping[str, Any] | None = None,
        circuits: Sequence[int] | None = None,
    ) -> None:
        super().__init__()
        require(
            (model is None) != (circuits is None),
            "static allocation",
            {"model": model is not None, "circuits": circuits},
            "exactly one of model= or circuits=",
        )
        if circuits is not None:
            require(
                isinstance(circuits, Sequence) and all(is_integer(c) and c >= 0 for c in circuits),
                "circuits",
                circuits,
                "one circuit index >= 0 per robot",
            )
        self.model = None if model is None else as_model(model)
        self.plan = None if circuits is None else [int(c) for c in circuits]

    def setup(self) -> None:
        n = len(self.agents)
        if self.model is not None:
            self.model.check_team(self.classes)
            self.plan = robot_circuits(self.model.optimum(), self.classes)
        assert self.plan is not None
        require(
            len(self.plan) == n and max(self.plan) < self.n_actions,
            "circuits",
            self.plan,
            f"{n} circuit indices in [0, {self.n_actions - 1}]",
        )

    def choose(self, robot: int, allowed: np.ndarray) -> int:
        assert self.plan is not None
        return self.plan[robot]


class GreedyAllocator(TeamAllocator):
    """Greedy allocation: a deciding robot takes the currently most valuable slot for it.

    Dahl, Mataric & Sukhatme (DARS 2004, section 6) propose as the better comparison "a greedy
    algorithm which always fills the currently most valuable slot". Robot r of class j, deciding
    while the other working robots form groups J_i on the circuits, serves the circuit with the
    largest slot value s_{i,J_i,j} = w_i (c_{i,J_i+j} - c_{i,J_i}) (Equation 1) under the current
    circuit values; ties go to the robot's current circuit, then the lowest index.

    Each choice is a best response in a game whose potential is the team's value rate, so repeated
    choices settle in an allocation no single move improves (a local optimum of the model).
    Knows: the model `c` (measured offline by `estimate_model` of `benchmarks/arena_runs.py`), every robot's class,
    the current allocation and the circuits' current values. It ignores the cost of switching.
    """

    def __init__(self, model: CompletionModel | Mapping[str, Any]) -> None:
        super().__init__()
        self.model = as_model(model)

    def setup(self) -> None:
        self.model.check_team(self.classes)

    def slot_values(self, robot: int) -> np.ndarray:
        """The value of robot `robot` joining each circuit's current group."""
        model = self.model.with_values(self.values)
        k = self.classes.of_robot[robot]
        return np.array(
            [model.slot_value(i, g, k) for i, g in enumerate(self.groups(exclude=robot))]
        )

    def choose(self, robot: int, allowed: np.ndarray) -> int:
        return prefer_current(self.slot_values(robot), allowed, self.current[robot])


def prefer_current(scores: np.ndarray, allowed: np.ndarray, current: int) -> int:
    """The allowed index with the highest score; ties go to `current`, then the lowest index."""
    best = scores[allowed].max()
    top = [int(a) for a in allowed if scores[a] >= best - 1e-12 * max(1.0, abs(best))]
    return current if current in top else top[0]
