"""The trial runner: one env, one policy per robot, a convergence period and a measured period.

Shared by the benchmarks, the tests and researchers' own agents. It records what the analysis
needs and nothing the policies could see that they should not: the allocation timeline (every
change of a robot's current circuit, time-stamped), every delivery, and periodic snapshots of the
learners' Q-tables. The result is a plain, JSON-serialisable dataclass; the same seed gives the same
result.

Seeding: one `numpy.random.SeedSequence(seed)` is split into one stream for the env and one per
policy, so adding a robot does not change the others' random draws. On a scenario the seed is the
episode's: the env is reset with `seed` itself (`reset_seed`), so a trial with seed s runs exactly
the episode a user gets from `env.reset(seed=s)` on the scenario's env (the suite's evaluation
seeds mean one thing everywhere); on a preset the env's seed is drawn from its stream, as it was
when the committed preset trials were run.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

import tavc_env
from tavc_agents.driver import PolicyDriver
from tavc_agents.experiments.trial_result import (
    TrialResult as TrialResult,
)  # what run_trial returns
from tavc_agents.policy import Policy, Team
from tavc_env.arena import Arena, ArenaSpec, resolve_env_kwargs
from tavc_env.env import completed_task_s
from tavc_env.validation import is_integer, is_number, require

PolicyFactory = Callable[[str], Policy]
EVENT_KINDS = ("break_down", "repair", "set_values")


@dataclass(frozen=True)
class Event:
    """Something done to the arena during a trial at `at_s` simulated seconds: robot `robot` breaks
    down or is repaired, or the circuits' values become `values` (a priority change).

    The runner applies it at the first step boundary at or after `at_s` (event-driven steps end
    whenever some robot completes a task, every few seconds with six robots) and records the time
    it was applied.
    """

    at_s: float
    kind: str
    robot: int | None = None
    values: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        require(is_number(self.at_s) and self.at_s >= 0, "event.at_s", self.at_s, "a time >= 0 s")
        require(self.kind in EVENT_KINDS, "event.kind", self.kind, f"one of {list(EVENT_KINDS)}")
        if self.kind == "set_values":
            require(self.robot is None, "event.robot", self.robot, "None for set_values")
            values: Any = self.values  # whatever the caller gave; checked here
            ok = (
                isinstance(values, (Sequence, np.ndarray))
                and not isinstance(values, str)
                and len(values) >= 1
                and all(is_number(w) and w > 0 for w in values)
            )
            require(
                ok,
                "event.values",
                values,
                "a non-empty sequence of finite circuit values > 0 for set_values",
            )
            object.__setattr__(self, "values", tuple(float(w) for w in values))
        else:
            require(
                is_integer(self.robot) and self.robot is not None and self.robot >= 0,
                "event.robot",
                self.robot,
                f"a robot index >= 0 for {self.kind} (and no values)",
            )
            require(self.values is None, "event.values", self.values, f"None for {self.kind}")
            object.__setattr__(self, "robot", int(self.robot))  # type: ignore[arg-type]


def check_events(events: object, config: tavc_env.ArenaConfig, end_s: float) -> list[Event]:
    """`events` as a list, checked against the trial's arena and length before it starts: every
    robot in the team, one value per circuit, every event within the trial, and every repair
    after a breakdown of its robot (an earlier event or the arena's own schedule)."""
    ok = isinstance(events, (Sequence, np.ndarray)) and not isinstance(events, str)
    require(ok, "events", events, "a sequence of Event (tavc_agents.experiments.runner.Event)")
    assert isinstance(events, (Sequence, np.ndarray))
    n, m = config.n_robots, config.n_circuits
    checked = list(events)
    for k, event in enumerate(checked):
        require(
            isinstance(event, Event),
            f"events[{k}]",
            event,
            "an tavc_agents.experiments.runner.Event",
        )
        require(
            event.at_s < end_s,
            f"events[{k}].at_s",
            event.at_s,
            f"a time within the trial, [0, {end_s:g}) s (a later event would never happen)",
        )
        if event.kind == "set_values":
            assert event.values is not None
            require(
                len(event.values) == m,
                f"events[{k}].values",
                event.values,
                f"{m} circuit values (one per circuit)",
            )
            continue
        assert event.robot is not None
        require(
            event.robot < n, f"events[{k}].robot", event.robot, f"a robot index in [0, {n - 1}]"
        )
    # in the order the runner applies them (a stable sort by time); a scheduled breakdown of the
    # arena counts from its time on (whether its own repair came first is left to the run)
    broken: set[int] = set()
    for k, event in sorted(enumerate(checked), key=lambda item: item[1].at_s):
        robot = event.robot
        if event.kind == "break_down":
            broken.add(robot)
        elif event.kind == "repair":
            scheduled = {b.robot for b in config.breakdowns if b.at_s <= event.at_s}
            require(
                robot in broken | scheduled,
                f"events[{k}].robot",
                robot,
                "a robot broken down by an earlier event or a scheduled breakdown of the arena "
                f"(robots {', '.join(str(r) for r in sorted(broken | scheduled)) or 'none'})",
            )
            broken.discard(robot)
    return checked


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return repr(value)


def _factory_name(factory: Callable[..., Any]) -> str:
    """`module.name` of an env factory (of the function a `functools.partial` wraps)."""
    inner = getattr(factory, "func", factory)
    name = getattr(inner, "__qualname__", None) or type(inner).__name__
    module = getattr(inner, "__module__", None)
    return f"{module}.{name}" if module else str(name)


def env_arguments(env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """A plain mapping of env arguments (a `scenario`, or a `preset` or `config` and arena
    overrides; env options, mixed, as a sweep's `TrialSpec.env_kwargs` holds them) as `run_trial`'s
    keyword arguments `arena` (resolved by `tavc_env.resolve_arena`, which names any clash) and
    `options`; any other key is a ValueError naming it."""
    arena, option_kwargs = resolve_env_kwargs(env_kwargs)
    out: dict[str, Any] = {"arena": arena}
    base = option_kwargs.pop("options", None)
    if base is not None or option_kwargs:
        out["options"] = (base or tavc_env.EnvOptions()).replace(**option_kwargs)
    return out


def trial_streams(seed: int, n_agents: int) -> list[np.random.SeedSequence]:
    """A trial's random streams from its `seed`: the env's first, then one per agent."""
    return list(np.random.SeedSequence(seed).spawn(n_agents + 1))


def env_seed(stream: np.random.SeedSequence) -> int:
    """The seed a preset trial resets its env with, from the env's stream (`trial_streams(...)[0]`)."""
    return int(stream.generate_state(1)[0])


def reset_seed(seed: int, arena: Arena, n_agents: int) -> int:
    """The seed a trial with seed `seed` resets its env with: on a scenario, `seed` itself (the
    episode a user gets with `env.reset(seed=seed)`); on a preset, one drawn from the env's
    stream (`env_seed`)."""
    if arena.scenario is not None:
        return seed
    return env_seed(trial_streams(seed, n_agents)[0])


def run_trial(
    policies: Mapping[str, Policy] | PolicyFactory | Team,
    *,
    seed: int,
    convergence_s: float = 15 * 3600.0,
    measured_s: float = 5 * 3600.0,
    snapshot_every_s: float = 3600.0,
    label: str = "",
    progress: Callable[[float], None] | None = None,
    events: Sequence[Event] = (),
    on_step: Callable[[Any], None] | None = None,
    arena: ArenaSpec | Arena = None,
    options: tavc_env.EnvOptions | None = None,
    env_factory: Callable[..., Any] | None = None,
) -> TrialResult:
    """Run one trial and return what it recorded.

    `policies` maps every agent name to its policy, or is a factory called with each agent name,
    or is a `Team` (a centralised allocator, which also observes every robot's info each step).
    `events` (breakdowns, repairs, priority changes) are applied at their times. `on_step`, if
    given, is called with the env after every step (e.g. to render frames). `progress`, if given,
    is called with the simulated time after each step.

    `arena` says which arena, as `tavc_env.resolve_arena` takes it (the one place that resolves
    it and refuses clashes): a scenario (`"bad_start"`, `"tavc/bad_start-v0"` or a
    `tavc_env.Scenario`: its arena and its priority shifts), a preset name or an `ArenaConfig`, a
    plain mapping (`{"preset": "dahl2004", "dt": 0.05}`; overrides alone change `dahl2004`), or
    None (`dahl2004`). The env's `options` (`tavc_env.EnvOptions`) are the defaults unless given,
    except that the trial sets `max_sim_time_s` from the two periods (and lifts `max_cycles`):
    `options` must leave those two at their defaults. `env_arguments` turns a plain mapping of all
    of these (as a sweep's `TrialSpec.env_kwargs` holds them) into these arguments.

    `env_factory` (None: the arena's own env) builds the env instead, from `config=` and
    `options=`: e.g. `functools.partial(tavc_env.twin_parallel_env, tables=tables)` runs the trial
    on the model twin (`tavc_env.twin`; not for a scenario). A trial run on another factory records
    its name in `env_kwargs["env_factory"]`, so its result cannot pass for a physics trial.
    """
    for name, value in (("convergence_s", convergence_s), ("measured_s", measured_s)):
        require(is_number(value) and value >= 0, name, value, "a finite duration >= 0 s")
    require(
        measured_s + convergence_s > 0,
        "convergence_s + measured_s",
        measured_s + convergence_s,
        "a positive total duration",
    )
    require(
        measured_s == 0 or float(convergence_s) + float(measured_s) > float(convergence_s),
        "measured_s",
        measured_s,
        f"0, or a period the clock resolves after convergence_s = {convergence_s} (the measured "
        "window would be empty: refused before the convergence runs)",
    )
    require(
        is_number(snapshot_every_s) and snapshot_every_s > 0,
        "snapshot_every_s",
        snapshot_every_s,
        "a finite period > 0 s",
    )
    require(
        options is None or isinstance(options, tavc_env.EnvOptions),
        "options",
        options,
        "a tavc_env.EnvOptions or None",
    )
    chosen = options if options is not None else tavc_env.EnvOptions()
    reserved = sorted({"max_sim_time_s", "max_cycles"} & set(chosen.changed()))
    require(
        not reserved,
        "options",
        reserved,
        "no max_sim_time_s / max_cycles: the trial's length is convergence_s + measured_s",
    )
    require(
        env_factory is None or callable(env_factory),
        "env_factory",
        env_factory,
        "None (the arena's own env) or a callable taking config= and options=",
    )
    resolved = tavc_env.resolve_arena(arena)
    factory = None if env_factory is tavc_env.parallel_env else env_factory
    total = float(convergence_s + measured_s)
    env = resolved.parallel_env(
        chosen.replace(max_sim_time_s=total, max_cycles=10**9), factory=factory
    )
    agents = list(env.possible_agents)
    events = check_events(events, env.config, total)
    team = policies if isinstance(policies, Team) else None
    if team is not None:
        table: dict[str, Policy] = team.policies(list(agents), env.config)
    elif callable(policies) and not isinstance(policies, Mapping):
        table = {a: policies(a) for a in agents}
    else:
        assert isinstance(policies, Mapping)
        missing = sorted(set(agents) - set(policies))
        extra = sorted(set(policies) - set(agents))
        if missing or extra:
            raise ValueError(
                f"policies missing for {missing} and given for unknown agents {extra}; "
                f"allowed: one policy per agent {agents}"
            )
        table = dict(policies)

    _, *policy_seqs = trial_streams(seed, len(agents))
    n_actions = env.config.n_circuits
    for agent, seq in zip(agents, policy_seqs):
        table[agent].reset(np.random.default_rng(seq), n_actions)

    cfg = env.config
    # what the caller chose, as a sweep's TrialSpec.env_kwargs would hold it
    recorded = _jsonable({**resolved.kwargs, **chosen.changed()})
    if factory is not None:
        recorded["env_factory"] = _factory_name(factory)
    result = TrialResult(
        seed=seed,
        label=label,
        env_kwargs=recorded,
        agents=agents,
        speed_classes=[r.speed_class for r in cfg.robots],
        speeds=[r.speed for r in cfg.robots],
        values=[c.value for c in cfg.circuits],
        convergence_s=float(convergence_s),
        measured_s=float(measured_s),
        end_s=0.0,
        initial_circuits=[],
    )
    started = time.perf_counter()
    obs, infos = env.reset(seed=reset_seed(seed, resolved, len(agents)))
    result.initial_circuits = [infos[a]["circuit"] for a in agents]
    current = list(result.initial_circuits)
    driver = PolicyDriver({agent: table[agent] for agent in agents})
    index = {agent: i for i, agent in enumerate(agents)}
    rewards: dict[str, float] = {}
    next_snapshot = 0.0
    schedule = sorted(events, key=lambda e: e.at_s)
    while env.agents:
        now = infos[agents[0]]["sim_time_s"]
        while schedule and schedule[0].at_s <= now + 1e-9:
            infos = _apply(env, schedule.pop(0), infos, result, now)
        if team is not None:
            team.observe(infos, env.circuit_values)
        if now >= next_snapshot:
            _snapshot(result, table, now)
            next_snapshot += snapshot_every_s
        actions = driver.actions(obs, rewards, infos)
        for agent, action in actions.items():
            i = index[agent]
            if action != current[i]:
                current[i] = action
                result.changes.append((now, i, action))
        obs, rewards, _, _, infos = env.step(actions)
        result.steps += 1
        if not any(info["action_required"] for info in infos.values()) and env.agents:
            result.capped_steps += 1
        for i, agent in enumerate(agents):
            t = completed_task_s(infos[agent])
            if t is not None:
                result.delivery_time_s.append(infos[agent]["sim_time_s"])
                result.delivery_robot.append(i)
                result.delivery_circuit.append(infos[agent]["circuit"])
                result.delivery_task_time_s.append(t)
                result.delivery_value.append(infos[agent]["task_value"])  # w when delivered
        if progress is not None:
            progress(env.sim_time_s)
        if on_step is not None:
            on_step(env)
    result.end_s = env.sim_time_s
    result.escapes = env.escapes
    result.jams = env.jams
    result.jammed_s = env.time_jammed_s
    _snapshot(result, table, result.end_s)
    for agent in agents:
        stats = _learner_stats(table[agent])
        if stats:
            result.learner_stats[agent] = stats
    result.wall_s = time.perf_counter() - started
    return result


def _apply(
    env: Any, event: Event, infos: dict[str, dict[str, Any]], result: TrialResult, now: float
) -> dict[str, dict[str, Any]]:
    """Apply `event` to `env`; return the infos as they now stand (the env's own: a robot that
    breaks down no longer has to decide)."""
    if event.kind == "set_values":
        env.set_circuit_values(event.values)
        result.events.append((now, event.kind, list(event.values or ())))
        return infos
    assert event.robot is not None
    agent = env.possible_agents[event.robot]
    if event.kind == "break_down":
        env.break_down(agent)
        infos = env.current_infos()  # the env writes its own infos: this robot no longer decides
    else:
        env.repair(agent)
    result.events.append((now, event.kind, event.robot))
    return infos


def _snapshot(result: TrialResult, table: Mapping[str, Policy], now: float) -> None:
    tables = {a: p.q_table.tolist() for a, p in table.items() if hasattr(p, "q_table")}
    if tables:
        result.q_snapshots.append({"time_s": now, "q": tables})


def _learner_stats(policy: Policy) -> dict[str, Any]:
    if not hasattr(policy, "updates"):
        return {}
    updates = np.asarray(policy.updates)
    return {
        "updates": updates.tolist(),
        "never_updated": int((updates == 0).sum()),
        "choices": int(getattr(policy, "choices", 0)),
        "non_greedy_choices": int(getattr(policy, "non_greedy_choices", 0)),
    }
