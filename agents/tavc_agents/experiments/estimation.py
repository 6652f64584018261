"""The TAVC model measured by simulation: every group of robots alone on every circuit, as fixed
allocations, gives the task-completion frequencies c_{i,J} of `tavc_agents.model.CompletionModel`."""

from __future__ import annotations

import itertools
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from tavc_agents.experiments.runner import TrialResult
from tavc_agents.experiments.sweep import TrialSpec, run_sweep
from tavc_agents.model import CompletionModel, Group, SpeedClasses, model_from_runs
from tavc_env import ArenaConfig, make_config
from tavc_env.validation import require


def group_specs(
    config: ArenaConfig,
    seeds: Sequence[int],
    warmup_s: float,
    measure_s: float,
    key_prefix: str = "",
) -> list[TrialSpec]:
    """The sweep that measures c: every non-empty group alone on every circuit, as fixed
    allocations. Each spec is tagged with its `circuit`, `group` (robots per class) and `seed`;
    its key, `<prefix>c<i>_g<counts>_s<seed>`, is derived from those tags."""
    classes = SpeedClasses.of(config)
    specs = []
    for i in range(config.n_circuits):
        for group in itertools.product(*(range(n + 1) for n in classes.team)):
            if sum(group) == 0:
                continue
            robots = tuple(r for r, n in zip(classes.robots, group) for _ in range(n))
            for seed in seeds:
                specs.append(
                    TrialSpec(
                        key=f"{key_prefix}c{i}_g{'-'.join(map(str, group))}_s{seed}",
                        allocator="fixed",
                        allocator_kwargs={"circuit": i},
                        seed=seed,
                        env_kwargs={"config": config, "robots": robots},
                        convergence_s=warmup_s,
                        measured_s=measure_s,
                        snapshot_every_s=warmup_s + measure_s,
                        tags={"circuit": i, "group": tuple(group), "seed": seed},
                    )
                )
    return specs


def group_of(spec: TrialSpec) -> Group:
    """The group (robots per class) a `group_specs` spec measures."""
    group = spec.tags["group"]
    assert isinstance(group, tuple)
    return tuple(int(n) for n in group)


def circuit_of(spec: TrialSpec) -> int:
    """The circuit a `group_specs` spec measures."""
    circuit = spec.tags["circuit"]
    assert isinstance(circuit, int)
    return circuit


def measured_rate(result: TrialResult) -> float:
    """Tasks per second completed in a trial's measured window."""
    t0, t1 = result.measured_window
    times = np.asarray(result.delivery_time_s, dtype=float)
    return float(((times >= t0) & (times < t1)).sum() / (t1 - t0))


def estimate_model(
    config: ArenaConfig | str = "dahl2004",
    *,
    seeds: Sequence[int] = (0, 1, 2),
    warmup_s: float = 600.0,
    measure_s: float = 7200.0,
    out_dir: str | Path | None = None,
    workers: int | None = None,
    progress_bar: bool = False,
) -> CompletionModel:
    """Measure c_{i,J} for every group and circuit of `config` (or a preset name) by simulation.

    Each group serves each circuit alone (the other robots absent) for `warmup_s` then `measure_s`
    simulated seconds, once per seed. With `out_dir`, runs are saved as they finish and a rerun
    resumes; otherwise they run in a temporary folder.
    """
    cfg = make_config(config) if isinstance(config, str) else config
    require(len(seeds) >= 1, "seeds", seeds, "at least one seed")
    specs = group_specs(cfg, seeds, warmup_s, measure_s)
    with tempfile.TemporaryDirectory() as tmp:
        results = run_sweep(
            specs, out_dir if out_dir is not None else tmp, workers, progress_bar=progress_bar
        )
    runs = [(circuit_of(s), group_of(s), measured_rate(results[s.key])) for s in specs]
    return model_from_runs(cfg, runs)
