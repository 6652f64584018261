"""The deep-MARL leaderboard: TorchRL MAPPO and IPPO (one actor shared by every robot) trained for
one budget of robot decisions on the paper's scenario and the three with the most headroom
(`dahl2004`, `passing`, `three_circuits`, `bad_start`), training seeds 0-4, then run greedily on
each scenario's evaluation seeds; interquartile means with bootstrap intervals over training seeds,
beside `stay` and the best allocator. It needs the `marl` extra.

Writes `deep_leaderboard.{md,csv,json}`, `deep_leaderboard.png`, every run under runs/ and its
network under networks/ into a new run folder under runs/ (git ignores it), `--out`, or with
`--update-reference` benchmarks/results/deep_leaderboard/. Runs resume: a rerun into the same
folder skips the saved runs; `--max-jobs N` runs at most N new ones (0: only the report).

    python benchmarks/deep_leaderboard.py --update-reference --workers 2   # 40 runs
    python benchmarks/deep_leaderboard.py --quick                          # smoke run

The deep-MARL part of the leaderboard: TorchRL MAPPO and IPPO (one actor shared by every robot;
`tavc_agents.learners.torchrl_ppo`) trained on a scenario for one budget of robot decisions, then
run greedily on the scenario's evaluation seeds through the trial runner, scored as the allocators'
leaderboard scores them (`benchmarks/leaderboard.py`).

A job is one (algorithm, scenario, training seed) run: train on the scenario's env (training seeds
0, 1, ...; the evaluation seeds are never seen), with a learning curve (the greedy network on one
training-side episode, `CURVE_SEED`, after every `decisions / curve_points` decisions), then the
final network on the evaluation seeds. Each job is saved as it finishes with its network
(`networks/<key>.npz`); a rerun skips saved jobs, and `--max-jobs` bounds how many new jobs one
session runs. The report renders from whatever jobs are saved, with N per cell.

Training reward: `reward="value"` (docs/semi_mdp.md): a robot is paid its circuit's value at each
delivery, so the team's summed undiscounted return per hour is the evaluation metric itself;
the paper's `w / t` would reward short tasks quadratically instead. Discounting is TorchRL's per
env step (event-driven steps, about one decision each), a variance knob, as the contract says.

The script is `benchmarks/deep_leaderboard.py`.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from tavc_agents.analysis.plots import count_ticks, subplots
from tavc_agents.analysis.reports import Report, markdown_table
from tavc_agents.evaluation import iqm_ci, references, value_per_hour
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
from tavc_agents.learners.network import Mlp, NetworkTeam
from tavc_env.scenarios import SCENARIOS

ALGORITHMS = ("mappo", "ippo")  # as tavc_agents.learners.torchrl_ppo.ALGORITHMS (no torch here)
CREDITS = ("own", "team")  # as tavc_agents.learners.torchrl_ppo.CREDITS
DEEP_SCENARIOS = ("dahl2004", "passing", "three_circuits", "bad_start")
"""The paper's scenario and the three with the most measured headroom."""
CURVE_SEED = 1_000
"""The learning curve's episode: a training-side seed, not an evaluation seed."""
REWARD_SCALE = 1e-3  # value rewards are about 2000 a delivery: networks see O(1)
FIGURE = "deep_leaderboard.png"
JOBS = "runs"
NETWORKS = "networks"
Row = dict[str, Any]
LEARNER_TEXT = {"mappo": "MAPPO (centralised critic)", "ippo": "IPPO (decentralised critic)"}
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
    }
    recorded_fields: ClassVar = (
        "algorithms scenarios seeds decisions batch epochs curve_points eval_seeds_text "
        "episode_text resamples seed credit"
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
    curve_points: int = 10
    """learning-curve evaluations after the untrained one"""
    eval_seeds: int | None = None
    """evaluation seeds per scenario (default: all of the scenario's)"""
    episode_h: float | None = None
    """episode length of training and evaluation, simulated hours (default: the scenario's)"""
    max_jobs: int | None = None
    """run at most this many jobs not yet saved (0: only the report; default: all)"""
    quick: bool = False
    """smoke run: 1 seed, 400 decisions, 2 evaluation seeds of 0.2 h"""

    def reference_name(self) -> str:
        # team-credit runs are the credit study's (docs/results/scenarios.md, "Own or team credit")
        return "deep_credit" if self.credit == "team" else "deep_leaderboard"

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
                ("curve_points", at_least(self.curve_points, 1), "an integer >= 1"),
                ("eval_seeds", self.eval_seeds is None or at_least(self.eval_seeds, 1), ">= 1"),
                ("episode_h", self.episode_h is None or positive(self.episode_h), "hours > 0"),
                ("max_jobs", self.max_jobs is None or at_least(self.max_jobs, 0), "None or >= 0"),
            ],
        )

    @property
    def eval_seeds_text(self) -> str:
        return "all" if self.eval_seeds is None else str(self.eval_seeds)

    @property
    def episode_text(self) -> str:
        return "scenario's" if self.episode_h is None else str(float(self.episode_h))


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
                        )
                    )
    return out


def greedy_value(mlp: Mlp, scenario: str, seed: int, episode_s: float) -> float:
    """The network, greedy on every robot, for one episode of the scenario: value per hour."""
    result = run_trial(
        NetworkTeam(mlp),
        seed=seed,
        convergence_s=0.0,
        measured_s=episode_s,
        snapshot_every_s=episode_s,
        arena={"scenario": scenario},
    )
    return value_per_hour(result)


def greedy_choices(mlp: Mlp, scenario: str) -> list[list[int]]:
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

    from tavc_agents.learners import torchrl_ppo
    from tavc_env.scenarios import ScenarioEnv

    started, cpu0 = time.perf_counter(), time.process_time()
    torch.manual_seed(job.seed)
    torch.set_num_threads(1)  # one core per job: jobs run side by side
    env = torchrl_ppo.make_env(
        ScenarioEnv(
            job.scenario, observation_mode="paper_id", reward="value", max_sim_time_s=job.episode_s
        ),
        job.seed,
        REWARD_SCALE,
        job.credit,
    )
    curve: list[dict[str, Any]] = []
    curve_cpu = [0.0]  # CPU seconds of the curve's evaluations (not training)

    def on_batch(decisions: int, steps: int, mlp: Callable[[], Mlp]) -> None:
        due = not curve or decisions // job.curve_every > curve[-1]["decisions"] // job.curve_every
        if due or decisions >= job.decisions:
            cpu = time.process_time()
            value = greedy_value(mlp(), job.scenario, CURVE_SEED, job.episode_s)
            curve_cpu[0] += time.process_time() - cpu
            curve.append({"decisions": decisions, "steps": steps, "value_per_h": value})

    mlp, decisions, steps = torchrl_ppo.train(
        env, job.algorithm, job.decisions, job.batch, on_batch, epochs=job.epochs
    )
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


# runs saved before `credit` existed were all trained on their own deliveries
RUNS = json_jobs(run_training, run_key, unit="run", omit=("networks",), added={"credit": "own"})


# -- the report ---------------------------------------------------------------------------------------
def rows_of(
    runs: Sequence[Run], results: Mapping[str, Mapping[str, Any]], refs: Mapping[str, Any]
) -> list[Row]:
    """One row per saved run: its mean value per hour and normalised score over the evaluation
    seeds (a run's score), its decisions and its times."""
    rows = []
    for job in runs:
        result = results.get(run_key(job))
        if result is None:
            continue
        value = mean_value(result)
        rows.append(
            {
                "scenario": job.scenario,
                "algorithm": job.algorithm,
                "seed": job.seed,
                "decisions": result["decisions"],
                "value_per_h": value,
                "score": normalised(value, refs[job.scenario]),
                "train_cpu_s": result["train_cpu_s"],
                "cpu_s": result["cpu_s"],
                "wall_s": result["wall_s"],
            }
        )
    return rows


def mean_value(result: Mapping[str, Any]) -> float:
    """A run's value per hour: its final network's mean over the evaluation seeds."""
    return float(np.mean(result["eval_values_per_h"]))


def normalised(value: float, ref: Mapping[str, float]) -> float:
    """0 = random allocation, 1 = the model optimum (the scenarios' committed references)."""
    return (value - ref["random"]) / (ref["optimum"] - ref["random"])


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
    for allocator, cells in summary.items():
        for name, cell in cells.items():
            if name != "suite" and (name not in best or cell["iqm"] > best[name][1]):
                best[name] = (allocator, float(cell["iqm"]))
    return best


def cost_plan(s: Settings, rows: Sequence[Row], n_jobs: int) -> str:
    """The measured cost of a run and what the whole study takes at that cost."""
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
    return (
        f"Measured cost (CPU seconds of training per 1000 decisions, over the saved runs): {text}. "
        f"A whole run (training, learning curve, evaluation) took {run_cpu / 60:.1f} CPU min on "
        f"average, so the {n_jobs} runs take about {n_jobs * run_cpu / 3600:.1f} CPU h. "
        f"Saved: {len(rows)}; left: {left}, about {left * run_cpu / 3600:.1f} CPU h, "
        f"{left * run_cpu / 3600 / 2:.1f} h of wall time on 2 free cores (two runs side by side, "
        "each on one core)."
    )


def report(
    s: Settings,
    runs: Sequence[Run],
    results: Mapping[str, Mapping[str, Any]],
    provenance: Mapping[str, Any],
) -> Report:
    refs = references(s.references)
    rows = rows_of(runs, results, refs)
    baselines = reference_scores(s.references)
    stay = {name: v["stay"] for name, v in baselines.items()}
    best = best_allocators(RESULTS_DIR / "leaderboard" / "leaderboard.json")
    rng = np.random.default_rng(s.seed)
    table: list[list[Any]] = []
    summary: dict[str, dict[str, Any]] = {}
    for name in s.scenarios:
        for algorithm in s.algorithms:
            scores = [
                r["score"] for r in rows if (r["scenario"], r["algorithm"]) == (name, algorithm)
            ]
            if scores:
                point, low, high = iqm_ci([scores], s.resamples, rng)
                cell = f"{point:.3f} [{low:.3f}, {high:.3f}]"
                summary[f"{name}/{algorithm}"] = {"iqm": point, "ci": [low, high], "n": len(scores)}
            else:
                cell = "-"
            b = best.get(name)
            table.append(
                [
                    SCENARIOS[name].id,
                    algorithm,
                    len(scores),
                    cell,
                    f"{stay[name]:.3f}",
                    f"{baselines[name]['static']:.3f}",
                    f"{b[0]} {b[1]:.3f}" if b else "-",
                ]
            )
    header = [
        "scenario",
        "learner",
        "N seeds",
        "IQM score [95 % CI]",
        "stay",
        "static optimum",
        "best allocator",
    ]
    beats = [k for k, v in summary.items() if v["ci"][0] > stay[k.partition("/")[0]]]
    verdict = (
        "Learners whose interval lies above `stay` (with one seed the interval is a point): "
        + ", ".join(beats)
        + "."
        if beats
        else "No deep learner's interval lies above `stay` in any scenario so far."
    )
    machine = provenance.get("machine", {})
    seeds_note = (
        "the scenario's evaluation seeds"
        if s.eval_seeds is None
        else f"the first {s.eval_seeds} of the scenario's evaluation seeds"
    )
    body = "\n\n".join(
        [
            f"TorchRL {' and '.join(LEARNER_TEXT[a] for a in s.algorithms)}, one actor shared "
            'by every robot (`paper_id` observations), trained with `reward="value"` '
            f"({CREDIT_TEXT[s.credit]}) for "
            f"{s.decisions:,} robot decisions per run (the same budget in every scenario; PPO "
            f"batches of {s.batch} env steps, {s.epochs} epochs), training seeds "
            f"0-{s.seeds - 1}. Each run's score is its final network's mean normalised score "
            "(0 = random allocation, 1 = the model optimum; the scenarios' committed references) "
            f"over {seeds_note}, greedy, through the "
            "trial runner; a cell is the interquartile mean over training seeds [95 % percentile "
            f"bootstrap, {s.resamples} resamples]. `stay` and the static optimum (the model optimum "
            "at the start, held) are the references' mean scores; the best allocator is the "
            "committed allocators' leaderboard's best IQM, if it is committed.",
            markdown_table(header, table),
            verdict,
            "Every saved run: its network untrained, at its best and at its last checkpoint of "
            f"the learning curve (one episode, seed {CURVE_SEED}), its score (the evaluation "
            "above), and whether its final greedy policy is `stay` (every robot goes back to the "
            "circuit it just served):",
            runs_table(s, runs, results, refs),
            cost_plan(s, rows, len(runs)),
            f"Machine: {machine.get('cpu_model', '?')}, {machine.get('cores', '?')} cores, "
            f"{machine.get('ram_gib', '?')} GiB ({machine.get('platform', '?')}). "
            f"Wall time of the saved runs: {sum(r['wall_s'] for r in rows) / 3600:.2f} h, CPU "
            f"time {sum(r['cpu_s'] for r in rows) / 3600:.2f} h (each run on one core).",
            f"Learning curves (`{FIGURE}`): the greedy network's normalised score on one "
            f"training-side episode (seed {CURVE_SEED}) against the decisions of training; "
            "line: mean over seeds, band: range.",
            "What the networks learned (each robot's greedy circuit after serving each circuit, "
            "the network's whole policy; seed 0 of each learner, or the first saved seed):",
            learned(s, runs, results),
        ]
    )
    rep = Report("deep_leaderboard", "Deep MARL on the scenario suite", body, rows, summary)
    rep.figures.append((FIGURE, lambda path: draw(path, s, runs, results, refs, stay)))
    return rep


def runs_table(
    s: Settings,
    runs: Sequence[Run],
    results: Mapping[str, Mapping[str, Any]],
    refs: Mapping[str, Any],
) -> str:
    """One row per saved run, by scenario, learner and seed: its learning curve's start, best
    and end, and its final score."""
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
        table.append(
            [
                job.scenario,
                job.algorithm,
                job.seed,
                f"{curve[0][1]:.2f}",
                f"{best[1]:.2f} at {best[0]:,}",
                f"{curve[-1][1]:.2f}",
                f"{normalised(mean_value(result), ref):.3f}",
                "stay" if stays else "moves",
            ]
        )
    if not table:
        return "(no run saved yet)"
    header = ["scenario", "learner", "seed", "untrained", "best (decisions)", "last", "score"]
    return markdown_table([*header, "final policy"], table)


def learned(s: Settings, runs: Sequence[Run], results: Mapping[str, Mapping[str, Any]]) -> str:
    parts = []
    for name in s.scenarios:
        config = SCENARIOS[name].config()
        for algorithm in s.algorithms:
            saved = [j for j in runs if (j.scenario, j.algorithm) == (name, algorithm)]
            first = next((j for j in saved if run_key(j) in results), None)
            if first is None:
                continue
            choices = results[run_key(first)]["choices"]
            start = dict(SCENARIOS[name].arena).get("start_circuits")
            rows = [
                [
                    f"robot_{i}",
                    config.robots[i].speed_class,
                    "drawn" if start is None else start[i],
                    *choices[i],
                    end_circuit(choices[i], None if start is None else start[i]),
                ]
                for i in range(config.n_robots)
            ]
            header = [
                "robot",
                "class",
                "start",
                *(f"after {c}" for c in range(config.n_circuits)),
                "ends on",
            ]
            parts.append(
                f"**{SCENARIOS[name].id}, {algorithm}, seed {first.seed}** "
                f"(circuit values {[c.value for c in config.circuits]})\n\n"
                + markdown_table(header, rows)
            )
    return "\n\n".join(parts) if parts else "(no run saved yet)"


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
) -> None:
    """One panel per scenario: each learner's curve, mean over seeds with the range as a band."""
    fig, axes = subplots(1, len(s.scenarios), figsize=(3.4 * len(s.scenarios), 3.2))
    for ax, name in zip(np.atleast_1d(axes), s.scenarios):
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
            n = min(len(c) for c in curves)  # a curve's points fall at the same batches
            x = np.mean([[p["decisions"] for p in c[:n]] for c in curves], axis=0)
            y = np.array(
                [[normalised(p["value_per_h"], refs[name]) for p in c[:n]] for c in curves]
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
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")


def run(settings: Settings) -> Outcome:
    """Run (or resume) the runs not yet saved (at most `max_jobs`), then report every saved run."""
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
    rep = report(s, every, results, provenance)
    written = rep.write(out, provenance)
    return Outcome(out, written, rep.body)


def _stored_provenance(out: Path) -> dict[str, Any]:
    from tavc_agents.experiments.provenance import load_provenance, run_metadata

    return load_provenance(out) or run_metadata(settings={})


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
