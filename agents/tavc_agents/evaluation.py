"""The suite's evaluation protocol, shared by the leaderboards and by anyone scoring an agent on
the scenarios: which episodes (a scenario's evaluation seeds and episode length), the metric (value
delivered per simulated hour), the committed references that normalise it (0 = random allocation,
1 = the model optimum), the interquartile mean with its stratified bootstrap interval (as rliable's),
and the allocators the leaderboard compares.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import json
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from tavc_agents.experiments.files import read_report
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.registry import REGISTRY
from tavc_agents.experiments.runner import TrialResult, env_arguments, run_trial
from tavc_agents.experiments.sweep import SweepError, TrialSpec, run_sweep
from tavc_agents.learners.network import READOUTS, declared_sets
from tavc_agents.model import CompletionModel, load_model
from tavc_agents.policy import Policy
from tavc_env.observations import OBSERVATION_MODES
from tavc_env.safe_files import atomic_path
from tavc_env.scenarios import SCENARIOS, ScenarioEnv
from tavc_env.validation import is_integer, is_number


# -- the episodes and the metric --------------------------------------------------------------------
def value_per_hour(result: TrialResult) -> float:
    """The suite's metric of one episode: delivered value (w at delivery) per simulated hour."""
    return float(sum(result.delivery_value)) / (result.end_s / 3600.0)


# -- normalisation and aggregation ---------------------------------------------------------------
def iqm(scores: Sequence[float]) -> float:
    """The interquartile mean: the mean of the middle half (scipy's 25 % trimmed mean)."""
    return float(stats.trim_mean(np.asarray(scores, dtype=float), 0.25))


def iqm_ci(
    groups: Sequence[Sequence[float]], resamples: int, rng: np.random.Generator
) -> tuple[float, float, float]:
    """The IQM of all scores of `groups` pooled, with a 95 % percentile bootstrap interval that
    resamples each group (scenario) on its own: stratified, as rliable's."""
    samples = [np.asarray(g, dtype=float) for g in groups]

    def pooled(*resampled: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.asarray(stats.trim_mean(np.concatenate(resampled, axis=axis), 0.25, axis=axis))

    point = float(stats.trim_mean(np.concatenate(samples), 0.25))
    if all(np.ptp(g) == 0 for g in samples):
        return point, point, point
    result = stats.bootstrap(
        samples,
        pooled,
        n_resamples=resamples,
        method="percentile",
        paired=False,
        vectorized=True,
        random_state=rng,
    )
    return point, float(result.confidence_interval.low), float(result.confidence_interval.high)


def references(path: Path) -> dict[str, dict[str, float]]:
    """The random and optimum value per hour of every scenario, from the committed references."""
    summary = read_report(path)["summary"]
    return {
        name: {"random": float(v["random_per_h"]), "optimum": float(v["optimum_per_h"])}
        for name, v in summary.items()
    }


def normalised(value: float, ref: Mapping[str, float]) -> float:
    """0 = random allocation, 1 = the model optimum (a scenario's entry of `references`)."""
    return (value - ref["random"]) / (ref["optimum"] - ref["random"])


# -- the allocators the leaderboard compares ------------------------------------------------------
@dataclass(frozen=True)
class Allocator:
    name: str  # the row's name in trial keys, tables and trials.csv
    label: str
    kwargs: Mapping[str, Any]
    registry: str = ""  # the allocator's registry name, if not `name`
    observation_mode: str | None = None  # the env's observation, if not its default

    @property
    def allocator(self) -> str:
        return self.registry or self.name


OWN_REWARD: Mapping[str, Any] = {"epsilon": 0.03, "recency": 0.2, "hysteresis": 0.0}
"""The own-reward learner's settings, chosen on training seeds (benchmarks/own_reward_search.py,
benchmarks/results/own_reward_search/)."""


def allocators(
    model: CompletionModel,
    networks: Mapping[str, Path] | None = None,
    plugins: Sequence[str] = (),
    *,
    rich: bool = False,
) -> list[Allocator]:
    """The allocators compared, in report order (the model-based ones get `model`; `networks`:
    trained networks by learning run; `plugins`: more allocators by registry name; `rich`: also
    the own-reward learner on the `rich` observation, reading the circuits' values from it)."""
    m = model.to_dict()
    extra = [Allocator(name, name, {"model": m} if takes_model(name) else {}) for name in plugins]
    trained = [
        Allocator(f"network_{run}", f"{run} (trained network)", {"weights": str(path)}, "network")
        for run, path in (networks or {}).items()
    ]
    return [
        Allocator("random", "random", {}),
        Allocator("stay", "stay (the start's circuits)", {}),
        Allocator("epsilon_tavc", "epsilon TAVC", {"epsilon": 0.1, "init": "scaled"}),
        Allocator("softmax_tavc", "softmax TAVC", {"temperature": 0.005, "init": "scaled"}),
        Allocator("own_reward", "own-reward learner", dict(OWN_REWARD)),
        *(
            [
                Allocator(
                    "own_reward_rich",
                    "own-reward learner (rich observation)",
                    {**OWN_REWARD, "values": "observed"},
                    "own_reward",
                    "rich",
                )
            ]
            if rich
            else []
        ),
        Allocator("response_threshold", "response threshold", {}),
        Allocator("auction", "auction", {"model": m}),
        Allocator("greedy", "greedy (model)", {"model": m}),
        Allocator("static", "static (model optimum)", {"model": m}),
        *trained,
        *extra,
    ]


def takes_model(name: str) -> bool:
    """Whether the factory of allocator `name` has a `model` parameter."""
    return "model" in inspect.signature(REGISTRY.get(name).factory).parameters


# -- scoring an agent: `evaluate` -------------------------------------------------------------------
PettingZooPolicy = Callable[[Mapping[str, Any], Mapping[str, Mapping[str, Any]]], Mapping[str, int]]
"""A policy as an RL researcher has one for the parallel env: `policy(observations, infos)` gives
an action for every robot whose info says `action_required` (others may be given and are ignored
while they are busy); an optional `policy.reset(seed)` is called before each episode."""

SUITE = "suite"
"""`evaluate(..., scenarios="suite")`: every scenario of `SCENARIOS`."""


class EvaluationError(ValueError):
    """An agent that cannot be evaluated, or that failed in an episode (the message names the
    scenario, the episode's seed and the robot)."""


@dataclass(frozen=True)
class Episode:
    """One evaluation episode: its scenario, seed, value per simulated hour and normalised score."""

    scenario: str
    seed: int
    value_per_hour: float
    score: float


@dataclass(frozen=True)
class Evaluation:
    """What `evaluate` measured: every episode, and per scenario (and over the suite, stratified by
    scenario) the IQM of the normalised scores with its 95 % percentile bootstrap interval."""

    name: str
    kind: str
    readout: str
    episode_h: float | None
    episodes: tuple[Episode, ...]
    iqm: Mapping[str, tuple[float, float, float]]
    suite: tuple[float, float, float] | None
    metadata: Mapping[str, Any]

    def scores(self, scenario: str) -> list[float]:
        return [e.score for e in self.episodes if e.scenario == scenario]

    def table(self) -> str:
        """The result as a Markdown table: IQM [95 % CI] per scenario, and the suite's."""
        rows = [
            "| scenario | episodes | IQM score [95 % CI] | mean value per hour |",
            "|---|---|---|---|",
        ]
        for name, (point, low, high) in self.iqm.items():
            values = [e.value_per_hour for e in self.episodes if e.scenario == name]
            rows.append(
                f"| {name} | {len(values)} | {point:.3f} [{low:.3f}, {high:.3f}] | "
                f"{float(np.mean(values)):,.0f} |"
            )
        if self.suite is not None:
            point, low, high = self.suite
            rows.append(
                f"| **suite** (stratified) | {len(self.episodes)} | "
                f"{point:.3f} [{low:.3f}, {high:.3f}] | |"
            )
        return "\n".join(rows)

    def to_row(self) -> dict[str, Any]:
        """The leaderboard row (`benchmarks/leaderboard.py --rows FILE`): plain JSON data."""
        return {
            "format": ROW_FORMAT,
            "name": self.name,
            "kind": self.kind,
            "readout": self.readout,
            "episode_h": self.episode_h,
            "episodes": [dataclasses.asdict(e) for e in self.episodes],
            "iqm": {k: list(v) for k, v in self.iqm.items()},
            "suite": None if self.suite is None else list(self.suite),
            "metadata": dict(self.metadata),
        }

    def save(self, path: str | Path) -> Path:
        """Write the leaderboard row to `path` (JSON, atomically: a kill leaves the old file or
        the new one, never half of one)."""
        with atomic_path(Path(path)) as tmp:
            tmp.write_text(json.dumps(self.to_row(), indent=1) + "\n", encoding="utf-8")
        return Path(path)


ROW_FORMAT = "tavc-leaderboard-row-1"


def read_row(path: str | Path) -> dict[str, Any]:
    """A leaderboard row written by `Evaluation.save` (checked: its format, and scores for
    scenarios of the suite on their evaluation seeds)."""
    data = read_report(Path(path))
    if not isinstance(data, dict) or data.get("format") != ROW_FORMAT:
        raise EvaluationError(
            f"{path} is not a leaderboard row; allowed: a file written by tavc evaluate --out "
            f"(format {ROW_FORMAT!r})"
        )
    for e in data["episodes"]:
        scenario = SCENARIOS.get(e["scenario"])
        if scenario is None or e["seed"] not in scenario.eval_seeds:
            raise EvaluationError(
                f"{path}: episode {e['scenario']!r} seed {e['seed']!r} is not an evaluation "
                "episode of the suite; allowed: a scenario of SCENARIOS on its eval_seeds"
            )
    return data


def scenario_list(scenarios: str | Sequence[str]) -> list[str]:
    """`scenarios` as names of `SCENARIOS`: one name, several, or `"suite"` for all."""
    names = (
        list(SCENARIOS)
        if scenarios == SUITE
        else [scenarios]
        if isinstance(scenarios, str)
        else list(scenarios)
    )
    unknown = [n for n in names if n not in SCENARIOS]
    if not names or unknown:
        raise EvaluationError(
            f"scenario {unknown[0] if unknown else names!r} is unknown; allowed: one or more of "
            f"{', '.join(SCENARIOS)}, or {SUITE!r}"
        )
    missing = [n for n in names if SCENARIOS[n].references is None]
    if missing:
        raise EvaluationError(f"scenario {missing[0]!r} has no committed references to score with")
    return names


def evaluate(
    agent: str | Path | Callable[..., Any],
    scenarios: str | Sequence[str] = SUITE,
    *,
    seeds: int | Sequence[int] | None = None,
    episode_h: float | None = None,
    params: Mapping[str, Any] | None = None,
    readout: str = "sampled",
    observation_mode: str | None = None,
    workers: int = 1,
    name: str | None = None,
    resamples: int = 10_000,
    bootstrap_seed: int = 0,
    progress: bool = False,
) -> Evaluation:
    """Score `agent` on the suite's evaluation protocol: each scenario's evaluation seeds (episode
    s is exactly `env.reset(seed=s)` on the scenario's env), its episode length and its metric,
    normalised with its committed references; IQM with a stratified bootstrap interval.

    `agent` is one of:
      - a registered allocator's name (`tavc_agents.experiments.registry`, plugins included;
        `params` are its parameters; the model-based ones get the scenario's TAVC model);
      - a saved network (`.npz` path, `Mlp.save`), read out `readout`: `"sampled"` (as a
        stochastic policy acts, from each robot's seeded generator) or `"greedy"`;
      - a `Policy` factory (a callable taking an agent's name, returning a `Policy`);
      - a PettingZoo-style policy (`PettingZooPolicy`: a callable taking `(observations,
        infos)`), run on the scenario's parallel env with its default observations.

    `seeds`: how many of each scenario's evaluation seeds (the first ones), or the seeds
    themselves (each an evaluation seed), default all. `episode_h`: shorter episodes than the
    scenario's (their scores are not the leaderboard's). `observation_mode`: the env's observation
    (`rich` adds the circuits' values; None: the default). `workers`: processes for a named
    allocator or a network (a callable runs in this process).
    """
    names = scenario_list(scenarios)
    plan = _episodes(names, seeds)
    if episode_h is not None and not (is_number(episode_h) and 0 < episode_h <= 24):
        raise EvaluationError(f"episode_h = {episode_h!r} is invalid; allowed: hours in (0, 24]")
    if not (is_integer(workers) and workers >= 1):
        raise EvaluationError(f"workers = {workers!r} is invalid; allowed: an integer >= 1")
    if not (is_integer(resamples) and resamples >= 100):
        raise EvaluationError(f"resamples = {resamples!r} is invalid; allowed: an integer >= 100")
    kind, label, run = _runner(agent, params, readout, names)
    started = time.process_time()
    if observation_mode is not None and observation_mode not in OBSERVATION_MODES:
        raise EvaluationError(
            f"observation_mode = {observation_mode!r} is invalid; allowed: None (the env's "
            f"default) or one of {list(OBSERVATION_MODES)}"
        )
    values = run(plan, episode_h, workers, progress, observation_mode=observation_mode)
    episodes = tuple(
        Episode(s, seed, v, SCENARIOS[s].score(v)) for (s, seed), v in zip(plan, values)
    )
    rng = np.random.default_rng(bootstrap_seed)
    per = {s: [e.score for e in episodes if e.scenario == s] for s in names}
    iqm_of = {s: iqm_ci([per[s]], resamples, rng) for s in names}
    suite = iqm_ci(list(per.values()), resamples, rng) if len(names) > 1 else None
    return Evaluation(
        name=name or label,
        kind=kind,
        readout=readout if kind == "network" else "as it acts",
        episode_h=episode_h,
        episodes=episodes,
        iqm=iqm_of,
        suite=suite,
        metadata=run_metadata(evaluation_cpu_s=round(time.process_time() - started, 2)),
    )


def _episodes(names: Sequence[str], seeds: int | Sequence[int] | None) -> list[tuple[str, int]]:
    plan = []
    for name in names:
        protocol = SCENARIOS[name].eval_seeds
        if seeds is None:
            chosen: Sequence[int] = protocol
        elif is_integer(seeds) and not isinstance(seeds, bool):
            if not 1 <= int(seeds) <= len(protocol):  # type: ignore[arg-type]
                raise EvaluationError(
                    f"seeds = {seeds!r} is invalid; allowed: 1 to {len(protocol)} (the number "
                    f"of {name}'s evaluation seeds), or a list of them"
                )
            chosen = protocol[: int(seeds)]  # type: ignore[arg-type]
        elif isinstance(seeds, Sequence) and len(seeds) >= 1:
            bad = [s for s in seeds if not is_integer(s) or s not in protocol]
            if bad:
                raise EvaluationError(
                    f"seed {bad[0]!r} of scenario {name!r} is invalid; allowed: its evaluation "
                    f"seeds {protocol[0]}..{protocol[-1]} (train on others)"
                )
            chosen = [int(s) for s in seeds]
        else:
            raise EvaluationError(
                f"seeds = {seeds!r} is invalid; allowed: None, a count, or a list of evaluation seeds"
            )
        plan += [(name, int(s)) for s in chosen]
    return plan


Runner = Callable[..., list[float]]


def _runner(
    agent: Any, params: Mapping[str, Any] | None, readout: str, names: Sequence[str]
) -> tuple[str, str, Runner]:
    """(kind, label, the function that runs a list of episodes) for `agent`; refused in one line
    before any episode when it cannot be run."""
    if readout not in READOUTS:
        raise EvaluationError(f"readout = {readout!r} is invalid; allowed: one of {list(READOUTS)}")
    if isinstance(agent, Path) or (isinstance(agent, str) and agent.endswith(".npz")):
        path = Path(agent)
        try:
            layers, group_of, _ = declared_sets(path)
        except (OSError, ValueError) as error:
            raise EvaluationError(f"network {path}: {error}") from error
        for name in names:
            config = SCENARIOS[name].config()
            inputs = config.n_circuits + config.n_robots
            if layers[0][1] != inputs or layers[-1][0] != config.n_circuits:
                raise EvaluationError(
                    f"network {path} takes {layers[0][1]} inputs and gives {layers[-1][0]} "
                    f"scores; scenario {name!r} needs {inputs} inputs (paper_id) and "
                    f"{config.n_circuits} scores: it was trained for another arena"
                )
            if group_of is not None and len(group_of) != config.n_robots:
                raise EvaluationError(
                    f"network {path} routes {len(group_of)} robots to its parameter sets; "
                    f"scenario {name!r} has {config.n_robots}: it was trained for another arena"
                )
        kwargs = {"weights": str(path), "readout": readout}
        return "network", path.stem, functools.partial(_run_named, "network", kwargs)
    if isinstance(agent, str):
        if agent not in REGISTRY.names():
            raise EvaluationError(
                f"allocator {agent!r} is unknown; allowed: one of {', '.join(REGISTRY.names())} "
                "(or a Policy factory, a PettingZoo-style policy, or a network's .npz)"
            )
        return "allocator", agent, functools.partial(_run_named, agent, dict(params or {}))
    if callable(agent):
        if params:
            raise EvaluationError("params are for a named allocator; allowed: none with a callable")
        label = getattr(agent, "__name__", type(agent).__name__)
        if _positional_parameters(agent) >= 2:
            return "pettingzoo policy", label, functools.partial(_run_pettingzoo, agent)
        return "policy factory", label, functools.partial(_run_factory, agent)
    raise EvaluationError(
        f"agent = {agent!r} is invalid; allowed: an allocator's name, a network's .npz path, a "
        "Policy factory or a PettingZoo-style policy(observations, infos)"
    )


def _positional_parameters(fn: Callable[..., Any]) -> int:
    try:
        signature = inspect.signature(fn)
    except (TypeError, ValueError):
        return 1
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return sum(p.kind in kinds for p in signature.parameters.values())


def _episode_s(scenario: str, episode_h: float | None) -> float:
    return SCENARIOS[scenario].episode_s if episode_h is None else float(episode_h) * 3600.0


def episode_env(scenario: str, observation_mode: str | None) -> dict[str, Any]:
    """The env arguments of an evaluation episode of `scenario`: the scenario, and the observation
    if one is chosen (None: the env's default)."""
    chosen = {} if observation_mode is None else {"observation_mode": observation_mode}
    return {"scenario": scenario, **chosen}


def episode_key(scenario: str, allocator: str, seed: int) -> str:
    """The trial key of evaluation episode `seed` of `scenario` for `allocator`."""
    return f"{scenario}__{allocator}__{seed}"


def episode_spec(
    scenario: str,
    seed: int,
    allocator: str,
    kwargs: Mapping[str, Any],
    episode_h: float | None,
    observation_mode: str | None = None,
) -> TrialSpec:
    """Evaluation episode `seed` of `scenario` for a named allocator, as a sweep's trial: the
    model-based allocators get the scenario's TAVC model at its start values; `observation_mode`
    (None: the env's default) is the env's observation."""
    s = SCENARIOS[scenario]
    kw = dict(kwargs)
    if takes_model(allocator) and "model" not in kw:
        values = [c.value for c in s.config().circuits]
        kw["model"] = load_model(s.model).with_values(values).to_dict()
    episode_s = _episode_s(scenario, episode_h)
    return TrialSpec(
        key=episode_key(scenario, allocator, seed),
        allocator=allocator,
        allocator_kwargs=kw,
        seed=seed,
        env_kwargs=episode_env(scenario, observation_mode),
        convergence_s=0.0,
        measured_s=episode_s,
        snapshot_every_s=episode_s,
        tags={"scenario": scenario, "allocator": allocator, "seed": seed},
    )


def _run_named(
    allocator: str,
    kwargs: Mapping[str, Any],
    plan: list[tuple[str, int]],
    episode_h: float | None,
    workers: int,
    progress: bool,
    observation_mode: str | None = None,
) -> list[float]:
    specs = [
        episode_spec(s, seed, allocator, kwargs, episode_h, observation_mode) for s, seed in plan
    ]
    with tempfile.TemporaryDirectory(prefix="tavc-evaluate-") as tmp:
        try:
            results = run_sweep(specs, tmp, workers=workers, progress_bar=progress)
        except SweepError as error:  # one line: the first failed episode and how many failed
            first = error.failures[0]
            raise EvaluationError(
                f"{allocator}, episode {first.key}: {first.error.strip().splitlines()[-1]} "
                f"({len(error.failures)} of {len(specs)} episodes failed)"
            ) from error
    return [value_per_hour(results[spec.key]) for spec in specs]


def _run_factory(
    factory: Callable[[str], Policy],
    plan: list[tuple[str, int]],
    episode_h: float | None,
    workers: int,
    progress: bool,
    observation_mode: str | None = None,
) -> list[float]:
    values = []
    for scenario, seed in plan:
        episode_s = _episode_s(scenario, episode_h)
        try:
            result = run_trial(
                factory,
                seed=seed,
                convergence_s=0.0,
                measured_s=episode_s,
                snapshot_every_s=episode_s,
                **env_arguments(episode_env(scenario, observation_mode)),
            )
        except Exception as error:
            raise EvaluationError(
                f"scenario {scenario!r}, episode {seed}: the policy failed: "
                f"{type(error).__name__}: {error}"
            ) from error
        values.append(value_per_hour(result))
    return values


def _run_pettingzoo(
    policy: PettingZooPolicy,
    plan: list[tuple[str, int]],
    episode_h: float | None,
    workers: int,
    progress: bool,
    observation_mode: str | None = None,
) -> list[float]:
    values = []
    for scenario, seed in plan:
        options = episode_env(scenario, observation_mode)
        options.pop("scenario")
        env = ScenarioEnv(scenario, max_sim_time_s=_episode_s(scenario, episode_h), **options)
        reset = getattr(policy, "reset", None)
        if callable(reset):
            reset(seed)
        observations, infos = env.reset(seed=seed)
        while env.agents:
            where = f"scenario {scenario!r}, episode {seed}, t = {env.sim_time_s:.1f} s"
            try:
                actions = policy(observations, infos)
            except Exception as error:
                raise EvaluationError(
                    f"{where}: the policy raised {type(error).__name__}: {error}"
                ) from error
            if not isinstance(actions, Mapping):
                raise EvaluationError(
                    f"{where}: the policy returned {type(actions).__name__}; allowed: a mapping "
                    "from robot name to circuit"
                )
            chosen = {}
            for robot in env.agents:
                if not infos[robot]["action_required"]:
                    continue
                if robot not in actions:
                    raise EvaluationError(
                        f"{where}: no action for {robot}, which must decide; allowed: a circuit "
                        f"in 0..{env.config.n_circuits - 1}"
                    )
                action = actions[robot]
                if not is_integer(action) or not 0 <= int(action) < env.config.n_circuits:
                    raise EvaluationError(
                        f"{where}: action {action!r} for {robot} is illegal; allowed: a circuit "
                        f"in 0..{env.config.n_circuits - 1}"
                    )
                chosen[robot] = int(action)
            observations, _, _, _, infos = env.step(chosen)
        values.append(float(env.episode_statistics()["value_per_hour"]))
    return values
