"""A first check of PPO on the semi-MDP contract (`tavc_agents.learners.smdp_ppo` over the
TorchRL-native batched env): one training run on one scenario, its speed end to end (robot
decisions per CPU second of collection and updates, batch by batch) and its learning curve, then
the final network scored as the deep leaderboard scores networks, and the compute plan of the full
study from the measured speed.

    python benchmarks/smdp_ppo_check.py --update-reference   # bad_start, 200k decisions: minutes
    python benchmarks/smdp_ppo_check.py --quick

One run (`--seed-run`, default 0; training episodes are the env's seeds spawned from it, never an
evaluation seed) of `--decisions` robot decisions at `--n-envs` arenas. Speed: decisions per CPU
second of this process over each batch (collection through the TorchRL `Collector`, then the PPO
update), the learning curve's evaluations excluded; N batches, mean with its 95 % interval.
Learning curve: after every `decisions / curve_points` decisions the network is run on one
training-side episode (`CURVE_SEED`) read out `sampled` (each robot draws from the policy's
softmax, as it acts in training) and `greedy` (the argmax). Final score: both read-outs on the
scenario's evaluation seeds through the trial runner (`NetworkTeam`), normalised with the
package's references (0 random, 1 the model optimum); the headline read-out is the one with the
higher mean on `--choice-episodes` training-side episodes (seeds 0, 1, ...), as in
`benchmarks/deep_leaderboard.py`. The script is `benchmarks/smdp_ppo_check.py`; outputs
`smdp_ppo_check.{md,csv,json}`.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.evaluation import iqm_ci, normalised, references, value_per_hour
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.runner import run_trial
from tavc_agents.experiments.study import (
    Outcome,
    ScoredSettings,
    at_least,
    refuse_invalid,
    run_study,
)
from tavc_agents.learners.network import Mlp, NetworkTeam
from tavc_env.scenarios import SCENARIOS

CURVE_SEED = 1_000
"""The learning curve's episode: a training-side seed, not an evaluation seed."""
READOUTS = ("sampled", "greedy")
PLAN_SCENARIOS = ("dahl2004", "passing", "bad_start", "three_circuits", "priority_shifts")
PLAN_SEEDS = 5
PLAN_DECISIONS = 1_000_000
ABLATIONS = ("discount=step", "rows=all", "parameters=class")


@dataclass(frozen=True, kw_only=True)
class Settings(ScoredSettings):
    """The check's settings (its command line)."""

    reference: ClassVar = "smdp_ppo_check"
    quick_sizes: ClassVar = {
        "decisions": 3_000,
        "steps_per_batch": 64,
        "curve_points": 2,
        "eval_seeds": 2,
        "episode_h": 0.2,
        "choice_episodes": 1,
        "resamples": 200,
    }
    recorded_fields: ClassVar = (
        "scenario algorithm parameters gamma_h decisions n_envs steps_per_batch epochs minibatch "
        "seed_run curve_points eval_seeds_text episode_text choice_episodes resamples seed"
    )

    scenario: str = "bad_start"
    """the scenario (a name in tavc_env.scenarios.SCENARIOS)"""
    algorithm: str = "mappo"
    """mappo (critic on state()) or ippo (critic on the robot's own observation)"""
    parameters: str = "shared"
    """shared (the read-outs need one network)"""
    gamma_h: float = 0.1
    """discount per simulated hour"""
    decisions: int = 200_000
    """the budget: robot decisions of training"""
    n_envs: int = 16
    """arenas stepped together"""
    steps_per_batch: int = 256
    """env steps per arena per PPO batch"""
    epochs: int = 4
    minibatch: int = 1024
    seed_run: int = 0
    """the training run's seed (torch and the arenas' seeds)"""
    curve_points: int = 10
    """learning-curve evaluations after the untrained one"""
    eval_seeds: int | None = None
    """evaluation seeds (default: all of the scenario's)"""
    episode_h: float | None = None
    """episode length of training and evaluation, simulated hours (default: the scenario's)"""
    choice_episodes: int = 3
    """training-side episodes that choose the headline read-out"""
    quick: bool = False
    """smoke run: 3,000 decisions, episodes of 0.2 h, 2 evaluation seeds"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                ("scenario", self.scenario in SCENARIOS, f"one of {', '.join(SCENARIOS)}"),
                ("algorithm", self.algorithm in ("mappo", "ippo"), "mappo or ippo"),
                ("parameters", self.parameters == "shared", "shared (one network to read out)"),
                ("decisions", at_least(self.decisions, 1), "an integer >= 1"),
                ("n_envs", at_least(self.n_envs, 1), "an integer >= 1"),
                ("steps_per_batch", at_least(self.steps_per_batch, 2), "an integer >= 2"),
                ("curve_points", at_least(self.curve_points, 1), "an integer >= 1"),
                ("eval_seeds", self.eval_seeds is None or at_least(self.eval_seeds, 1), ">= 1"),
                ("choice_episodes", at_least(self.choice_episodes, 1), "an integer >= 1"),
            ],
        )

    @property
    def eval_seeds_text(self) -> str:
        return "all" if self.eval_seeds is None else str(self.eval_seeds)

    @property
    def episode_text(self) -> str:
        return "scenario's" if self.episode_h is None else str(float(self.episode_h))

    @property
    def episode_s(self) -> float:
        scenario = SCENARIOS[self.scenario]
        return scenario.episode_s if self.episode_h is None else float(self.episode_h) * 3600.0


def episode_value(mlp: Mlp, scenario: str, seed: int, episode_s: float, readout: str) -> float:
    """The network read out `readout` on every robot for episode `seed`: value per hour."""
    result = run_trial(
        NetworkTeam(mlp, readout=readout),
        seed=seed,
        convergence_s=0.0,
        measured_s=episode_s,
        snapshot_every_s=episode_s,
        arena={"scenario": scenario},
    )
    return value_per_hour(result)


def train(s: Settings) -> tuple[Mlp, list[dict[str, Any]], list[dict[str, Any]]]:
    """The training run: its network, its batches' speed and its learning curve."""
    import torch  # the `marl` extra

    from tavc_agents.learners import smdp_ppo
    from tavc_env.adapters.torchrl_env import TorchArenaEnv

    torch.manual_seed(s.seed_run)
    torch.set_num_threads(1)  # one core, as the study's jobs run side by side
    ppo = smdp_ppo.PpoSettings(
        algorithm=s.algorithm,
        parameters=s.parameters,
        gamma_h=s.gamma_h,
        n_envs=s.n_envs,
        steps_per_batch=s.steps_per_batch,
        epochs=s.epochs,
        minibatch=s.minibatch,
    )
    env_kwargs = {"scenario": s.scenario, "reward": "value", "max_sim_time_s": s.episode_s}
    env = TorchArenaEnv(
        s.n_envs, env_kwargs=env_kwargs, seed=s.seed_run, with_state=s.algorithm == "mappo"
    )
    every = max(1, s.decisions // s.curve_points)
    batches: list[dict[str, Any]] = []
    curve: list[dict[str, Any]] = []
    last = smdp_ppo.Progress(0, 0, 0.0, 0.0)

    def point(decisions: int, mlp: Mlp) -> None:
        values = {r: episode_value(mlp, s.scenario, CURVE_SEED, s.episode_s, r) for r in READOUTS}
        curve.append({"decisions": decisions, **{f"{r}_per_h": v for r, v in values.items()}})

    def on_batch(p: smdp_ppo.Progress, learner: smdp_ppo.Learner) -> None:
        nonlocal last
        cpu = (p.collect_cpu_s - last.collect_cpu_s) + (p.update_cpu_s - last.update_cpu_s)
        batches.append(
            {
                "decisions": p.decisions - last.decisions,
                "collect_cpu_s": p.collect_cpu_s - last.collect_cpu_s,
                "update_cpu_s": p.update_cpu_s - last.update_cpu_s,
                "decisions_per_cpu_s": (p.decisions - last.decisions) / cpu,
            }
        )
        if p.decisions // every > last.decisions // every or p.decisions >= s.decisions:
            point(p.decisions, smdp_ppo.network(learner.actor_net))
        last = p

    untrained = smdp_ppo.make_learner(env, ppo)  # the curve's first point: an untrained actor
    point(0, smdp_ppo.network(untrained.actor_net))
    torch.manual_seed(s.seed_run)  # training starts from the same generator as without it
    learner, _ = smdp_ppo.train(env, ppo, s.decisions, on_batch)
    env.close()
    return smdp_ppo.network(learner.actor_net), batches, curve


def run(settings: Settings) -> Outcome:
    s = settings.sized()
    out = s.out_dir()
    provenance = run_metadata(settings=s.recorded())
    started = time.perf_counter()
    cpu0 = time.process_time()
    mlp, batches, curve = train(s)
    scenario = SCENARIOS[s.scenario]
    seeds = scenario.eval_seeds[: s.eval_seeds]
    ref = references(s.references)[s.scenario]
    rng = np.random.default_rng(s.seed)
    scored: dict[str, dict[str, Any]] = {}
    for readout in READOUTS:
        values = [episode_value(mlp, s.scenario, x, s.episode_s, readout) for x in seeds]
        choice = [
            episode_value(mlp, s.scenario, x, s.episode_s, readout)
            for x in range(s.choice_episodes)
        ]
        scores = [normalised(v, ref) for v in values]
        point, low, high = iqm_ci([scores], s.resamples, rng)
        scored[readout] = {
            "values_per_h": values,
            "scores": scores,
            "iqm": point,
            "low": low,
            "high": high,
            "choice_score": float(np.mean([normalised(v, ref) for v in choice])),
        }
    headline = max(READOUTS, key=lambda r: scored[r]["choice_score"])  # ties: sampled (first)
    rates = [b["decisions_per_cpu_s"] for b in batches]
    rate, rate_low, rate_high, n_batches = mean_ci(rates)
    decisions = sum(b["decisions"] for b in batches)
    collect = sum(b["collect_cpu_s"] for b in batches)
    update = sum(b["update_cpu_s"] for b in batches)
    overall = decisions / (collect + update)
    provenance["wall_time_s"] = time.perf_counter() - started
    provenance["cpu_time_s"] = time.process_time() - cpu0
    body = report_text(s, scored, headline, curve, (rate, rate_low, rate_high, n_batches))
    other_cpu = provenance["cpu_time_s"] - collect - update  # curve, read-outs, set-up
    body += "\n\n" + plan_text(s, overall, other_cpu, len(seeds))
    rows = [
        {"readout": r, "seed": x, "value_per_h": v, "score": sc}
        for r in READOUTS
        for x, v, sc in zip(seeds, scored[r]["values_per_h"], scored[r]["scores"])
    ]
    data = {
        "scored": scored,
        "headline": headline,
        "curve": curve,
        "batches": batches,
        "speed": {
            "decisions": decisions,
            "collect_cpu_s": collect,
            "update_cpu_s": update,
            "decisions_per_cpu_s": overall,
            "batch_mean": rate,
            "batch_low": rate_low,
            "batch_high": rate_high,
            "batches": n_batches,
        },
        "torch_versions": torch_versions(),
    }
    report = Report(
        "smdp_ppo_check", "PPO on the semi-MDP contract: a first check", body, rows, data
    )
    written = report.write(out, provenance)
    return Outcome(out, written, f"{body}\nwrote {out / 'smdp_ppo_check.md'}")


def torch_versions() -> dict[str, str]:
    import tensordict
    import torch
    import torchrl

    return {
        "torch": torch.__version__,
        "torchrl": torchrl.__version__,
        "tensordict": tensordict.__version__,
    }


def report_text(
    s: Settings,
    scored: dict[str, dict[str, Any]],
    headline: str,
    curve: Sequence[dict[str, Any]],
    speed: tuple[float, float, float, int],
) -> str:
    ref = references(s.references)[s.scenario]
    n = len(scored["sampled"]["scores"])
    table = markdown_table(
        ["read-out", f"IQM over {n} evaluation episodes [95 % CI]", "choice episodes (mean)"],
        [
            [
                f"{r}{' (headline)' if r == headline else ''}",
                fmt_ci(scored[r]["iqm"], scored[r]["low"], scored[r]["high"], 3),
                f"{scored[r]['choice_score']:.3f}",
            ]
            for r in READOUTS
        ],
    )
    curve_table = markdown_table(
        ["decisions", "sampled (normalised)", "greedy (normalised)"],
        [
            [
                f"{p['decisions']:,}",
                f"{normalised(p['sampled_per_h'], ref):.3f}",
                f"{normalised(p['greedy_per_h'], ref):.3f}",
            ]
            for p in curve
        ],
    )
    rate, low, high, batches = speed
    return (
        f"One {s.algorithm.upper()} run (seed {s.seed_run}, shared parameters, gamma_h "
        f"{s.gamma_h} per simulated hour) on `{s.scenario}`, {s.decisions:,} robot decisions at "
        f"{s.n_envs} arenas of {s.steps_per_batch} env steps per batch. Scores are normalised "
        "(0 random, 1 the model optimum, the package's references); one training seed, so the "
        "interval is over evaluation episodes only, not over training runs.\n\n"
        f"{table}\n\n"
        f"**Speed**: {fmt_ci(rate, low, high, 0)} robot decisions per CPU second of training "
        f"(collection and updates; mean over {batches} batches, 95 % interval).\n\n"
        f"**Learning curve** (one training-side episode, seed {CURVE_SEED}, per point):\n\n"
        f"{curve_table}"
    )


def plan_text(s: Settings, rate: float, evaluation_cpu_s: float, eval_episodes: int) -> str:
    """The full study's compute from this run's measured speed (`rate`, decisions per CPU
    second of training) and its other CPU time (`evaluation_cpu_s`: curve, read-outs, set-up,
    which do not grow with the budget)."""
    runs = len(PLAN_SCENARIOS) * PLAN_SEEDS
    ablation_runs = len(ABLATIONS) * PLAN_SEEDS
    train_h = PLAN_DECISIONS / rate / 3600.0
    per_run_eval_h = evaluation_cpu_s / 3600.0
    return (
        "## Plan (from this run's speed)\n\n"
        f"Training at {rate:,.0f} decisions per CPU second (this run, `{s.scenario}`; other "
        "scenarios' env steps cost differently, so this is a first estimate, to be replaced by "
        f"each scenario's first run) takes {train_h:.2f} CPU hours per run of "
        f"{PLAN_DECISIONS:,} decisions. Main grid: {len(PLAN_SCENARIOS)} scenarios "
        f"({', '.join(PLAN_SCENARIOS)}) x {PLAN_SEEDS} seeds = {runs} runs, "
        f"{runs * train_h:.1f} CPU hours of training. Ablation on one scenario "
        f"({', '.join(ABLATIONS)}, each beside the main grid's runs) x {PLAN_SEEDS} seeds = "
        f"{ablation_runs} runs, {ablation_runs * train_h:.1f} CPU hours. The curve and "
        f"read-out evaluations and set-up of this run took {per_run_eval_h:.2f} CPU hours "
        f"({eval_episodes} evaluation episodes per read-out); with the same number of curve "
        "points they cost the same per run at any budget. On the machine's 2 cores: "
        f"about {(runs + ablation_runs) * (train_h + per_run_eval_h) / 2:.0f} wall hours."
    )


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
