"""Learning runs of deep MARL learners: their greedy evaluation and the files a run writes (what
the examples in `docs/examples/` that train with a library need, beside the analysis layer whose
measures and reports they use).

A library trains (`docs/examples/`); after each chunk of training the example exports the network
(`tavc_agents.learners.network.Mlp`) and `evaluate_network` runs it greedily through the trial runner,
on physics, measured with the same measures as every allocator. `write_learning_run` writes the
learning curve (CSV + PNG), the final evaluation (Markdown + JSON, with provenance) and the
network (`network.npz`), which the allocator study then runs as the allocator `network`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tavc_agents.analysis import allocation
from tavc_agents.analysis.measures import measure
from tavc_agents.analysis.plots import learning_curve
from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table, write_csv
from tavc_agents.analysis.stats import mean_ci
from tavc_agents.experiments.files import atomic_path
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.runner import env_arguments, run_trial
from tavc_agents.learners.network import Mlp, NetworkTeam
from tavc_env import make_config
from tavc_env.validation import is_number, require

# Rewards are w / t with t in ms (about 0.03): the examples scale them so that networks see O(1).
REWARD_SCALE = 100.0


def training_arena(preset: str) -> dict[str, Any]:
    """The examples' training arena: `preset`, `paper_id` observations (a network shared by all
    robots tells them apart), 6-hour episodes."""
    return {"preset": preset, "observation_mode": "paper_id", "max_sim_time_s": 6 * 3600.0}


EVAL_SEED = 10_000  # the checkpoints' evaluation trial (the same for every checkpoint)
FINAL_SEEDS_FROM = 20_000  # the final evaluation's fresh seeds start here


@dataclass(frozen=True)
class RunOptions:
    """What every example's training run shares; with the example's budget, its command line."""

    preset: str = "dahl2004"
    """the arena preset to train and evaluate on"""
    seed: int = 0
    """seed of the training (networks, environments)"""
    eval_every: int = 10
    """evaluate the greedy network after every this many updates (and after the last)"""
    eval_hours: float = 2.0
    """simulated hours of each greedy evaluation"""
    final_seeds: int = 10
    """fresh seeds of the final evaluation"""
    out: Path | None = None
    """write the learning curve, the final evaluation and the network here"""

    def __post_init__(self) -> None:
        for name, ok, allowed in (
            ("eval_every", isinstance(self.eval_every, int) and self.eval_every >= 1, ">= 1"),
            ("eval_hours", is_number(self.eval_hours) and self.eval_hours > 0, "> 0"),
            ("final_seeds", isinstance(self.final_seeds, int) and self.final_seeds >= 2, ">= 2"),
        ):
            require(ok, name, getattr(self, name), allowed)
        if self.out is not None and Path(self.out).exists() and not Path(self.out).is_dir():
            raise ValueError(f"out = {str(self.out)!r} is invalid; allowed: a folder (new or not)")

    def start(self, name: str, title: str, budget: Mapping[str, Any]) -> LearningRun:
        """A learning run of the example `name` with these options and its `budget`."""
        settings = {**budget, **{k: v for k, v in asdict(self).items() if k != "out"}}
        return LearningRun(name, title, training_arena(self.preset), settings)

    def update_done(
        self, run: LearningRun, k: int, last: int, step: int, mlp: Callable[[], Mlp]
    ) -> None:
        """After update `k` of `last` (`step` env steps or decisions so far): evaluate the network
        `mlp()` if one is due (`k = 0`: before training, always)."""
        if k % self.eval_every == 0 or k == last:
            run.checkpoint(step, mlp(), self.eval_hours, EVAL_SEED)

    def finish(self, run: LearningRun) -> LearningRun:
        """The final evaluation on fresh seeds; the files written if `out` was given."""
        run.finish(range(FINAL_SEEDS_FROM, FINAL_SEEDS_FROM + self.final_seeds), self.eval_hours)
        if self.out is not None:
            for path in write_learning_run(run, self.out):
                print(f"wrote {path}")
        return run


DEFAULT_OPTIONS = RunOptions()


@dataclass(frozen=True)
class Evaluation:
    """One greedy trial of a frozen network (the measures of `tavc_agents.analysis.measures`)."""

    seed: int
    hours: float
    performance: float  # delivered value (w / max w per delivery) per robot per 10 s
    fast_share: float  # fraction of time fast robots serve the high-value circuit
    slow_share: float
    switches_per_robot_h: float


def evaluate_network(
    mlp: Mlp, env_kwargs: Mapping[str, Any], hours: float, seed: int
) -> Evaluation:
    """Run every robot on `mlp`, greedily, for `hours` of simulated time from the start of an
    episode (the arena of `env_kwargs`, observation as the network was trained)."""
    require(is_number(hours) and hours > 0, "hours", hours, "a duration > 0 h")
    arena = {k: v for k, v in env_kwargs.items() if k not in ("observation_mode", "max_sim_time_s")}
    result = run_trial(
        NetworkTeam(mlp),
        seed=seed,
        convergence_s=0.0,
        measured_s=hours * 3600.0,
        **env_arguments(arena),
    )
    m = measure(result)
    switches = allocation.switches_per_robot_h(result, *result.measured_window)
    return Evaluation(seed, hours, m.performance, m.fast_share, m.slow_share, switches)


@dataclass(frozen=True)
class CurveRow:
    """The greedy evaluation after `step` env steps of training (`wall_s` since training began)."""

    step: int
    wall_s: float
    evaluation: Evaluation


@dataclass
class LearningRun:
    """A training run's learning curve, its final network and its final evaluations."""

    name: str
    title: str
    env_kwargs: Mapping[str, Any]
    settings: Mapping[str, Any]
    curve: list[CurveRow] = field(default_factory=list)
    mlp: Mlp | None = None
    final: list[Evaluation] = field(default_factory=list)
    started: float = field(default_factory=time.perf_counter)

    def checkpoint(self, step: int, mlp: Mlp, hours: float, seed: int) -> CurveRow:
        """Evaluate the network as it is after `step` steps and add it to the curve."""
        row = CurveRow(
            step,
            time.perf_counter() - self.started,
            evaluate_network(mlp, self.env_kwargs, hours, seed),
        )
        self.curve.append(row)
        self.mlp = mlp
        return row

    def finish(self, seeds: Sequence[int], hours: float) -> None:
        """The final evaluation: the last network on fresh seeds."""
        require(
            self.mlp is not None, "learning run", self.name, "a run with at least one checkpoint"
        )
        assert self.mlp is not None
        self.final = [evaluate_network(self.mlp, self.env_kwargs, hours, s) for s in seeds]


def curve_rows(run: LearningRun) -> list[dict[str, Any]]:
    return [
        {"step": r.step, "wall_s": round(r.wall_s, 1), **asdict(r.evaluation)} for r in run.curve
    ]


def summary(run: LearningRun) -> dict[str, Any]:
    out: dict[str, Any] = {"trials": len(run.final)}
    for key in ("performance", "fast_share", "slow_share", "switches_per_robot_h"):
        mean, low, high, _ = mean_ci([getattr(e, key) for e in run.final])
        out[key] = {"mean": mean, "ci95": [low, high]}
    diff = [e.fast_share - e.slow_share for e in run.final]
    mean, low, high, _ = mean_ci(diff)
    out["fast_minus_slow"] = {"mean": mean, "ci95": [low, high]}
    return out


def report_body(run: LearningRun) -> str:
    s = summary(run)
    hours = run.final[0].hours if run.final else 0.0
    lines = [
        f"Final evaluation: the trained network, greedy, on {s['trials']} fresh seeds of "
        f"{hours:g} simulated hours each (physics); mean [95 % CI] over trials.",
        "",
        "| measure | value |",
        "|---|---|",
    ]
    names = {
        "performance": ("value / robot / 10 s", 4),
        "fast_share": ("fast robots' time on the high-value circuit", 3),
        "slow_share": ("slow robots' time on the high-value circuit", 3),
        "fast_minus_slow": ("fast - slow", 3),
        "switches_per_robot_h": ("switches / robot / h", 2),
    }
    for key, (label, digits) in names.items():
        v = s[key]
        low, high = v["ci95"]
        lines.append(f"| {label} | {fmt_ci(v['mean'], low, high, digits)} |")
    lines += [
        "",
        f"Learning curve: {len(run.curve)} checkpoints, greedy evaluation after each (`curve.csv`, `curve.png`).",
        "",
        "What the network learned: each robot's greedy choice after serving each circuit "
        "(the network's whole policy, since it sees only its last circuit and its index).",
        "",
        what_it_learned(run),
    ]
    return "\n".join(lines)


def what_it_learned(run: LearningRun) -> str:
    """The final network's greedy circuit for every robot and last circuit, with the robots'
    speed classes, and whether that is staying, a fixed circuit, or differentiation by class."""
    require(run.mlp is not None, "learning run", run.name, "a run with a network")
    assert run.mlp is not None
    config = make_config(str(run.env_kwargs["preset"]))
    n, m = config.n_robots, config.n_circuits
    agents = [f"robot_{i}" for i in range(n)]
    robots = NetworkTeam(run.mlp).policies(agents, config)  # the allocator itself, asked
    every = np.ones(m, np.int8)
    choice = [[robots[a].act(np.eye(m)[c], every) for c in range(m)] for a in agents]
    rows = [
        [f"robot_{i}", config.robots[i].speed_class, *(str(a) for a in choice[i])] for i in range(n)
    ]
    table = markdown_table(["robot", "class", *(f"after circuit {c}" for c in range(m))], rows)
    stays = all(choice[i][c] == c for i in range(n) for c in range(m))
    if stays:
        reading = (
            "Every robot stays on the circuit it served: the allocation the start gave is kept."
        )
    else:
        by_class: dict[str, set[int]] = {}
        for i in range(n):
            by_class.setdefault(config.robots[i].speed_class, set()).update(choice[i])
        reading = (
            "Circuits chosen by class: "
            + "; ".join(f"{cls}: {sorted(cs)}" for cls, cs in by_class.items())
            + "."
        )
    return f"{table}\n\n{reading}"


def plot_curve(run: LearningRun, path: str | Path) -> None:
    """The learning curve of `run` (`tavc_agents.analysis.plots.learning_curve` of its rows)."""
    learning_curve(curve_rows(run), run.title, path)


def write_learning_run(run: LearningRun, out: Path) -> list[Path]:
    """Write `curve.csv`, `curve.png`, `evaluation.md` / `.json` and `network.npz` into `out`."""
    require(
        run.mlp is not None and bool(run.final),
        "learning run",
        run.name,
        "a finished run (checkpoint, then finish)",
    )
    assert run.mlp is not None
    out.mkdir(parents=True, exist_ok=True)
    meta = run_metadata(settings=dict(run.settings), env=dict(run.env_kwargs))
    report = Report(
        "evaluation",
        run.title,
        report_body(run),
        [asdict(e) for e in run.final],
        {"final": summary(run), "curve": curve_rows(run)},
        figures=[("curve.png", lambda p: plot_curve(run, p))],
    )
    written = report.write(out, meta)
    write_csv(out / "curve.csv", curve_rows(run))
    with atomic_path(out / "network.npz") as tmp:
        run.mlp.save(tmp)
    return [*written, out / "curve.csv", out / "network.npz"]
