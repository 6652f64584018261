"""How fast PPO on the semi-MDP contract trains (`tavc_agents.learners.smdp_ppo` over the
TorchRL-native batched env): robot decisions per CPU second end to end, collection and updates,
batch by batch, and the compute plan of the deep study from it. How well it learns is the deep
leaderboard's question (`benchmarks/deep_leaderboard.py --route smdp`).

    python benchmarks/smdp_ppo_speed.py --update-reference   # bad_start, K = 16: a few minutes
    python benchmarks/smdp_ppo_speed.py --quick

One training run (`--seed-run`) of `--decisions` robot decisions at `--n-envs` arenas of one
scenario, `--steps-per-batch` env steps per arena per batch, in this process with one torch
thread. Each batch's CPU seconds of this process are split into collection (the TorchRL
`Collector` stepping the env and the actor) and update (advantages and the PPO epochs); its speed
is its decisions (rows at which a robot decided) over both. Reported: the mean over batches with
its 95 % interval (without the first, which warms caches up), and the run's total (all
decisions over all CPU seconds, the first batch included). Every batch is a row
of the csv. The script is `benchmarks/smdp_ppo_speed.py`; outputs `smdp_ppo_speed.{md,csv,json}`.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from tavc_agents.analysis.reports import Report, fmt_ci
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    refuse_invalid,
    run_study,
)
from tavc_env.scenarios import SCENARIOS

PLAN_SCENARIOS = ("dahl2004", "passing", "bad_start", "three_circuits", "priority_shifts")
PLAN_SEEDS = 5
PLAN_DECISIONS = 1_000_000
ABLATIONS = ("discount=step", "rows=all", "parameters=class")


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The speed study's settings (its command line)."""

    reference: ClassVar = "smdp_ppo_speed"
    quick_sizes: ClassVar = {"decisions": 3_000, "steps_per_batch": 64}
    recorded_fields: ClassVar = "scenario algorithm decisions n_envs steps_per_batch seed_run"

    scenario: str = "bad_start"
    """the scenario (a name in tavc_env.scenarios.SCENARIOS)"""
    algorithm: str = "mappo"
    """mappo (critic on state(); every step reads each arena's state) or ippo"""
    decisions: int = 200_000
    """robot decisions of training"""
    n_envs: int = 16
    """arenas stepped together (K)"""
    steps_per_batch: int = 256
    """env steps per arena per PPO batch"""
    seed_run: int = 0
    """the run's seed (torch and the arenas)"""
    quick: bool = False
    """smoke run: 3,000 decisions, 64 steps per batch"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(
            self,
            [
                ("scenario", self.scenario in SCENARIOS, f"one of {', '.join(SCENARIOS)}"),
                ("algorithm", self.algorithm in ("mappo", "ippo"), "mappo or ippo"),
                ("decisions", at_least(self.decisions, 1), "an integer >= 1"),
                ("n_envs", at_least(self.n_envs, 1), "an integer >= 1"),
                ("steps_per_batch", at_least(self.steps_per_batch, 2), "an integer >= 2"),
                ("seed_run", at_least(self.seed_run, 0), "an integer >= 0"),
            ],
        )


def train(s: Settings) -> list[dict[str, Any]]:
    """The run: every batch's decisions and CPU seconds of collection and of the update."""
    import torch  # the `marl` extra

    from tavc_agents.learners import smdp_ppo

    torch.manual_seed(s.seed_run)
    torch.set_num_threads(1)
    ppo = smdp_ppo.PpoSettings(
        algorithm=s.algorithm, n_envs=s.n_envs, steps_per_batch=s.steps_per_batch
    )
    env = smdp_ppo.make_env(ppo, s.seed_run, scenario=s.scenario)
    batches: list[dict[str, Any]] = []
    last = smdp_ppo.Progress(0, 0, 0.0, 0.0)

    def on_batch(p: smdp_ppo.Progress, _: smdp_ppo.Learner) -> None:
        nonlocal last
        collect, update = p.collect_cpu_s - last.collect_cpu_s, p.update_cpu_s - last.update_cpu_s
        decisions = p.decisions - last.decisions
        batches.append(
            {
                "batch": len(batches),
                "decisions": decisions,
                "collect_cpu_s": collect,
                "update_cpu_s": update,
                "decisions_per_cpu_s": decisions / (collect + update),
            }
        )
        last = p

    smdp_ppo.train(env, ppo, s.decisions, on_batch)
    env.close()
    return batches


def torch_versions() -> dict[str, str]:
    import tensordict
    import torch
    import torchrl

    return {
        "torch": torch.__version__,
        "torchrl": torchrl.__version__,
        "tensordict": tensordict.__version__,
    }


def run(settings: Settings) -> Outcome:
    s = settings.sized()
    out = s.out_dir()
    provenance = run_metadata(settings=s.recorded())
    started, cpu0, load0 = time.perf_counter(), time.process_time(), os.getloadavg()[0]
    batches = train(s)
    provenance["load_average_1min"] = [load0, os.getloadavg()[0]]  # other processes' share
    provenance["wall_time_s"] = time.perf_counter() - started
    provenance["cpu_time_s"] = time.process_time() - cpu0
    provenance["torch_versions"] = torch_versions()
    steady = batches[1:] if len(batches) > 2 else batches  # the first one warms caches up
    rate, low, high, n = mean_ci([b["decisions_per_cpu_s"] for b in steady])
    decisions = sum(b["decisions"] for b in batches)
    collect = sum(b["collect_cpu_s"] for b in batches)
    update = sum(b["update_cpu_s"] for b in batches)
    overall = decisions / (collect + update)
    body = (
        f"{s.algorithm.upper()} on `{s.scenario}` (`smdp_ppo`, its default settings), "
        f"{s.n_envs} arenas x {s.steps_per_batch} env steps per batch, one torch thread, seed "
        f"{s.seed_run}: **{fmt_ci(rate, low, high, 0)} robot decisions per CPU second of "
        f"training** (mean over {n} batches, 95 % interval; the first batch, which warms compiled "
        f"caches up, left out when there are more than two); over the whole run {decisions:,} "
        f"decisions in {collect + update:.1f} CPU s, {overall:,.0f} per CPU second, of which "
        f"collection {collect / (collect + update):.0%} and updates "
        f"{update / (collect + update):.0%}. Versions: "
        + ", ".join(f"{k} {v}" for k, v in provenance["torch_versions"].items())
        + "; load average (1 min) at the start and the end: "
        f"{provenance['load_average_1min'][0]:.1f}, {provenance['load_average_1min'][1]:.1f} "
        f"({os.cpu_count()} cores).\n\n{plan_text(overall)}"
    )
    summary = {
        "decisions": decisions,
        "collect_cpu_s": collect,
        "update_cpu_s": update,
        "decisions_per_cpu_s": overall,
        "batch_mean": rate,
        "batch_low": low,
        "batch_high": high,
        "batches": n,
    }
    report = Report(
        "smdp_ppo_speed", "How fast PPO on the semi-MDP contract trains", body, batches, summary
    )
    written = report.write(out, provenance)
    return Outcome(out, written, f"{body}\nwrote {out / 'smdp_ppo_speed.md'}")


def plan_text(rate: float) -> str:
    """The deep study's training compute at `rate` decisions per CPU second."""
    runs = len(PLAN_SCENARIOS) * PLAN_SEEDS
    ablation_runs = len(ABLATIONS) * PLAN_SEEDS
    hours = PLAN_DECISIONS / rate / 3600.0
    return (
        "## Plan\n\n"
        f"At this speed a run of {PLAN_DECISIONS:,} decisions takes {hours:.2f} CPU hours of "
        "training (other scenarios' env steps cost differently: the deep leaderboard's report "
        "gives each saved run's own cost, and its read-outs' cost). The study: "
        f"{len(PLAN_SCENARIOS)} scenarios ({', '.join(PLAN_SCENARIOS)}) x {PLAN_SEEDS} seeds = "
        f"{runs} runs, {runs * hours:.1f} CPU hours; the ablation on one scenario "
        f"({', '.join(ABLATIONS)}) x {PLAN_SEEDS} seeds = {ablation_runs} runs, "
        f"{ablation_runs * hours:.1f} CPU hours; together about "
        f"{(runs + ablation_runs) * hours / 2:.1f} wall hours on 2 free cores."
    )


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
