"""The deep-MARL leaderboard: TorchRL MAPPO and IPPO (one actor shared by every robot) trained for
one budget of robot decisions on the paper's scenario and the three with the most headroom
(`dahl2004`, `passing`, `three_circuits`, `bad_start`), training seeds 0-4, then every final
network read out both ways on each scenario's evaluation seeds: sampled (as it was trained) and
greedy; interquartile means with bootstrap intervals over training seeds, beside `stay` and the
best allocator. Training needs the `marl` extra; the read-outs need numpy only.

Writes `deep_leaderboard.{md,csv,json}`, `deep_leaderboard.png`, every run under runs/, its
network under networks/ and its read-outs under readouts/ into a new run folder under runs/ (git
ignores it), `--out`, or with `--update-reference` benchmarks/results/deep_leaderboard/. Jobs
resume: a rerun into the same folder skips the saved runs and read-outs; `--max-jobs N` trains at
most N new runs (0: none), `--max-evaluations N` reads out at most N new (run, read-out) pairs
(0: none; both 0: only the report).

    python benchmarks/deep_leaderboard.py --update-reference --workers 2   # 40 runs, 80 read-outs
    python benchmarks/deep_leaderboard.py --update-reference --max-jobs 0  # read-outs of the saved networks
    python benchmarks/deep_leaderboard.py --quick                          # smoke run

The deep-MARL part of the leaderboard: TorchRL MAPPO and IPPO (one actor shared by every robot;
`tavc_agents.learners.torchrl_ppo`) trained on a scenario for one budget of robot decisions, then
run on the scenario's evaluation seeds through the trial runner, scored as the allocators'
leaderboard scores them (`benchmarks/leaderboard.py`).

Two kinds of job. A training job is one (algorithm, scenario, training seed) run: train on the
scenario's env (training seeds 0, 1, ...; the evaluation seeds are never seen), with a learning
curve (the greedy network on one training-side episode, `CURVE_SEED`, after every
`decisions / curve_points` decisions), then the final network greedily on the evaluation seeds of
its day (kept in its record; the report reads the read-out jobs instead). Each is saved as it
finishes with its network (`networks/<key>.npz`). A read-out job is one (run, read-out): the
saved network, unchanged, read out `sampled` (each robot draws an allowed circuit from the softmax
of the network's scores, from its own seeded generator: the policy streams `run_trial` gives it,
so an episode's draws are fixed by its seed) or `greedy` (the highest score), on the scenario's
evaluation seeds and on `choice_episodes` training-side episodes (seeds 0, 1, 2 by default: the
training seeds' range, never an evaluation seed). Read-out jobs are saved under readouts/ as they
finish, keyed `<run key>__<read-out>`, with a digest of the network file they read (a retrained
network is read out again). A rerun skips saved jobs of both kinds; the report renders from
whatever is saved, with N per cell.

Which read-out a learner is scored by: the one whose mean normalised score over the learner's runs
and their training-side episodes is the higher (a tie goes to `sampled`, the policy as trained);
the evaluation seeds never enter that choice. The report gives both read-outs' IQMs and the chosen
one's as the headline.

`--route smdp` trains with `tavc_agents.learners.smdp_ppo` instead (the semi-MDP contract: per-robot
GAE discounted by `--gamma-h` per simulated hour, decision rows only, MAPPO's critic on `state()`,
`--n-envs` arenas of the TorchRL-native batched env) and writes its own reference,
`deep_leaderboard_smdp` (the committed report stays the pettingzoo route's until a full rerun):

    python benchmarks/deep_leaderboard.py --route smdp --decisions 1000000 --update-reference

Its ablation's departures from the contract, `--discount step` (gamma per env step), `--rows all`
(every robot's row of every step in the batch) and `--parameters class` or `robot` (one actor per
speed class or per robot, saved as one network file of several sets, each robot read out with its
own), each write a reference of their own (`deep_leaderboard_smdp_per_step`,
`deep_leaderboard_smdp_all_rows`, `deep_leaderboard_smdp_per_class`, ...).

Training reward: `reward="value"` (docs/semi_mdp.md): a robot is paid its circuit's value at each
delivery, so the team's summed undiscounted return per hour is the evaluation metric itself;
the paper's `w / t` would reward short tasks quadratically instead. On the pettingzoo route,
discounting is TorchRL's per env step (event-driven steps, about one decision each), a variance knob, as the contract says.

The script is `benchmarks/deep_leaderboard.py`.
"""

from __future__ import annotations

import hashlib
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from tavc_agents.analysis.plots import count_ticks, subplots
from tavc_agents.analysis.reports import Report, markdown_table
from tavc_agents.evaluation import iqm_ci, normalised, references, value_per_hour
from tavc_agents.experiments.files import read_csv, read_report
from tavc_agents.experiments.runner import run_trial
from tavc_agents.experiments.study import (
    RESULTS_DIR,
    Outcome,
    ScoredSettings,
    at_least,
    positive,
    refuse_invalid,
    run_study,
)
from tavc_agents.experiments.sweep import json_jobs, saved_results
from tavc_agents.learners.network import Mlp, NetworkSet, NetworkTeam
from tavc_env.scenarios import SCENARIOS
from tavc_env.validation import is_number

ALGORITHMS = ("mappo", "ippo")  # as tavc_agents.learners.torchrl_ppo.ALGORITHMS (no torch here)
CREDITS = ("own", "team")  # as tavc_agents.learners.torchrl_ppo.CREDITS
PARAMETERS = ("shared", "class", "robot")  # as tavc_agents.learners.smdp_ppo.PARAMETERS
ROUTES = ("pettingzoo", "smdp")
"""pettingzoo: TorchRL's PettingZooWrapper, one env step per frame, GAE per env step
(`tavc_agents.learners.torchrl_ppo`; the committed report's); smdp: the TorchRL-native batched env
and PPO on the semi-MDP contract (`tavc_agents.learners.smdp_ppo`)."""
DEEP_SCENARIOS = ("dahl2004", "passing", "three_circuits", "bad_start")
"""The paper's scenario and the three with the most measured headroom."""
CURVE_SEED = 1_000
"""The learning curve's episode: a training-side seed, not an evaluation seed."""
REWARD_SCALE = 1e-3  # value rewards are about 2000 a delivery: networks see O(1)
READOUTS = ("sampled", "greedy")
"""How a saved network is read out (`NetworkTeam(readout=...)`): `sampled`, as it was trained (an
allowed circuit drawn from the softmax of its scores, from each robot's seeded generator), and
`greedy` (the highest score); in the report's order."""
READOUT_TEXT = {"sampled": "sampled (as trained)", "greedy": "greedy (argmax)"}
READOUT_COLOURS = {"sampled": "tab:green", "greedy": "tab:purple"}  # not the learners' C0, C1
FIGURE = "deep_leaderboard.png"
JOBS = "runs"
NETWORKS = "networks"
READOUT_JOBS_DIR = "readouts"
Row = dict[str, Any]
Network = Mlp | NetworkSet
"""A trained actor: one network for every robot, or parameter sets (`--parameters`)."""
DEFAULT_ENTROPY = 0.01  # smdp_ppo.PpoSettings' (checked by tests/benchmarks: one value)
LEARNER_TEXT = {"mappo": "MAPPO (centralised critic)", "ippo": "IPPO (decentralised critic)"}
ACTORS = {
    "shared": "one actor shared by every robot",
    "class": "one actor per speed class (ablation; one network file of the sets)",
    "robot": "one actor per robot (ablation; one network file of the sets)",
}
CREDIT_TEXT = {
    "own": "each robot on its own deliveries",
    "team": "each robot on the team's: the mean reward of the step, every robot alike",
}


@dataclass(frozen=True, kw_only=True)
class Settings(ScoredSettings):
    """The deep leaderboard's settings (its command line)."""

    reference: ClassVar = "deep_leaderboard"
    quick_sizes: ClassVar = {
        "seeds": 1,
        "decisions": 400,
        "batch": 200,
        "curve_points": 2,
        "eval_seeds": 2,
        "episode_h": 0.2,
        "resamples": 200,
        "choice_episodes": 1,
    }
    recorded_fields: ClassVar = (
        "algorithms scenarios seeds decisions batch epochs curve_points eval_seeds_text "
        "episode_text resamples seed credit choice_episodes route_text"
    )

    algorithms: tuple[str, ...] = ALGORITHMS
    """the learners: mappo (centralised critic), ippo (decentralised critic); both share one actor"""
    scenarios: tuple[str, ...] = DEEP_SCENARIOS
    """the scenarios (names in tavc_env.scenarios.SCENARIOS)"""
    seeds: int = 5
    """training seeds per (algorithm, scenario): 0, 1, ..."""
    decisions: int = 100_000
    """the budget: robot decisions of training per run (the same for every scenario)"""
    batch: int = 1_000
    """env steps per PPO batch"""
    epochs: int = 4
    """PPO passes over each batch"""
    credit: str = "own"
    """own: each robot is trained on its own deliveries; team: on the team's (the mean reward of
    the step, every robot alike)"""
    route: str = "pettingzoo"
    """pettingzoo (GAE per env step, every robot's row) or smdp (the semi-MDP contract: per-robot
    GAE discounted by gamma_h per simulated hour, decision rows only, MAPPO's critic on state())"""
    gamma_h: float = 0.1
    """smdp route: the discount per simulated hour"""
    n_envs: int = 16
    """smdp route: arenas stepped together"""
    arena_steps: int = 256
    """smdp route: env steps per arena per PPO batch (`batch` is the pettingzoo route's)"""
    discount: str = "time"
    """smdp route: time (gamma_h ** (tau / 3600), the contract) or step (gamma_step per env
    step: the ablation)"""
    gamma_step: float = 0.99
    """smdp route with discount=step: the discount per env step"""
    rows: str = "decisions"
    """smdp route: decisions (decision rows only, the contract) or all (every robot's row of
    every env step: the ablation)"""
    parameters: str = "shared"
    """smdp route: shared (one actor for every robot, the contract's runs), class (one set per
    speed class) or robot (one set per robot): the ablation, saved as one network file"""
    entropy: float = DEFAULT_ENTROPY
    """smdp route: the entropy bonus's coefficient (another value: a search's runs, in a
    reference folder of their own)"""
    curve_points: int = 10
    """learning-curve evaluations after the untrained one"""
    eval_seeds: int | None = None
    """evaluation seeds per scenario (default: all of the scenario's)"""
    episode_h: float | None = None
    """episode length of training and evaluation, simulated hours (default: the scenario's)"""
    choice_episodes: int = 3
    """training-side episodes per run on which both read-outs are scored to choose the headline
    read-out (seeds 0, 1, ...: the training seeds' range, never an evaluation seed)"""
    max_jobs: int | None = None
    """train at most this many runs not yet saved (0: none; default: all)"""
    max_evaluations: int | None = None
    """read out at most this many (run, read-out) pairs not yet saved (0: none; default: all);
    with --max-jobs 0 as well: only the report"""
    quick: bool = False
    """smoke run: 1 seed, 400 decisions, 2 evaluation seeds and 1 choice episode of 0.2 h"""

    def reference_name(self) -> str:
        # team-credit runs are the credit study's (docs/results/scenarios.md, "Own or team credit")
        name = "deep_credit" if self.credit == "team" else "deep_leaderboard"
        if self.route == "pettingzoo":
            return name
        # an ablation's runs share their keys with the contract's: a folder of their own
        step = "_per_step" if self.discount == "step" else ""
        rows = "_all_rows" if self.rows == "all" else ""
        sets = "" if self.parameters == "shared" else f"_per_{self.parameters}"
        bonus = "" if self.entropy == DEFAULT_ENTROPY else f"_entropy{self.entropy:g}"
        return f"{name}_{self.route}{step}{rows}{sets}{bonus}"

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                (
                    "algorithms",
                    len(self.algorithms) >= 1 and all(a in ALGORITHMS for a in self.algorithms),
                    f"one or more of {', '.join(ALGORITHMS)}",
                ),
                (
                    "scenarios",
                    len(self.scenarios) >= 1 and all(n in SCENARIOS for n in self.scenarios),
                    f"one or more of {', '.join(SCENARIOS)}",
                ),
                ("seeds", at_least(self.seeds, 1), "an integer >= 1"),
                ("decisions", at_least(self.decisions, 1), "an integer >= 1"),
                ("batch", at_least(self.batch, 2), "an integer >= 2 (env steps)"),
                ("epochs", at_least(self.epochs, 1), "an integer >= 1"),
                ("credit", self.credit in CREDITS, f"one of {', '.join(CREDITS)}"),
                ("route", self.route in ROUTES, f"one of {', '.join(ROUTES)}"),
                ("gamma_h", positive(self.gamma_h) and self.gamma_h <= 1, "a number in (0, 1]"),
                ("n_envs", at_least(self.n_envs, 1), "an integer >= 1"),
                ("arena_steps", at_least(self.arena_steps, 2), "an integer >= 2"),
                ("discount", self.discount in ("time", "step"), "time or step"),
                (
                    "gamma_step",
                    positive(self.gamma_step) and self.gamma_step <= 1,
                    "a number in (0, 1]",
                ),
                ("rows", self.rows in ("decisions", "all"), "decisions or all"),
                (
                    "parameters",
                    self.parameters in PARAMETERS
                    and (self.route == "smdp" or self.parameters == "shared"),
                    f"one of {', '.join(PARAMETERS)} on the smdp route; shared on pettingzoo",
                ),
                (
                    "entropy",
                    is_number(self.entropy)
                    and 0 <= self.entropy < 10
                    and (self.route == "smdp" or self.entropy == DEFAULT_ENTROPY),
                    f"a number in [0, 10) on the smdp route; {DEFAULT_ENTROPY} on pettingzoo",
                ),
                ("curve_points", at_least(self.curve_points, 1), "an integer >= 1"),
                ("eval_seeds", self.eval_seeds is None or at_least(self.eval_seeds, 1), ">= 1"),
                ("episode_h", self.episode_h is None or positive(self.episode_h), "hours > 0"),
                (
                    "choice_episodes",
                    at_least(self.choice_episodes, 1) and self.choice_episodes <= 1_000,
                    "an integer in 1..1000 (training-side seeds 0, 1, ...)",
                ),
                ("max_jobs", self.max_jobs is None or at_least(self.max_jobs, 0), "None or >= 0"),
                (
                    "max_evaluations",
                    self.max_evaluations is None or at_least(self.max_evaluations, 0),
                    "None or >= 0",
                ),
            ],
        )

    @property
    def eval_seeds_text(self) -> str:
        return "all" if self.eval_seeds is None else str(self.eval_seeds)

    @property
    def episode_text(self) -> str:
        return "scenario's" if self.episode_h is None else str(float(self.episode_h))

    @property
    def route_text(self) -> str:
        if self.route == "pettingzoo":
            return self.route
        ablation = "".join(f", {k} {v}" for k, v in self.ablation())
        return (
            f"{self.route} (gamma_h {self.gamma_h}, {self.n_envs} x {self.arena_steps} steps"
            f"{ablation})"
        )

    def ablation(self) -> tuple[tuple[str, Any], ...]:
        """The smdp route's settings that depart from the contract (none: the contract's)."""
        out: list[tuple[str, Any]] = []
        if self.discount == "step":
            out += [("discount", "step"), ("gamma_step", self.gamma_step)]
        if self.rows == "all":
            out.append(("rows", "all"))
        if self.parameters != "shared":
            out.append(("parameters", self.parameters))
        if self.entropy != DEFAULT_ENTROPY:
            out.append(("entropy", self.entropy))
        return tuple(out)

    def ppo(self) -> tuple[tuple[str, Any], ...]:
        """The smdp route's own settings of a run (none on the pettingzoo route)."""
        if self.route == "pettingzoo":
            return ()
        return (
            ("gamma_h", self.gamma_h),
            ("n_envs", self.n_envs),
            ("steps_per_batch", self.arena_steps),
            *self.ablation(),
        )


@dataclass(frozen=True)
class Run:
    """One training run and its evaluation (a job)."""

    algorithm: str
    scenario: str
    seed: int
    decisions: int
    batch: int
    epochs: int
    curve_every: int
    episode_s: float
    eval_seeds: tuple[int, ...]
    networks: str = ""
    """where the final network is written (`<networks>/<key>.npz`; not part of the record)"""
    credit: str = "own"
    """whose deliveries a robot is trained on (`Settings.credit`)"""
    route: str = "pettingzoo"
    """the learner's route (`ROUTES`)"""
    ppo: tuple[tuple[str, Any], ...] = ()
    """the smdp route's settings of `smdp_ppo.PpoSettings` (`Settings.ppo`)"""


def run_key(job: Run) -> str:
    return f"{job.scenario}__{job.algorithm}__seed{job.seed}"


def jobs(s: Settings, networks: Path) -> list[Run]:
    """Every run, in the order that keeps partial results balanced: the scenarios in pairs as
    given (the paper's and `passing` first), within a pair seed by seed, both scenarios at each
    seed and the algorithms alternating."""
    out = []
    pairs = [s.scenarios[k : k + 2] for k in range(0, len(s.scenarios), 2)]
    for pair in pairs:
        for seed in range(s.seeds):
            for name in pair:
                scenario = SCENARIOS[name]
                n = len(scenario.eval_seeds) if s.eval_seeds is None else s.eval_seeds
                hours = scenario.episode_s / 3600.0 if s.episode_h is None else s.episode_h
                for algorithm in s.algorithms:
                    out.append(
                        Run(
                            algorithm,
                            name,
                            seed,
                            s.decisions,
                            s.batch,
                            s.epochs,
                            max(1, s.decisions // s.curve_points),
                            float(hours) * 3600.0,
                            tuple(scenario.eval_seeds[:n]),
                            str(networks),
                            s.credit,
                            s.route,
                            s.ppo(),
                        )
                    )
    return out


def greedy_value(mlp: Network, scenario: str, seed: int, episode_s: float) -> float:
    """The network, greedy on every robot, for one episode of the scenario: value per hour."""
    return network_value(mlp, scenario, seed, episode_s, "greedy")


def network_value(mlp: Network, scenario: str, seed: int, episode_s: float, readout: str) -> float:
    """The network read out `readout` on every robot for episode `seed` of the scenario (the env
    reset with `seed`; a sampled robot draws from its policy stream of that trial): value per
    hour."""
    result = run_trial(
        NetworkTeam(mlp, readout=readout),
        seed=seed,
        convergence_s=0.0,
        measured_s=episode_s,
        snapshot_every_s=episode_s,
        arena={"scenario": scenario},
    )
    return value_per_hour(result)


def greedy_choices(mlp: Network, scenario: str) -> list[list[int]]:
    """Each robot's greedy circuit after serving each circuit: the network's whole policy (it sees
    its last circuit and its index only)."""
    config = SCENARIOS[scenario].config()
    agents = [f"robot_{i}" for i in range(config.n_robots)]
    robots = NetworkTeam(mlp).policies(agents, config)
    every = np.ones(config.n_circuits, np.int8)
    eye = np.eye(config.n_circuits)
    return [[robots[a].act(eye[c], every) for c in range(config.n_circuits)] for a in agents]


def run_training(job: Run) -> dict[str, Any]:
    """Train one run, evaluate it; its network is written beside the saved runs."""
    import torch  # the `marl` extra: only a process that trains needs it

    started, cpu0 = time.perf_counter(), time.process_time()
    torch.manual_seed(job.seed)
    torch.set_num_threads(1)  # one core per job: jobs run side by side
    curve: list[dict[str, Any]] = []
    curve_cpu = [0.0]  # CPU seconds of the curve's evaluations (not training)

    def on_batch(decisions: int, steps: int, mlp: Callable[[], Network]) -> None:
        due = not curve or decisions // job.curve_every > curve[-1]["decisions"] // job.curve_every
        if due or decisions >= job.decisions:
            cpu = time.process_time()
            value = greedy_value(mlp(), job.scenario, CURVE_SEED, job.episode_s)
            curve_cpu[0] += time.process_time() - cpu
            curve.append({"decisions": decisions, "steps": steps, "value_per_h": value})

    train = train_smdp if job.route == "smdp" else train_pettingzoo
    mlp, decisions, steps = train(job, on_batch)
    train_cpu = time.process_time() - cpu0 - curve_cpu[0]
    train_wall = time.perf_counter() - started
    values = [greedy_value(mlp, job.scenario, s, job.episode_s) for s in job.eval_seeds]
    if job.networks:
        folder = Path(job.networks)
        folder.mkdir(parents=True, exist_ok=True)
        mlp.save(folder / f"{run_key(job)}.npz")
    return {
        "decisions": decisions,
        "steps": steps,
        "curve": curve,
        "eval_values_per_h": values,
        "choices": greedy_choices(mlp, job.scenario),
        "train_wall_s": train_wall,
        "train_cpu_s": train_cpu,
        "curve_cpu_s": curve_cpu[0],
        "wall_s": time.perf_counter() - started,
        "cpu_s": time.process_time() - cpu0,
    }


OnBatch = Callable[[int, int, Callable[[], Network]], None]
"""After each batch (and before the first): decisions and env steps so far, and the network."""


def train_pettingzoo(job: Run, on_batch: OnBatch) -> tuple[Network, int, int]:
    """The pettingzoo route: `torchrl_ppo` on TorchRL's PettingZooWrapper of the scenario."""
    from tavc_agents.learners import torchrl_ppo
    from tavc_env.scenarios import ScenarioEnv

    env = torchrl_ppo.make_env(
        ScenarioEnv(
            job.scenario, observation_mode="paper_id", reward="value", max_sim_time_s=job.episode_s
        ),
        job.seed,
        REWARD_SCALE,
        job.credit,
    )
    return torchrl_ppo.train(
        env, job.algorithm, job.decisions, job.batch, on_batch, epochs=job.epochs
    )


def train_smdp(job: Run, on_batch: OnBatch) -> tuple[Network, int, int]:
    """The smdp route: `smdp_ppo` on the TorchRL-native batched env of the scenario, its
    arenas seeded from the run's seed."""
    import torch

    from tavc_agents.learners import smdp_ppo

    ppo = smdp_ppo.PpoSettings(
        algorithm=job.algorithm,
        credit=job.credit,
        epochs=job.epochs,
        reward_scale=REWARD_SCALE,
        **dict(job.ppo),
    )
    env = smdp_ppo.make_env(ppo, job.seed, scenario=job.scenario, max_sim_time_s=job.episode_s)
    untrained = smdp_ppo.make_learner(env, ppo)  # the curve's first point: the initial actor
    on_batch(0, 0, lambda: smdp_ppo.network(untrained.actor_net))
    torch.manual_seed(job.seed)  # training starts from the generator as it was: the same actor

    def after(p: smdp_ppo.Progress, learner: smdp_ppo.Learner) -> None:
        on_batch(p.decisions, p.steps, lambda: smdp_ppo.network(learner.actor_net))

    learner, progress = smdp_ppo.train(env, ppo, job.decisions, after)
    env.close()
    return smdp_ppo.network(learner.actor_net), progress.decisions, progress.steps


# runs saved before `credit` and `route` existed were all trained on their own deliveries, on the
# pettingzoo route
RUNS = json_jobs(
    run_training,
    run_key,
    unit="run",
    omit=("networks",),
    added={"credit": "own", "route": "pettingzoo", "ppo": []},
)


# -- the read-outs: each saved network evaluated both ways, without training ---------------------------
@dataclass(frozen=True)
class Readout:
    """One saved network read out one way (a job): on the scenario's evaluation seeds and on the
    training-side episodes that choose the headline read-out."""

    run: str
    """the run's key: its network is `<networks>/<run>.npz`"""
    scenario: str
    readout: str
    episode_s: float
    eval_seeds: tuple[int, ...]
    choice_seeds: tuple[int, ...]
    network: str
    """the digest of the network file (`file_digest`): a network trained again is read out again"""
    networks: str = ""
    """the folder of the networks (not part of the record)"""


def readout_key(job: Readout) -> str:
    return f"{job.run}__{job.readout}"


def file_digest(path: Path) -> str:
    """The first 16 hex digits of the SHA-256 of the file."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def choice_seeds(s: Settings) -> tuple[int, ...]:
    """The training-side episodes that choose the read-out: seeds 0, 1, ... (the training seeds'
    range; the scenarios' evaluation seeds are 10000 and up)."""
    return tuple(range(s.choice_episodes))


def readout_jobs(
    s: Settings, runs: Sequence[Run], results: Mapping[str, Any], networks: Path
) -> list[Readout]:
    """Both read-outs of every run whose training is saved with its network, in the runs' order
    (so partial results stay balanced), each run's `sampled` first."""
    out = []
    for job in runs:
        path = networks / f"{run_key(job)}.npz"
        if run_key(job) not in results or not path.is_file():
            continue
        digest = file_digest(path)
        for readout in READOUTS:
            out.append(
                Readout(
                    run_key(job),
                    job.scenario,
                    readout,
                    job.episode_s,
                    job.eval_seeds,
                    choice_seeds(s),
                    digest,
                    str(networks),
                )
            )
    return out


def run_readout(job: Readout) -> dict[str, Any]:
    """Read the saved network out `job.readout` on the evaluation seeds and the choice's
    training-side episodes; with its policy (every robot's probabilities after each circuit)."""
    started, cpu0 = time.perf_counter(), time.process_time()
    path = Path(job.networks) / f"{job.run}.npz"
    if file_digest(path) != job.network:
        raise ValueError(
            f"network file {path} changed since its read-out was planned (digest "
            f"{file_digest(path)}, not {job.network}); allowed: run the study again"
        )
    mlp = NetworkSet.load(path)
    evaluation = [
        network_value(mlp, job.scenario, seed, job.episode_s, job.readout)
        for seed in job.eval_seeds
    ]
    choice = [
        network_value(mlp, job.scenario, seed, job.episode_s, job.readout)
        for seed in job.choice_seeds
    ]
    return {
        "eval_values_per_h": evaluation,
        "choice_values_per_h": choice,
        "probabilities": policy_probabilities(mlp, job.scenario),
        "wall_s": time.perf_counter() - started,
        "cpu_s": time.process_time() - cpu0,
    }


def policy_probabilities(mlp: NetworkSet, scenario: str) -> list[list[list[float]]]:
    """Each robot's probability of each circuit after serving each circuit (`[robot][last][next]`,
    the softmax of the network's scores, every circuit allowed): the policy it was trained as,
    which `sampled` follows and whose argmax `greedy` takes."""
    config = SCENARIOS[scenario].config()
    n, m = config.n_robots, config.n_circuits
    out = []
    for robot in range(n):
        rows = []
        for last in range(m):
            x = np.concatenate([np.eye(m)[last], np.eye(n)[robot]])
            scores = mlp.mlp_of(robot).scores(x)
            p = np.exp(scores - scores.max())
            rows.append([round(float(v), 6) for v in p / p.sum()])
        out.append(rows)
    return out


EVALUATIONS = json_jobs(run_readout, readout_key, unit="read-out", omit=("networks",))


# -- the report ---------------------------------------------------------------------------------------
Evaluations = Mapping[str, Mapping[str, Any]]
"""Saved read-out results by `readout_key`."""


def readouts_of(job: Run, evaluations: Evaluations) -> dict[str, Mapping[str, Any]]:
    """The saved read-outs of a run, by read-out name."""
    found = {r: evaluations.get(f"{run_key(job)}__{r}") for r in READOUTS}
    return {r: v for r, v in found.items() if v is not None}


def rows_of(
    runs: Sequence[Run],
    results: Mapping[str, Mapping[str, Any]],
    refs: Mapping[str, Any],
    evaluations: Evaluations | None = None,
) -> list[Row]:
    """One row per saved run: for each read-out its mean value per hour and normalised score over
    the evaluation seeds (a run's score) and its mean score on the training-side choice episodes
    (None while that read-out is not saved), its decisions and its times."""
    rows = []
    for job in runs:
        result = results.get(run_key(job))
        if result is None:
            continue
        ref = refs[job.scenario]
        row: Row = {
            "scenario": job.scenario,
            "algorithm": job.algorithm,
            "seed": job.seed,
            "decisions": result["decisions"],
        }
        saved = readouts_of(job, evaluations or {})
        for readout in READOUTS:
            ev = saved.get(readout)
            value = None if ev is None else mean_value(ev)
            row[f"value_per_h_{readout}"] = value
            row[f"score_{readout}"] = None if value is None else normalised(value, ref)
            row[f"choice_score_{readout}"] = (
                None if ev is None else normalised(float(np.mean(ev["choice_values_per_h"])), ref)
            )
        row |= {
            "train_cpu_s": result["train_cpu_s"],
            "cpu_s": result["cpu_s"],
            "wall_s": result["wall_s"],
            "readout_cpu_s": sum(float(ev["cpu_s"]) for ev in saved.values()),
        }
        rows.append(row)
    return rows


def mean_value(result: Mapping[str, Any]) -> float:
    """A network's value per hour: its mean over the evaluation seeds."""
    return float(np.mean(result["eval_values_per_h"]))


def chosen_readout(choice_means: Mapping[str, float]) -> str:
    """The read-out a learner's own training-side episodes choose: the higher mean normalised
    score there; a tie goes to `sampled` (the policy as it was trained)."""
    return max(READOUTS, key=lambda r: choice_means[r])  # max keeps the first of equals


def cells(s: Settings, rows: Sequence[Row], rng: np.random.Generator) -> dict[str, dict[str, Any]]:
    """Per learner (`scenario/algorithm`) with both read-outs saved for some run: each read-out's
    IQM over those runs with its interval, the training-side means, the chosen read-out and its
    IQM (`iqm`, `ci`, `n`: the headline)."""
    summary: dict[str, dict[str, Any]] = {}
    for name in s.scenarios:
        for algorithm in s.algorithms:
            mine = [
                r
                for r in rows
                if (r["scenario"], r["algorithm"]) == (name, algorithm)
                and all(r[f"score_{ro}"] is not None for ro in READOUTS)
            ]
            if not mine:
                continue
            cell: dict[str, Any] = {"n": len(mine)}
            for readout in READOUTS:
                scores = [r[f"score_{readout}"] for r in mine]
                point, low, high = iqm_ci([scores], s.resamples, rng)
                cell[readout] = {"iqm": point, "ci": [low, high], "scores": scores}
            means = {ro: float(np.mean([r[f"choice_score_{ro}"] for r in mine])) for ro in READOUTS}
            chosen = chosen_readout(means)
            cell |= {
                "choice_mean": means,
                "readout": chosen,
                "iqm": cell[chosen]["iqm"],
                "ci": cell[chosen]["ci"],
            }
            summary[f"{name}/{algorithm}"] = cell
    return summary


def interval(cell: Mapping[str, Any]) -> str:
    return f"{cell['iqm']:.3f} [{cell['ci'][0]:.3f}, {cell['ci'][1]:.3f}]"


def reference_scores(path: Path) -> dict[str, dict[str, float]]:
    """The normalised score of `stay` and of the static model optimum per scenario (their mean
    value per hour over the evaluation seeds), from the committed references and the table
    beside them (`references.csv`)."""
    refs = references(path)
    table = list(read_csv(Path(path).with_suffix(".csv")))
    out = {}
    for name, ref in refs.items():
        mine = [row for row in table if row["scenario"] == name]
        out[name] = {
            key: normalised(float(np.mean([float(r[f"{key}_per_h"]) for r in mine])), ref)
            for key in ("stay", "static")
        }
    return out


def best_allocators(path: Path) -> dict[str, tuple[str, float]]:
    """The best allocator per scenario in the committed allocators' leaderboard (its IQM), if
    that leaderboard is committed; else nothing."""
    if not path.is_file():
        return {}
    summary = read_report(path)["summary"]
    best: dict[str, tuple[str, float]] = {}
    for allocator, cells_of in summary.items():
        if allocator == "deep":  # the deep learners shown beside the allocators (`--deep`)
            continue
        for name, cell in cells_of.items():
            if name != "suite" and (name not in best or cell["iqm"] > best[name][1]):
                best[name] = (allocator, float(cell["iqm"]))
    return best


def cost_plan(s: Settings, rows: Sequence[Row], n_jobs: int, evaluations: Evaluations) -> str:
    """The measured cost of a run and of a read-out, and what the whole study takes at that cost."""
    if not rows:
        return "No run is saved yet: no cost measured."
    per_1000 = {
        a: [1000.0 * r["train_cpu_s"] / r["decisions"] for r in rows if r["algorithm"] == a]
        for a in s.algorithms
    }
    run_cpu = float(np.mean([r["cpu_s"] for r in rows]))
    left = n_jobs - len(rows)
    text = ", ".join(
        f"{a} {np.mean(v):.2f} (range {min(v):.2f}-{max(v):.2f})" for a, v in per_1000.items() if v
    )
    out = (
        f"Measured cost (CPU seconds of training per 1000 decisions, over the saved runs): {text}. "
        f"A whole run (training, learning curve, its own greedy evaluation) took "
        f"{run_cpu / 60:.1f} CPU min on average, so the {n_jobs} runs take about "
        f"{n_jobs * run_cpu / 3600:.1f} CPU h. Saved: {len(rows)}; left: {left}, about "
        f"{left * run_cpu / 3600:.1f} CPU h, {left * run_cpu / 3600 / 2:.1f} h of wall time on 2 "
        "free cores (two runs side by side, each on one core)."
    )
    read = [float(v["cpu_s"]) for v in evaluations.values()]
    if read:
        wanted = len(READOUTS) * n_jobs
        out += (
            f" Read-outs (one network one way on the evaluation seeds and the training-side "
            f"episodes, no training): {len(read)} of {wanted} saved, "
            f"{np.mean(read) / 60:.2f} CPU min each on average, {sum(read) / 3600:.2f} CPU h in "
            f"all; left: {wanted - len(read)}, about {(wanted - len(read)) * np.mean(read) / 3600:.2f} "
            "CPU h."
        )
    return out


def report(
    s: Settings,
    runs: Sequence[Run],
    results: Mapping[str, Mapping[str, Any]],
    provenance: Mapping[str, Any],
    evaluations: Evaluations | None = None,
    readout_provenance: Mapping[str, Any] | None = None,
) -> Report:
    evaluations = evaluations or {}
    refs = references(s.references)
    rows = rows_of(runs, results, refs, evaluations)
    baselines = reference_scores(s.references)
    stay = {name: v["stay"] for name, v in baselines.items()}
    best = best_allocators(RESULTS_DIR / "leaderboard" / "leaderboard.json")
    summary = cells(s, rows, np.random.default_rng(s.seed))
    for row in rows:
        cell = summary.get(f"{row['scenario']}/{row['algorithm']}")
        row["readout_chosen"] = None if cell is None else cell["readout"]
    table: list[list[Any]] = []
    for name in s.scenarios:
        for algorithm in s.algorithms:
            trained = sum(1 for r in rows if (r["scenario"], r["algorithm"]) == (name, algorithm))
            c = summary.get(f"{name}/{algorithm}")
            b = best.get(name)
            table.append(
                [
                    SCENARIOS[name].id,
                    algorithm,
                    trained,
                    c["n"] if c else 0,
                    *(interval(c[ro]) if c else "-" for ro in READOUTS),
                    " / ".join(f"{c['choice_mean'][ro]:.3f}" for ro in READOUTS) if c else "-",
                    c["readout"] if c else "-",
                    f"**{interval(c)}** ({c['readout']})" if c else "-",
                    f"{stay[name]:.3f}",
                    f"{baselines[name]['static']:.3f}",
                    f"{b[0]} {b[1]:.3f}" if b else "-",
                ]
            )
    header = [
        "scenario",
        "learner",
        "N runs",
        "N read out",
        *(f"{READOUT_TEXT[ro]}: IQM score [95 % CI]" for ro in READOUTS),
        "training-side mean, sampled / greedy",
        "read-out chosen",
        "headline: chosen read-out's IQM [95 % CI]",
        "stay",
        "static optimum",
        "best allocator",
    ]
    machine = provenance.get("machine", {})
    seeds_note = (
        "the scenario's evaluation seeds"
        if s.eval_seeds is None
        else f"the first {s.eval_seeds} of the scenario's evaluation seeds"
    )
    choice = choice_seeds(s)
    body = "\n\n".join(
        [
            f"TorchRL {' and '.join(LEARNER_TEXT[a] for a in s.algorithms)}, {ACTORS[s.parameters]} "
            '(`paper_id` observations), trained with `reward="value"` '
            f"({CREDIT_TEXT[s.credit]}) for "
            f"{s.decisions:,} robot decisions per run (the same budget in every scenario; "
            f"{route_sentence(s)}, {s.epochs} epochs), training seeds "
            f"0-{s.seeds - 1}. Each final network is read out two ways, without training again: "
            "**sampled**, as it was trained (each robot draws an allowed circuit from the "
            "softmax of the network's scores, from its own seeded generator: the policy streams "
            "of the trial runner, so each episode's draws are fixed by its seed), and **greedy** "
            "(each robot takes the circuit of highest score). A run's score under a read-out is "
            "its network's mean normalised score (0 = random allocation, 1 = the model optimum; "
            f"the scenarios' committed references) over {seeds_note}, through the trial runner; "
            "a cell is the interquartile mean over training seeds [95 % percentile bootstrap, "
            f"{s.resamples} resamples]. The headline read-out of a learner is the one its own "
            f"training-side episodes choose: both read-outs are also run on {len(choice)} "
            f"episodes of seeds {choice[0]}-{choice[-1]} (the training seeds' range, never an "
            "evaluation seed), and the read-out with the higher mean score there over the "
            "learner's runs is chosen (a tie goes to sampled); the evaluation seeds do not enter "
            "the choice. `stay` and the static optimum (the model optimum at the start, held) "
            "are the references' mean scores; the best allocator is the committed allocators' "
            "leaderboard's best IQM, if it is committed.",
            markdown_table(header, table),
            verdicts(summary, stay),
            "Every saved run: its learning curve (the greedy network on one training-side "
            f"episode, seed {CURVE_SEED}: untrained, at its best and at its last checkpoint), "
            "its final network's score under each read-out on the evaluation seeds and on the "
            "training-side episodes, whether its greedy policy is `stay` (every robot goes back "
            "to the circuit it just served), and the probability with which its sampled policy "
            "stays (each robot's after each circuit: the mean, and the lowest and highest), and "
            "where the sampled policy sends the team in the long run (robots per circuit: each "
            "robot's chain over the circuit it just served, run from its start, as a share of "
            "its decisions):",
            runs_table(s, runs, results, refs, evaluations),
            cost_plan(s, rows, len(runs), evaluations),
            f"Machine: {machine.get('cpu_model', '?')}, {machine.get('cores', '?')} cores, "
            f"{machine.get('ram_gib', '?')} GiB ({machine.get('platform', '?')}). "
            f"Wall time of the saved runs: {sum(r['wall_s'] for r in rows) / 3600:.2f} h, CPU "
            f"time {sum(r['cpu_s'] for r in rows) / 3600:.2f} h (each run on one core)."
            + readout_note(evaluations, readout_provenance),
            f"Figure (`{FIGURE}`), top: learning curves, the greedy network's normalised score "
            f"on one training-side episode (seed {CURVE_SEED}) against the decisions of "
            "training (line: mean over seeds, band: range; only the final network is saved, so "
            "the curve is greedy only). Bottom: every final network's score on the evaluation "
            "seeds, sampled and greedy (dots: runs, bar: IQM; the chosen read-out marked *).",
            "What the networks learned (each robot's greedy circuit after serving each circuit, "
            "and in brackets the probability of each circuit that its sampled read-out draws "
            "from: the network's whole policy; seed 0 of each learner, or the first saved seed):",
            learned(s, runs, results, evaluations),
        ]
    )
    rep = Report("deep_leaderboard", "Deep MARL on the scenario suite", body, rows, summary)
    rep.figures.append((FIGURE, lambda path: draw(path, s, runs, results, refs, stay, summary)))
    return rep


def route_sentence(s: Settings) -> str:
    """How the runs were trained, in a few words of the report."""
    if s.route == "pettingzoo":
        return f"PPO batches of {s.batch} env steps"
    discount = (
        f"discounted by gamma_h = {s.gamma_h} per simulated hour"
        if s.discount == "time"
        else f"discounted by {s.gamma_step} per env step (ablation)"
    )
    rows = "decision rows only" if s.rows == "decisions" else "every row (ablation)"
    return (
        "the semi-MDP contract's PPO on the TorchRL-native batched env: per-robot GAE over its "
        f"decisions {discount}, {rows}, MAPPO's critic on state(); batches of {s.n_envs} "
        f"arenas x {s.arena_steps} env steps"
    )


def verdicts(summary: Mapping[str, Mapping[str, Any]], stay: Mapping[str, float]) -> str:
    """Which learners' intervals lie above `stay`, under each read-out and the chosen one."""

    def above(of: Callable[[Mapping[str, Any]], Mapping[str, Any]]) -> str:
        beats = [k for k, v in summary.items() if of(v)["ci"][0] > stay[k.partition("/")[0]]]
        return ", ".join(beats) if beats else "none"

    if not summary:
        return "No network is read out yet: no learner is compared with `stay`."
    return (
        "Learners whose interval lies above `stay` (with one seed the interval is a point): "
        f"by the chosen read-out, {above(lambda v: v)}; sampled, "
        f"{above(lambda v: v['sampled'])}; greedy, {above(lambda v: v['greedy'])}."
    )


def readout_note(evaluations: Evaluations, provenance: Mapping[str, Any] | None) -> str:
    if not evaluations:
        return ""
    cpu = sum(float(v["cpu_s"]) for v in evaluations.values())
    text = f" The saved read-outs took {cpu / 3600:.2f} CPU h (each on one core)"
    if provenance:
        commit = provenance.get("git", {}).get("commit", "?")
        text += (
            f"; the last session that ran some: `{provenance.get('command', '?')}` at commit "
            f"`{str(commit)[:12]}`, {provenance.get('timestamp_utc', '?')} "
            f"({READOUT_JOBS_DIR}/provenance.json)"
        )
    return text + "."


def runs_table(
    s: Settings,
    runs: Sequence[Run],
    results: Mapping[str, Mapping[str, Any]],
    refs: Mapping[str, Any],
    evaluations: Evaluations | None = None,
) -> str:
    """One row per saved run, by scenario, learner and seed: its (greedy) learning curve's start,
    best and end, its score under each read-out on the evaluation seeds and on the training-side
    episodes, its greedy policy, how often its sampled policy stays and where it sends the team
    in the long run."""
    table = []
    order = sorted(
        runs, key=lambda j: (s.scenarios.index(j.scenario), s.algorithms.index(j.algorithm), j.seed)
    )
    for job in order:
        result = results.get(run_key(job))
        if result is None:
            continue
        ref = refs[job.scenario]
        curve = [(p["decisions"], normalised(p["value_per_h"], ref)) for p in result["curve"]]
        best = max(curve, key=lambda point: point[1])
        choices = result["choices"]
        stays = all(row[c] == c for row in choices for c in range(len(row)))
        saved = readouts_of(job, evaluations or {})
        table.append(
            [
                job.scenario,
                job.algorithm,
                job.seed,
                f"{curve[0][1]:.2f}",
                f"{best[1]:.2f} at {best[0]:,}",
                f"{curve[-1][1]:.2f}",
                *(score_text(saved.get(ro), "eval_values_per_h", ref) for ro in READOUTS),
                *(score_text(saved.get(ro), "choice_values_per_h", ref) for ro in READOUTS),
                "stay" if stays else "moves",
                stay_probability(saved),
                long_run_text(saved, SCENARIOS[job.scenario]),
            ]
        )
    if not table:
        return "(no run saved yet)"
    header = [
        "scenario",
        "learner",
        "seed",
        "curve (greedy): untrained",
        "best (decisions)",
        "last",
        "score, sampled",
        "score, greedy",
        "training-side, sampled",
        "training-side, greedy",
        "greedy policy",
        "sampled P(stay): mean (min-max)",
        "sampled, long run: robots per circuit",
    ]
    return markdown_table(header, table)


def score_text(ev: Mapping[str, Any] | None, key: str, ref: Mapping[str, float]) -> str:
    """A saved read-out's mean normalised score over its episodes `key`; "-" if not saved."""
    return "-" if ev is None else f"{normalised(float(np.mean(ev[key])), ref):.3f}"


def long_run_share(
    probabilities: Sequence[Sequence[Sequence[float]]], starts: Sequence[int] | None
) -> np.ndarray:
    """Where the sampled policy sends the team in the long run: per circuit, the robots' summed
    share of decisions on it, each robot's chain over "the circuit it just served" (its
    probabilities after each circuit) run from its start circuit (uniform where the start is
    drawn), averaged over LONG_RUN_DECISIONS decisions (a Cesaro mean: defined for every chain,
    periodic or with several closed classes). A share of decisions, not of time."""
    total = np.zeros(len(probabilities[0]))
    for i, rows in enumerate(probabilities):
        move = np.asarray(rows, dtype=float)
        at = np.full(len(move), 1.0 / len(move))
        if starts is not None:
            at = np.eye(len(move))[starts[i]]
        mean = np.zeros(len(move))
        for _ in range(LONG_RUN_DECISIONS):
            at = at @ move
            mean += at
        total += mean / LONG_RUN_DECISIONS
    return total


LONG_RUN_DECISIONS = 2000


def policy_of(saved: Mapping[str, Mapping[str, Any]]) -> Any:
    """A run's whole sampled policy (each robot's probabilities after each circuit), which every
    read-out saves alike; None while none is saved."""
    return next((ev["probabilities"] for ev in saved.values()), None)


def long_run_text(saved: Mapping[str, Mapping[str, Any]], scenario: Any) -> str:
    """`long_run_share` of a run's saved read-out as "a / b / c" robots; "-" while none is
    saved."""
    probabilities = policy_of(saved)
    if probabilities is None:
        return "-"
    starts = dict(scenario.arena).get("start_circuits")
    return " / ".join(f"{x:.1f}" for x in long_run_share(probabilities, starts))


def stay_probability(saved: Mapping[str, Mapping[str, Any]]) -> str:
    """How likely the sampled policy goes back to the circuit it just served, over every robot
    and circuit: the mean, and the lowest and highest; "-" while no read-out is saved."""
    probabilities = policy_of(saved)
    if probabilities is None:
        return "-"
    stays = [p[c][c] for p in probabilities for c in range(len(p))]
    return f"{np.mean(stays):.2f} ({min(stays):.2f}-{max(stays):.2f})"


def learned(
    s: Settings,
    runs: Sequence[Run],
    results: Mapping[str, Mapping[str, Any]],
    evaluations: Evaluations | None = None,
) -> str:
    parts = []
    for name in s.scenarios:
        config = SCENARIOS[name].config()
        for algorithm in s.algorithms:
            saved = [j for j in runs if (j.scenario, j.algorithm) == (name, algorithm)]
            first = next((j for j in saved if run_key(j) in results), None)
            if first is None:
                continue
            choices = results[run_key(first)]["choices"]
            probabilities = policy_of(readouts_of(first, evaluations or {}))
            start = dict(SCENARIOS[name].arena).get("start_circuits")

            rows = [
                [
                    f"robot_{i}",
                    config.robots[i].speed_class,
                    "drawn" if start is None else start[i],
                    *(
                        choice_text(
                            choices[i][c], None if probabilities is None else probabilities[i][c]
                        )
                        for c in range(config.n_circuits)
                    ),
                    end_circuit(choices[i], None if start is None else start[i]),
                ]
                for i in range(config.n_robots)
            ]
            header = [
                "robot",
                "class",
                "start",
                *(f"after {c}: greedy (P sampled)" for c in range(config.n_circuits)),
                "greedy ends on",
            ]
            parts.append(
                f"**{SCENARIOS[name].id}, {algorithm}, seed {first.seed}** "
                f"(circuit values {[c.value for c in config.circuits]})\n\n"
                + markdown_table(header, rows)
            )
    return "\n\n".join(parts) if parts else "(no run saved yet)"


def choice_text(greedy: int, probabilities: Sequence[float] | None) -> str:
    """A robot's greedy circuit, with the probabilities its sampled read-out draws from."""
    if probabilities is None:
        return str(greedy)
    return f"{greedy} ({' '.join(f'{p:.2f}' for p in probabilities)})"


def end_circuit(choice: Sequence[int], start: int | None) -> str:
    """Where a robot following `choice` from `start` settles: a circuit, or a cycle."""
    if start is None:  # a start drawn at reset: where it can settle
        fixed = [c for c in range(len(choice)) if choice[c] == c]
        if len(fixed) == len(choice):
            return "stays on its start"
        return "/".join(str(c) for c in fixed) if fixed else "cycles"
    seen = [start]
    while choice[seen[-1]] not in seen:
        seen.append(choice[seen[-1]])
    loop = seen[seen.index(choice[seen[-1]]) :]
    return str(loop[0]) if len(loop) == 1 else "cycles " + "-".join(map(str, loop))


def draw(
    path: Path,
    s: Settings,
    runs: Sequence[Run],
    results: Mapping[str, Mapping[str, Any]],
    refs: Mapping[str, Any],
    stay: Mapping[str, float],
    summary: Mapping[str, Mapping[str, Any]] | None = None,
) -> None:
    """One column per scenario. Top: each learner's greedy learning curve, mean over seeds with
    the range as a band. Bottom: every final network's score on the evaluation seeds under each
    read-out (the learner's runs as dots, the IQM as a bar, the chosen read-out starred)."""
    summary = summary or {}
    n = len(s.scenarios)
    fig, axes = subplots(2, n, figsize=(3.4 * n, 6.2), squeeze=False)
    for k, name in enumerate(s.scenarios):
        ax, low = axes[0][k], axes[1][k]
        if not any(j.scenario == name and run_key(j) in results for j in runs):
            ax.text(0.5, 0.5, "no runs saved yet", transform=ax.transAxes, ha="center", fontsize=8)
        for algorithm in s.algorithms:
            curves = [
                results[run_key(j)]["curve"]
                for j in runs
                if (j.scenario, j.algorithm) == (name, algorithm) and run_key(j) in results
            ]
            if not curves:
                continue
            m = min(len(c) for c in curves)  # a curve's points fall at the same batches
            x = np.mean([[p["decisions"] for p in c[:m]] for c in curves], axis=0)
            y = np.array(
                [[normalised(p["value_per_h"], refs[name]) for p in c[:m]] for c in curves]
            )
            line = ax.plot(x, y.mean(axis=0), marker=".", label=f"{algorithm} (N={len(curves)})")
            ax.fill_between(x, y.min(axis=0), y.max(axis=0), alpha=0.2, color=line[0].get_color())
        ax.axhline(stay[name], color="k", lw=0.8, ls="--", label="stay")
        ax.axhline(0.0, color="grey", lw=0.5)
        ax.set_title(SCENARIOS[name].id, fontsize=9)
        ax.set_xlabel("decisions of training", fontsize=8)
        count_ticks(ax.xaxis)
        ax.set_ylabel(f"score, greedy (seed {CURVE_SEED})", fontsize=8)
        ax.legend(fontsize=7)
        draw_readouts(low, s, name, summary, stay[name])
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")


def draw_readouts(
    ax: Any, s: Settings, name: str, summary: Mapping[str, Mapping[str, Any]], stay: float
) -> None:
    """The final networks' scores under each read-out for one scenario (`summary`'s runs)."""
    labels, position = [], 0
    for algorithm in s.algorithms:
        cell = summary.get(f"{name}/{algorithm}")
        for readout in READOUTS:
            star = "*" if cell is not None and cell["readout"] == readout else ""
            labels.append(f"{algorithm}\n{readout}{star}")
            if cell is not None:
                scores = cell[readout]["scores"]
                x = position + np.linspace(-0.15, 0.15, len(scores))
                color = READOUT_COLOURS[readout]
                ax.scatter(x, scores, s=12, color=color, alpha=0.8)
                ax.hlines(cell[readout]["iqm"], position - 0.3, position + 0.3, color=color)
            position += 1
    if not any(f"{name}/{a}" in summary for a in s.algorithms):
        ax.text(0.5, 0.5, "no read-outs saved yet", transform=ax.transAxes, ha="center", fontsize=8)
    ax.axhline(stay, color="k", lw=0.8, ls="--", label="stay")
    ax.axhline(0.0, color="grey", lw=0.5)
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, fontsize=7)
    ax.set_xlim(-0.6, len(labels) - 0.4)
    ax.set_ylabel("score, evaluation seeds", fontsize=8)
    ax.set_title("final networks (* chosen)", fontsize=8)
    ax.legend(fontsize=7)


def run(settings: Settings) -> Outcome:
    """Train (or resume) the runs not yet saved (at most `max_jobs`), read out every saved
    network both ways not yet read out (at most `max_evaluations`; never training), then report
    everything saved."""
    s = settings.sized()
    out = s.out_dir()
    networks = out / NETWORKS
    every = jobs(s, networks)
    saved = saved_results(every, RUNS, out / JOBS)
    todo = [j for j in every if run_key(j) not in saved]
    todo = todo if s.max_jobs is None else todo[: s.max_jobs]
    if todo:
        _, provenance = s.run_jobs(todo, RUNS, JOBS, wall_of=lambda r: float(r["wall_s"]))
    else:
        provenance = _stored_provenance(out)
    results = saved_results(every, RUNS, out / JOBS)
    planned = readout_jobs(s, every, results, networks)
    read = saved_results(planned, EVALUATIONS, out / READOUT_JOBS_DIR)
    pending = [j for j in planned if readout_key(j) not in read]
    pending = pending if s.max_evaluations is None else pending[: s.max_evaluations]
    if pending:
        _, readout_provenance = s.run_jobs(
            pending,
            EVALUATIONS,
            READOUT_JOBS_DIR,
            provenance_in=READOUT_JOBS_DIR,
            wall_of=lambda r: float(r["wall_s"]),
        )
    else:
        readout_provenance = _stored_provenance(out / READOUT_JOBS_DIR, fallback=False)
    evaluations = saved_results(planned, EVALUATIONS, out / READOUT_JOBS_DIR)
    rep = report(s, every, results, provenance, evaluations, readout_provenance)
    # the header names the command that wrote this report: the runs' own when it trained some,
    # else this one's (it covers every scenario shown; provenance.json keeps the last training)
    written = rep.write(out, provenance if todo else _this_run(s))
    return Outcome(out, written, rep.body)


def _this_run(s: Settings) -> dict[str, Any]:
    from tavc_agents.experiments.provenance import run_metadata

    return run_metadata(settings=s.recorded())


def _stored_provenance(out: Path, fallback: bool = True) -> dict[str, Any]:
    from tavc_agents.experiments.provenance import load_provenance, run_metadata

    stored = load_provenance(out) if out.is_dir() else None
    return stored or (run_metadata(settings={}) if fallback else {})


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
