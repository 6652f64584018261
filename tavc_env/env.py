"""The PettingZoo adapter: wires the arena engine to agents, spaces, rewards and infos.

## tavc_arena_v1

| | |
|---|---|
| Agents | `robot_0 .. robot_{n-1}` (`dahl2004`: 0-2 fast at 0.30 m/s, 3-5 slow at 0.20 m/s); with `agent_names="speed_class"`, `fast_0 .. fast_2, slow_0 .. slow_2` |
| Action space | `Discrete(n_circuits)`: action `i` = serve circuit `i` next |
| Observation space | `observation_format="dict"` (default): `Dict(observation=Box(0, 1, (k,), float32), action_mask=Box(0, 1, (n_circuits,), int8))`; `"box"`: the `Box` alone, the mask in each info. `k` and the content depend on `observation_mode` (`tavc_env.observations`): `paper` (default, one-hot of the robot's last circuit), `paper_id`, `rich` |
| Reward | `w_i / t` when a task on circuit `i` completes (t from decision to delivery, in ms by default), else 0; `reward="value"`: `w_i` (see docs/semi_mdp.md) |
| Stepping | event-driven: each step runs until some robot completes a task (or `step_cap_s`); or every `decision_interval_s` |
| Infos | numbers and booleans only (every library can make tensors of them): `action_required`, `circuit`, `phase` (an integer code; its names are `PHASES`), `broken`, `task_completed` and `task_time_s` (0 when no task completed in the step; `completed_task_s(info)` reads both), `elapsed_s`, `sim_time_s`, `completed_tasks`, `jammed`; with `observation_format="box"` also `action_mask` |
| State | `state()`: per robot position, heading, velocity, circuit and phase; per station occupancy and line |

The mask allows every circuit to a robot that must decide; to a robot that need not, only the
circuit it serves (its action is ignored anyway). A learner may therefore ignore the mask.

Version history: v1 (this) made infos numeric (v0's `phase` was a name, its `task_time_s` None
when no task completed: TorchRL and BenchMARL could not make tensors of them) and added the
observation modes and formats. `tavc_env.v0` keeps v0 for saved work.

Robots that do not have to decide may be given any action (or none): it is ignored. A robot that
has to decide must be given a valid action, or `step` raises a ValueError and changes nothing. In
the AEC view (`env()`), the agent that is given a bad action gets the ValueError at once, and the
env is left as it was; so does a call out of order (before `reset`, after the end, for an unknown
agent: `OrderCheckingWrapper`).

## Copying

`copy.deepcopy(env)` and `pickle` of an env (before `reset`, or at any point of an episode) give an
env whose future is the original's, bit for bit: same observations, rewards, infos and positions for
the same actions. The copy does not copy the physics world: it rebuilds it by replaying the episode
from its `reset` (the generator as it was then, and every decision, breakdown, repair and value
change since, in order), and checks that the rebuilt arena equals the original before returning.
Copying therefore takes about as long as simulating the episode so far did. It has to: pymunk's
own copy of a space carries positions, velocities and cached contacts, but not the bodies' bias
velocities (the pushes that separate robots that touched in the last tick) nor the state of its
spatial index (which decides the order in which simultaneous contacts are solved), so a copy of
the world itself taken just after a contact drifted from the original by millimetres in its first
tick (tests/tavc_env/test_copy.py). Observers attached with `env.sim.add_observer` are copied
along (they do not see the replayed ticks). Copying `env.sim` on its own is exact in the same way;
a `Simulation` driven directly (not by an env) after its `reset`, or one changed behind its env's
back, cannot be copied: that raises a ValueError saying so.
"""

from __future__ import annotations

import copy
import copyreg
import hashlib
import math
import reprlib
import weakref
from array import array
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, Generic, TypeVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.env import AECEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper, OrderEnforcingWrapper
from pettingzoo.utils.wrappers.order_enforcing import (
    AECOrderEnforcingIterable,
    AECOrderEnforcingIterator,
)

from tavc_env.config import ArenaConfig
from tavc_env.engine.base import Advance, Engine
from tavc_env.engine.simulation import ArenaSnapshot, Simulation
from tavc_env.engine.tasks import PHASE_NAMES, Phase
from tavc_env.observations import (
    N_PHASES,
    ObservationBuilder,
    frozen,
    pose_features,
)
from tavc_env.options import (
    RENDER_MODES,
    TIME_UNITS,
    EnvOptions,
    agent_names,
    resolve_env_args,
)
from tavc_env.validation import is_integer, is_number, require

ENV_NAME = "tavc_arena_v1"
# The names of the `phase` codes in infos: PHASES[info["phase"]]
PHASES = tuple(PHASE_NAMES[p] for p in Phase)
_BROKEN = int(Phase.BROKEN)


E = TypeVar("E", bound=Engine)


class ArenaEnv(ParallelEnv[str, dict[str, np.ndarray], int], Generic[E]):
    """The PettingZoo adapter of any arena engine (`tavc_env.engine.base.Engine`): agents, spaces,
    stepping, rewards, infos, failures, priorities and copying, the same whatever the engine.

    A subclass says which engine (`_new_engine`) and what its global state is (`_state_space`,
    `state`, `snapshot`): `TavcArenaEnv` (the physics) and `tavc_env.twin.TwinArenaEnv` (the
    model twin). Arguments: `TavcArenaEnv`'s.
    """

    def __init__(
        self,
        preset: str | None = None,
        config: ArenaConfig | None = None,
        options: EnvOptions | None = None,
        **overrides: Any,
    ) -> None:
        self.config, self.options = resolve_env_args(preset, config, options, **overrides)
        self.render_mode = self.options.render_mode

        n, m = self.config.n_robots, self.config.n_circuits
        self.possible_agents = agent_names(self.config, self.options.agent_names)
        self.agents: list[str] = []
        self._index = {a: i for i, a in enumerate(self.possible_agents)}
        self._builder = ObservationBuilder(self.config, self.options.observation_mode)
        vector = self._builder.space
        space: spaces.Space[Any] = vector
        if self.options.observation_format == "dict":
            space = spaces.Dict(
                {"observation": vector, "action_mask": spaces.Box(0, 1, (m,), np.int8)}
            )
        self._observation_spaces = {a: space for a in self.possible_agents}
        self._action_spaces: dict[str, spaces.Space[Any]] = {
            a: spaces.Discrete(m) for a in self.possible_agents
        }
        # row c: only circuit c (a robot busy on c); row m: every circuit (a deciding robot)
        self._mask_rows = frozen(np.vstack([np.eye(m, dtype=np.int8), np.ones(m, np.int8)]))
        self._mask_views = list(self._mask_rows)
        self.state_space = self._state_space()
        self.sim: E = self._new_engine()
        self._rng: np.random.Generator | None = None
        self._history: _History | None = None  # what was done to the arena since reset
        self._value_plan: list[tuple[float, tuple[float, ...]]] = []  # (at_s, values), in order
        self.num_cycles = 0
        # of the task each robot completed this step (lists: read and written an item at a time)
        self._last_task_time = [math.nan] * n
        self._last_task_by_circuit = np.full((n, m), math.nan)  # (rich observations)
        # deliveries since reset, each counting w_i / max w (the paper's measure, summed)
        self.delivered_value = 0.0
        # deliveries since reset, each counting its circuit's value w when it was delivered (the
        # suite's metric, summed: value per hour is this over the episode's simulated hours)
        self.episode_value = 0.0
        self._last_task_value = [0.0] * n  # w paid for the task each robot completed this step
        self._paid_values: tuple[np.ndarray | None, list[float], float] = (None, [], 1.0)
        self._renderer: Any = None

    # -- PettingZoo API ------------------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Space[Any]:
        return self._observation_spaces[self._agent_index(agent, "agent")[1]]

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self._action_spaces[self._agent_index(agent, "agent")[1]]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, dict[str, Any]]]:
        require(
            seed is None or (is_integer(seed) and seed >= 0),
            "seed",
            seed,
            "None or an integer >= 0 (int or numpy integer; not bool, not float)",
        )
        require(
            options is None or isinstance(options, Mapping),
            "options",
            options,
            "None or a mapping (this env takes no reset options)",
        )
        if seed is not None or self._rng is None:
            self._rng, _ = seeding.np_random(None if seed is None else int(seed))
        # planned before the arena's reset, so that the arena's own history starts after it
        self._value_plan = self._plan_values(self._rng)
        self._history = _History(copy.deepcopy(self._rng))
        self.sim.reset(self._rng)
        _HISTORIES[self.sim] = self._history
        self.agents = self.possible_agents[:]
        self.num_cycles = 0
        self._last_task_time = [math.nan] * self.config.n_robots
        self._last_task_by_circuit[:] = math.nan
        self.delivered_value = 0.0
        self.episode_value = 0.0
        self._last_task_value = [0.0] * self.config.n_robots
        return self._observations(), self._infos(truncated=False)

    def step(
        self, actions: dict[str, Any]
    ) -> tuple[
        dict[str, dict[str, np.ndarray]],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        self._require_running()
        rewards, truncated = self.advance_choices(self._validate(actions))
        deciding = self.sim.tasks.needs_decision()  # once for the observations, masks and infos
        observations = self._observations(deciding)
        infos = self._infos(truncated, deciding)
        terminations = dict.fromkeys(self.agents, False)
        truncations = dict.fromkeys(self.agents, truncated)
        reward_of = dict(zip(self.agents, rewards))
        if truncated:
            self.agents = []
        return observations, reward_of, terminations, truncations, infos

    def advance_choices(self, choices: list[tuple[int, int]]) -> tuple[list[float], bool]:
        """The arena part of `step`, for adapters that build arrays themselves (`tavc_env.adapters.
        batched`): every `(robot, circuit)` choice of the deciding robots applied (in robot order,
        unchecked: the caller checked them), the arena advanced to the step's end, the values
        plan applied. Returns every robot's reward (n floats) and whether the episode is truncated;
        the step's observations, masks and infos are then `arena_arrays`."""
        self._require_running()
        history = self._recorder()
        for i, circuit in choices:
            self.sim.choose(i, circuit)
            history.choose(i, circuit)

        opts = self.options
        remaining = opts.max_sim_time_s - self.sim.time_s
        if opts.decision_interval_s is None:
            # an event-driven step also ends when the circuits' values change, so that every
            # delivery is paid at the values in force when it was made
            planned = self._value_plan[0][0] - self.sim.time_s if self._value_plan else math.inf
            duration, stop = min(opts.step_cap_s, remaining, planned), True
        else:
            duration, stop = min(opts.decision_interval_s, remaining), False
        out = self.sim.advance(duration, stop_on_decision=stop)
        history.advance(duration, stop)
        rewards = self._rewards(out)
        while self._value_plan and self._value_plan[0][0] <= self.sim.time_s + 1e-9:
            self.set_circuit_values(self._value_plan.pop(0)[1])
        self.num_cycles += 1
        truncated = (
            self.num_cycles >= opts.max_cycles or self.sim.time_s >= opts.max_sim_time_s - 1e-9
        )
        return rewards, truncated

    def _require_running(self) -> None:
        if not self.agents:
            raise ValueError("step() called on a finished episode; call reset() first")

    def _plan_values(self, rng: np.random.Generator) -> list[tuple[float, tuple[float, ...]]]:
        """The episode's planned priority changes, drawn at reset before the arena: `(at_s,
        values)` in time order, applied when simulated time reaches `at_s` (an event-driven step
        ends there). None here; a scenario with priority shifts plans them
        (`tavc_env.scenarios`)."""
        return []

    # -- what the engine decides ---------------------------------------------------------------
    def _new_engine(self) -> E:
        """The engine this env drives, for `self.config` and `self.options`."""
        raise NotImplementedError

    def _state_space(self) -> spaces.Box:
        """The space of `state()`."""
        raise NotImplementedError

    def state(self) -> np.ndarray:
        raise NotImplementedError

    def snapshot(self) -> ArenaSnapshot:
        """The arena now: positions, headings, targets, circuits, phases (copies)."""
        raise NotImplementedError

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            import gymnasium

            gymnasium.logger.warn(
                "render() called without a render_mode; pass render_mode='rgb_array' or 'human'"
            )
            return None
        if self._renderer is None:
            from tavc_env.render import Renderer  # pygame is an optional extra: import lazily

            self._renderer = Renderer(self.config, self.render_mode)
        frame: np.ndarray | None = self._renderer.draw(self.snapshot(), self.delivered_value)
        return frame

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # -- robot failure -------------------------------------------------------------------------
    def break_down(self, agent: str) -> None:
        """Robot `agent` breaks down now: it stops, leaves its line or dock, abandons its task and is
        taken off the floor until repaired. It stays in `agents` with `action_required` False."""
        i = self._agent_index(agent, "agent")[0]
        history = self._recorder()
        self.sim.break_down(i)
        history.break_down(i)

    def repair(self, agent: str) -> None:
        """Repair robot `agent`: it returns to the floor in the next step, which ends with it
        deciding (a decision epoch, like a scheduled repair)."""
        i, name = self._agent_index(agent, "agent")
        require(self.sim.broken()[i], "agent", name, "a robot that is broken")
        history = self._recorder()
        self.sim.schedule_repair(i)
        history.repair(i)

    def current_infos(self) -> dict[str, dict[str, Any]]:
        """Every agent's info as it stands now: what the last `reset` or `step` returned, with what
        was done to the arena since written in by the env itself (a robot broken down since has
        `action_required` False, `broken` True and the broken `phase`). For callers that act
        between steps, such as a trial applying a breakdown, so that no caller writes infos."""
        return self._infos(truncated=False)

    # -- the options, one by one (read-only: `options` holds them) -----------------------------
    @property
    def max_cycles(self) -> int:
        return self.options.max_cycles

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        # PettingZoo's parallel_api_test sets it; the options stay one validated value
        self.options = self.options.replace(max_cycles=value)

    @property
    def max_sim_time_s(self) -> float:
        return self.options.max_sim_time_s

    @property
    def decision_interval_s(self) -> float | None:
        return self.options.decision_interval_s

    @property
    def step_cap_s(self) -> float:
        return self.options.step_cap_s

    @property
    def reward_time_unit(self) -> str:
        return self.options.reward_time_unit

    @property
    def observation_mode(self) -> str:
        return self.options.observation_mode

    @property
    def observation_format(self) -> str:
        return self.options.observation_format

    # -- read-only views of the arena ----------------------------------------------------------
    @property
    def sim_time_s(self) -> float:
        """Simulated seconds since `reset`."""
        return self.sim.time_s

    @property
    def jams(self) -> int:
        """Jams the detector found since `reset` (see `jam_window_s`)."""
        return self.sim.jams

    @property
    def time_jammed_s(self) -> float:
        """Simulated time spent jammed since `reset`."""
        return self.sim.time_jammed_s

    @property
    def escapes(self) -> int:
        """Escape manoeuvres of stuck robots since `reset` (see `tavc_env.engine.navigation`)."""
        return self.sim.escapes

    # -- task priorities -----------------------------------------------------------------------
    @property
    def circuit_values(self) -> tuple[float, ...]:
        """The value `w_i` a delivery on each circuit earns now."""
        return tuple(float(w) for w in self.sim.tasks.values)

    def set_circuit_values(self, values: Any) -> None:
        """Change the circuits' values from now on (a priority change): deliveries completed after
        this call are paid with the new `w_i`. `reset` restores the configured values."""
        m = self.config.n_circuits
        ok = (
            isinstance(values, (list, tuple, np.ndarray))
            and len(values) == m
            and all(is_number(w) and w > 0 for w in values)
        )
        require(ok, "circuit values", values, f"a sequence of {m} finite values > 0")
        new_values = tuple(float(w) for w in values)
        history = self._recorder()
        self.sim.set_circuit_values(np.array(new_values))
        history.set_values(new_values)

    @property
    def value_plan(self) -> tuple[tuple[float, tuple[float, ...]], ...]:
        """The priority changes still to come this episode, `(at_s, values)` in time order (see
        `_plan_values`; empty outside scenarios with priority shifts)."""
        return tuple(self._value_plan)

    # -- copying (see the module's docstring) --------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_renderer"] = None  # a window or a pygame surface; drawn anew on the next render()
        state["_rng"] = self._rng is not None  # the rebuilt arena's own generator (__setstate__)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        # the copied engine (rebuilt by replay for the physics, `_rebuild_simulation`) carries
        # the copied episode: its generator is the env's, its history the copy's
        self._rng = self.sim.rng if state["_rng"] else None
        if self._history is not None:
            _HISTORIES[self.sim] = self._history

    def _recorder(self) -> _History:
        """The history of this episode, or a ValueError if the env was never reset."""
        if self._history is None or _HISTORIES.get(self.sim) is not self._history:
            raise ValueError(
                "the arena was used before reset() (or its simulation was replaced); "
                "allowed: call reset() first"
            )
        return self._history

    # -- helpers -------------------------------------------------------------------------------
    def _agent_index(self, agent: object, what: str) -> tuple[int, str]:
        if not isinstance(agent, str) or agent not in self._index:
            raise ValueError(f"{what} {agent!r} is unknown; allowed: {self.possible_agents}")
        return self._index[agent], agent

    def _validate(self, actions: object) -> list[tuple[int, int]]:
        """Check every action before touching the world, so bad input changes nothing."""
        require(
            isinstance(actions, dict), "actions", type(actions).__name__, "a dict agent -> action"
        )
        assert isinstance(actions, dict)
        for agent in actions:
            self._agent_index(agent, "action key")
        agents = self.possible_agents
        return [
            (i, self._circuit_of(agents[i], actions.get(agents[i])))
            for i in self.sim.tasks.needs_decision().nonzero()[0].tolist()
        ]

    def must_decide(self, agent: str) -> bool:
        """Whether `agent` has to be given an action in the next `step` (its info's
        `action_required`, before the episode ends)."""
        i, _ = self._agent_index(agent, "agent")
        return bool(self.agents) and bool(self.sim.tasks.needs_decision()[i])

    def check_action(self, agent: str, action: object) -> None:
        """Raise the ValueError `step` would raise for `agent`'s `action` (nothing if `agent` need
        not decide: its action would be ignored). Changes nothing."""
        if self.must_decide(agent):
            self._circuit_of(agent, action)

    def _circuit_of(self, agent: str, a: object) -> int:
        """The circuit index deciding robot `agent` chose, or a ValueError saying what is allowed."""
        m = self.config.n_circuits
        if type(a) is int and 0 <= a < m:  # the common case, without the checks' cost
            return a
        if a is None:
            raise ValueError(
                f"missing action for {agent}, which must decide; allowed: an integer in [0, {m - 1}]"
            )
        if isinstance(a, np.ndarray) and a.shape == ():
            a = a.item()
        require(
            is_integer(a) and 0 <= int(a) < m,  # type: ignore[call-overload]
            f"action of {agent}",
            a,
            f"an integer circuit index in [0, {m - 1}]",
        )
        return int(a)  # type: ignore[call-overload]

    def _rewards(self, out: Advance) -> list[float]:
        n = self.config.n_robots
        rewards = [0.0] * n
        self._last_task_time = times = [math.nan] * n
        self._last_task_value = paid = [0.0] * n
        if not out.completions:
            return rewards
        unit = TIME_UNITS[self.options.reward_time_unit]
        per_value = self.options.reward == "value"
        values, top = self._values_now()
        for c in out.completions:
            w = values[c.circuit]
            rewards[c.robot] += w if per_value else float(w / (c.task_time_s * unit))
            self.delivered_value += w / top
            self.episode_value += w
            paid[c.robot] = w
            times[c.robot] = float(c.task_time_s)
            self._last_task_by_circuit[c.robot, c.circuit] = float(c.task_time_s)
        return rewards

    def _values_now(self) -> tuple[list[float], float]:
        """The circuits' values now as Python floats, and the largest: read again only when the
        engine's values array is replaced (`set_circuit_values`, a reset)."""
        array, values, top = self._paid_values
        if array is not self.sim.tasks.values:
            array = self.sim.tasks.values
            values = [float(w) for w in array]
            top = max(values)
            self._paid_values = (array, values, top)
        return values, top

    def _observations(self, deciding: np.ndarray | None = None) -> dict[str, Any]:
        """Every agent's observation; `deciding`: `needs_decision()` if the caller has it."""
        vectors = self._builder.build(self.sim, self._last_task_by_circuit)
        if self.options.observation_format == "box":
            return {agent: vectors[self._index[agent]] for agent in self.agents}
        masks = self._masks(deciding)
        return {
            agent: {"observation": vectors[i], "action_mask": masks[i]}
            for agent in self.agents
            for i in (self._index[agent],)
        }

    def _masks(self, deciding: np.ndarray | None = None) -> list[np.ndarray]:
        """Every robot's action mask (`arena_arrays`), as shared read-only rows (none built per step)."""
        tasks = self.sim.tasks
        if deciding is None:
            deciding = tasks.needs_decision()
        rows, free = self._mask_views, self.config.n_circuits
        return [rows[free if d else c] for d, c in zip(_plain(deciding), _plain(tasks.circuit))]

    def _infos(
        self, truncated: bool, deciding: np.ndarray | None = None
    ) -> dict[str, dict[str, Any]]:
        """Every agent's info; `deciding`: `needs_decision()` if the caller has it. The fields of
        `arena_arrays`, from each array read once as Python numbers (a dict per agent made from
        `arena_arrays` costs 3x as much per step; tests/tavc_env/adapters/test_batched.py checks
        that the two agree)."""
        tasks = self.sim.tasks
        now = float(self.sim.time_s)
        if deciding is None:
            deciding = tasks.needs_decision()
        jammed = bool(self.sim.jammed)
        masks = self._masks(deciding) if self.options.observation_format == "box" else None
        required = [bool(d) and not truncated for d in _plain(deciding)]
        phases = _plain(tasks.phase)
        circuits = _plain(tasks.circuit)
        decided = _plain(tasks.decision_time)
        completed = _plain(tasks.completed)
        task_times = self._last_task_time
        task_values = self._last_task_value
        infos: dict[str, dict[str, Any]] = {}
        for agent in self.agents:
            i = self._index[agent]
            phase = phases[i]
            done = not math.isnan(task_times[i])
            infos[agent] = {
                "action_required": required[i],
                "circuit": circuits[i],
                "phase": phase,
                "broken": phase == _BROKEN,
                "task_completed": done,
                "task_time_s": task_times[i] if done else 0.0,
                "task_value": task_values[i] if done else 0.0,
                "elapsed_s": now - decided[i],
                "sim_time_s": now,
                "completed_tasks": completed[i],
                "jammed": jammed,
            }
            if masks is not None:
                infos[agent]["action_mask"] = masks[i]
        return infos

    def episode_statistics(self) -> dict[str, float]:
        """The episode so far: its delivered value (each delivery counting its circuit's value
        when delivered), simulated time, value per simulated hour (the suite's metric) and
        deliveries. `RecordEpisodeStatistics` puts it in every agent's info at the episode's last
        step (the plain env's infos hold only numbers, which the learning libraries' adapters turn
        into tensors)."""
        hours = self.sim.time_s / 3600.0
        return {
            "value": self.episode_value,
            "sim_time_s": float(self.sim.time_s),
            "value_per_hour": self.episode_value / hours if hours > 0 else math.nan,
            "deliveries": float(np.sum(self.sim.tasks.completed)),
        }


class TavcArenaEnv(ArenaEnv[Simulation]):
    """The prioritized transportation arena as a PettingZoo `ParallelEnv`.

    Args:
        preset: name of a preset configuration (`tavc_env.PRESETS`; None: `dahl2004`).
        config: a full `ArenaConfig` instead of a preset (giving both is a ValueError).
        options: the env's `EnvOptions` (time limits, stepping, reward unit, jam window,
            observation mode and format, render mode); None: the defaults.
        **overrides: fields of `ArenaConfig` (and the shorthands `speeds`, `values`) changed from
            the preset or config, and fields of `EnvOptions` changed from `options` (e.g.
            `decision_interval_s=5.0`, `render_mode="rgb_array"`); any other key is a ValueError
            naming it.

    `copy.deepcopy` and `pickle` of the env are exact at any point of an episode: they rebuild
    the arena by replaying the episode from its reset (see "Copying" in the module's docstring).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": ENV_NAME,
        "render_modes": list(RENDER_MODES),
        "render_fps": 10,
        "is_parallelizable": True,
    }

    def _new_engine(self) -> Simulation:
        return Simulation(self.config, jam_window_s=self.options.jam_window_s)

    def _state_space(self) -> spaces.Box:
        n, m = self.config.n_robots, self.config.n_circuits
        per_robot = 6 + m + N_PHASES
        size = n * per_robot + 2 * 2 * m
        low = np.zeros(size, np.float32)
        high = np.ones(size, np.float32)
        for i in range(n):
            low[i * per_robot + 2 : i * per_robot + 6] = -1.0
        return spaces.Box(low, high, (size,), np.float32)

    def state(self) -> np.ndarray:
        """Global state: per robot [x/W, y/H, cos h, sin h, vx/v, vy/v, circuit one-hot, phase
        one-hot]; per station [fraction of its bays occupied, line length / n_robots].
        Velocities are divided by the robot's top speed and clipped to [-1, 1] (contacts can
        briefly push a robot faster)."""
        if self._rng is None:
            raise ValueError("state() called before reset(); allowed: call reset() first")
        cfg = self.config
        sim = self.sim
        n, m = cfg.n_robots, cfg.n_circuits
        robots = np.zeros((n, 6 + m + N_PHASES), np.float32)
        robots[:, :6] = pose_features(sim, cfg, sim.speeds[:, None])
        robots[np.arange(n), 6 + sim.tasks.circuit] = 1.0
        robots[np.arange(n), 6 + m + sim.tasks.phase] = 1.0
        stations = np.array([[st.busy, len(st.line) / n] for st in sim.tasks.stations], np.float32)
        return np.concatenate([robots.ravel(), stations.ravel()])

    def snapshot(self) -> ArenaSnapshot:
        """The arena now: positions, headings, targets, circuits, phases (copies)."""
        return self.sim.snapshot()


def arena_arrays(envs: Sequence[ArenaEnv[Any]], truncated: Sequence[bool]) -> dict[str, np.ndarray]:
    """The observations, action masks and every info field of arenas `envs` now (envs of one
    kind, config and options), stacked over the arenas `(K, n, ...)`, each built once from the
    engines' arrays: what a batched view returns, the numbers of the dicts the plain env's
    `step` returns (`truncated[k]`: arena k's episode was truncated). The mask gives a robot
    that must decide every circuit, one that need not only the circuit it serves."""
    first = envs[0]
    n, m = first.config.n_robots, first.config.n_circuits
    sims = [env.sim for env in envs]
    tasks = [sim.tasks for sim in sims]
    deciding = np.array([t.needs_decision() for t in tasks], bool)
    circuit = np.array([t.circuit for t in tasks], np.int64)
    phase = np.array([t.phase for t in tasks], np.int64)
    task_time = np.array([env._last_task_time for env in envs])
    done = ~np.isnan(task_time)
    now = np.array([sim.time_s for sim in sims], float)[:, None]
    jammed = np.array([bool(sim.jammed) for sim in sims])[:, None]
    return {
        "observations": first._builder.stacked(
            sims, [env._last_task_by_circuit for env in envs], circuit
        ),
        "action_mask": first._mask_rows[np.where(deciding, m, circuit)],
        "action_required": deciding & ~np.array(truncated, bool)[:, None],
        "circuit": circuit,
        "phase": phase,
        "broken": phase == _BROKEN,
        "task_completed": done,
        "task_time_s": np.where(done, task_time, 0.0),
        "task_value": np.where(done, np.array([env._last_task_value for env in envs]), 0.0),
        "elapsed_s": now - np.array([t.decision_time for t in tasks], float),
        "sim_time_s": np.repeat(now, n, axis=1),
        "completed_tasks": np.array([t.completed for t in tasks], np.int64),
        "jammed": np.repeat(jammed, n, axis=1),
    }


def _plain(values: Any) -> list[Any]:
    """An engine's per-robot array (the physics) or list (the twin) as a list of Python
    numbers, read at once."""
    return values.tolist() if isinstance(values, np.ndarray) else values


def completed_task_s(info: Mapping[str, Any]) -> float | None:
    """The time of the task a robot completed in the step its `info` reports, or None if it
    completed none (read from v1's `task_completed`, or v0's None; None where neither is)."""
    t = info.get("task_time_s")
    if t is None or not info.get("task_completed", True):
        return None
    return float(t)


raw_env = TavcArenaEnv


def parallel_env(**kwargs: Any) -> TavcArenaEnv:
    """The arena as a PettingZoo ParallelEnv (see `TavcArenaEnv` for the arguments)."""
    return TavcArenaEnv(**kwargs)


class AecArenaEnv(parallel_to_aec_wrapper):
    """PettingZoo's conversion of the parallel env to AEC, checking each action as it is given.

    The bare conversion stores every action until the last agent of the cycle steps, then steps
    the parallel env: a bad action raised only then, at the wrong agent, and stayed stored, so
    every later step raised again. Here the agent that gives a bad action gets the ValueError at
    once and nothing is stored: the env is as it was, and a good action continues the cycle.
    """

    def __init__(self, arena: ArenaEnv[Any]) -> None:
        super().__init__(arena)
        self.arena = arena

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            require(action is None, f"action of {agent}", action, "None (the agent is done)")
        elif self.arena.must_decide(agent):
            m = self.arena.config.n_circuits
            allowed = f"an integer circuit index in [0, {m - 1}]"
            require(action is not None, f"action of {agent}", action, allowed)
            self.arena.check_action(agent, action)
        super().step(action)


class OrderCheckingWrapper(OrderEnforcingWrapper[str, dict[str, np.ndarray], int | None]):
    """PettingZoo's order enforcing, with the package's errors: `step`, `observe`, `last`,
    `agent_iter`, `state` and `render` before `reset`, an unknown agent, `step` or `last` after the
    episode ended (every agent done and stepped out) and a second agent from `agent_iter` without
    a `step` between each raise a ValueError saying what was called and what is allowed, where
    PettingZoo's own wrapper raises a bare AssertionError or KeyError, or only warns. A refused
    call changes nothing. After the end, `observe` still gives an agent's last observation."""

    def __init__(self, aec: AecArenaEnv) -> None:
        super().__init__(aec)
        self.arena = aec.arena

    def _require_reset(self, call: str) -> None:
        if not self._has_reset:
            raise ValueError(f"{call} called before reset(); allowed: call reset() first")

    def _require_running(self, call: str) -> None:
        self._require_reset(call)
        if not self.env.agents:
            raise ValueError(
                f"{call} called after the episode ended (every agent is done); "
                "allowed: call reset() first"
            )

    def step(self, action: int | None) -> None:
        self._require_running(f"step({reprlib.repr(action)})")
        self.env.step(action)
        self._has_updated = True  # only a step taken counts: a refused one can be given again

    def observe(self, agent: str) -> dict[str, np.ndarray] | None:
        self._require_reset(f"observe({reprlib.repr(agent)})")
        self.arena._agent_index(agent, "agent")
        return self.env.observe(agent)

    def last(
        self, observe: bool = True
    ) -> tuple[dict[str, np.ndarray] | None, float, bool, bool, dict[str, Any]]:
        self._require_running("last()")
        return self.env.last(observe)

    def agent_iter(self, max_iter: int = 2**63) -> AECOrderEnforcingIterable[str, Any, Any]:
        self._require_reset("agent_iter()")
        require(is_integer(max_iter) and max_iter >= 0, "max_iter", max_iter, "an integer >= 0")
        return _CheckedIterable(self, int(max_iter))

    def state(self) -> np.ndarray:
        self._require_reset("state()")
        return self.env.state()

    def render(self) -> np.ndarray | str | list[Any] | None:
        self._require_reset("render()")
        return self.env.render()


class _CheckedIterable(AECOrderEnforcingIterable[str, Any, Any]):
    def __iter__(self) -> _CheckedIterator:
        assert isinstance(self.env, OrderCheckingWrapper)
        return _CheckedIterator(self.env, self.max_iter)


class _CheckedIterator(AECOrderEnforcingIterator[str, Any, Any]):
    """`agent_iter`'s iterator: the next agent only after a `step` (a ValueError otherwise)."""

    def __next__(self) -> str:
        env = self.env
        assert isinstance(env, OrderCheckingWrapper)
        if not env.env.agents or self.iters_til_term <= 0:
            raise StopIteration
        if not env._has_updated:
            raise ValueError(
                f"the next agent of agent_iter() was asked for before step() of "
                f"{env.env.agent_selection}; allowed: call step() once for each agent it yields"
            )
        self.iters_til_term -= 1
        env._has_updated = False
        return env.env.agent_selection


def aec_view(arena: ArenaEnv[Any]) -> OrderCheckingWrapper:
    """The AEC view of a parallel arena env (this module's, a scenario's, v0's): PettingZoo's
    conversion, each action checked when it is given (`AecArenaEnv`), the order of calls checked
    with the package's errors (`OrderCheckingWrapper`)."""
    return OrderCheckingWrapper(AecArenaEnv(arena))


def env(**kwargs: Any) -> AECEnv[str, dict[str, np.ndarray], int | None]:
    """The arena as a PettingZoo AEC env: PettingZoo's conversion of the parallel env, with each
    action and the order of calls checked when they are given (see `aec_view`)."""
    return aec_view(parallel_env(**kwargs))


# -- copying an arena: rebuild by replay (see the module's docstring) --------------------------------
class _History:
    """What an env did to its arena since `reset`: the generator as it was just before the reset
    and every call that changed the arena since, in order. Enough to rebuild the arena exactly
    (`_rebuild_simulation`). Compact: three integers per call, runs of equal `advance` calls
    (fixed-interval stepping) counted in one entry."""

    CHOOSE, ADVANCE, BREAK_DOWN, REPAIR, VALUES = range(5)

    def __init__(self, start_rng: np.random.Generator) -> None:
        self.start_rng = start_rng
        self.ops = array("q")  # (code, a, b): CHOOSE robot circuit, ADVANCE stop count, ...
        self.durations = array("d")  # the duration of each ADVANCE entry
        self.values: list[tuple[float, ...]] = []  # the values of each VALUES entry

    def choose(self, robot: int, circuit: int) -> None:
        self.ops.extend((self.CHOOSE, robot, circuit))

    def advance(self, duration: float, stop_on_decision: bool) -> None:
        ops = self.ops
        if (
            len(ops) >= 3
            and ops[-3] == self.ADVANCE
            and ops[-2] == stop_on_decision
            and self.durations[-1] == duration
        ):
            ops[-1] += 1
        else:
            ops.extend((self.ADVANCE, int(stop_on_decision), 1))
            self.durations.append(duration)

    def break_down(self, robot: int) -> None:
        self.ops.extend((self.BREAK_DOWN, robot, 0))

    def repair(self, robot: int) -> None:
        self.ops.extend((self.REPAIR, robot, 0))

    def set_values(self, values: tuple[float, ...]) -> None:
        self.ops.extend((self.VALUES, len(self.values), 0))
        self.values.append(values)

    def replay(self, sim: Engine) -> None:
        """Do it all again to `sim`, which was just reset with a copy of `start_rng`."""
        ops, advances = self.ops, iter(self.durations)
        for k in range(0, len(ops), 3):
            code, a, b = ops[k], ops[k + 1], ops[k + 2]
            if code == self.CHOOSE:
                sim.choose(a, b)
            elif code == self.ADVANCE:
                duration = next(advances)
                for _ in range(b):
                    sim.advance(duration, stop_on_decision=bool(a))
            elif code == self.BREAK_DOWN:
                sim.break_down(a)
            elif code == self.REPAIR:
                sim.schedule_repair(a)
            else:
                sim.set_circuit_values(np.array(self.values[a]))


# The history of every arena an env drives, by arena (a registry rather than an attribute, so the
# engine knows nothing of it; an arena forgotten by everyone else leaves it).
_HISTORIES: weakref.WeakKeyDictionary[Engine, _History] = weakref.WeakKeyDictionary()
# Attributes of a Simulation that are not its state: code, caches of other attributes, links.
# (the generator is fed through its state; `_bitgen` is only where in memory that state lives)
_NOT_STATE = frozenset(
    {"config", "world", "_rng", "_bitgen", "_observers", "_tick_args", "_tick_loop", "_bound"}
)


def _arena_digest(sim: Simulation) -> str:
    """A digest of everything a simulation's future depends on: its generator, the robots' bodies
    (positions, velocities, on the floor or not) and every other attribute, walked generically so
    that state added to the engine later is covered too."""
    h = hashlib.blake2b(digest_size=20)
    world = sim.world
    for part in (world.positions(), world.velocities(), world.in_space):
        _feed(h, part, set())
    _feed(h, sim.rng, set())
    seen: set[int] = set()
    for name, value in sorted(vars(sim).items()):
        if name not in _NOT_STATE:
            h.update(name.encode())
            _feed(h, value, seen)
    return h.hexdigest()


def _feed(h: Any, value: object, seen: set[int]) -> None:
    if isinstance(value, np.ndarray):
        h.update(f"array{value.dtype.str}{value.shape}".encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, np.random.Generator):
        _feed(h, value.bit_generator.state, seen)
    elif value is None or isinstance(value, (bool, int, float, str, bytes, np.generic)):
        h.update(repr(value).encode())  # repr of a float is exact
    elif isinstance(value, dict):
        h.update(b"{")
        for key in sorted(value, key=repr):
            _feed(h, key, seen)
            _feed(h, value[key], seen)
    elif isinstance(value, (list, tuple)):
        h.update(f"({len(value)}".encode())
        for item in value:
            _feed(h, item, seen)
    elif callable(value) or id(value) in seen:
        pass  # compiled functions; an object already fed
    elif hasattr(value, "__dict__"):
        seen.add(id(value))
        h.update(type(value).__name__.encode())
        for name, item in sorted(vars(value).items()):
            if name != "config":
                h.update(name.encode())
                _feed(h, item, seen)
    else:
        h.update(repr(value).encode())


def _reduce_simulation(sim: Simulation) -> tuple[Any, ...]:
    """How `copy` and `pickle` take a Simulation: rebuilt from its config by replaying its history;
    observers restored after the replay (so they see none of it)."""
    history = _HISTORIES.get(sim)
    if history is None and _was_reset(sim):  # (never reset: a new one is the same)
        raise ValueError(
            "this Simulation cannot be copied or pickled: it was reset and driven directly, "
            "not by a tavc_env env, so there is no record of what was done to it, and "
            "pymunk's own copy of its physics world is not exact (it drops the bias "
            "velocities that separate robots after a contact, and the order in which "
            "contacts are solved); allowed: copy the env that drives it (copy.deepcopy(env), "
            "pickle), copy it before reset(), or build a new Simulation and reset it with a "
            "copy of the generator"
        )
    digest = "" if history is None else _arena_digest(sim)
    observers = list(getattr(sim, "_observers", []))
    return (
        _rebuild_simulation,
        (sim.config, sim.jam_window_s, history, digest),
        {"_observers": observers},
    )


def _was_reset(sim: Simulation) -> bool:
    try:
        return sim.rng is not None
    except ValueError:  # "no random generator yet"
        return False


def _rebuild_simulation(
    config: ArenaConfig, jam_window_s: float, history: _History | None, digest: str
) -> Simulation:
    sim = Simulation(config, jam_window_s=jam_window_s)
    if history is not None:
        sim.reset(copy.deepcopy(history.start_rng))
        history.replay(sim)
        if _arena_digest(sim) != digest:
            raise ValueError(
                "this arena cannot be copied: replaying its episode from reset did not give the "
                "arena it copies, so it was changed other than through its env (e.g. through "
                "env.sim directly: choose, advance, break_down, reset); allowed: drive the arena "
                "through the env's reset, step, break_down, repair and set_circuit_values only"
            )
        _HISTORIES[sim] = history
    return sim


copyreg.pickle(Simulation, _reduce_simulation)


class RecordEpisodeStatistics(BaseParallelWrapper):
    """A parallel env whose last step's infos carry the episode's statistics: every agent's info
    gets `"episode_statistics"` (`episode_statistics()`: delivered value, value per simulated
    hour, deliveries and, on a scenario, the normalised score), in the spirit of Gymnasium's
    `RecordEpisodeStatistics` (whose `"episode"` key it leaves alone).

        env = tavc_env.RecordEpisodeStatistics(tavc_env.scenarios.parallel_env("bad_start"))
    """

    def step(self, actions: dict[str, Any]) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        observations, rewards, terminations, truncations, infos = super().step(actions)
        ended = all(terminations.values()) or all(truncations.values())
        if ended and infos:
            statistics = self.unwrapped.episode_statistics()
            for info in infos.values():
                info["episode_statistics"] = dict(statistics)
        return observations, rewards, terminations, truncations, infos
