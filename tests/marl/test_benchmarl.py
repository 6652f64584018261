"""BenchMARL trains on the package's own `tavc` tasks (`tavc_env.adapters.benchmarl`), registered
with one call (the `benchmarl` extra, a venv of its own: BenchMARL pins an older TorchRL than the
`marl` extra's; skipped where BenchMARL is not installed)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.marl


def quick_experiment(
    tmp_path: Path, task: Any, frames: int, batch: int, algorithm: str = "mappo"
) -> Any:
    """A BenchMARL experiment of `frames` frames in batches of `batch` (two arena copies), one
    evaluation episode at the end, CSV and JSON logs under `tmp_path`."""
    from benchmarl.algorithms import IppoConfig, MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models.mlp import MlpConfig

    config = ExperimentConfig.get_from_yaml()
    config.max_n_frames = frames
    config.on_policy_collected_frames_per_batch = batch
    config.on_policy_n_envs_per_worker = 2
    config.on_policy_n_minibatch_iters = 2
    config.on_policy_minibatch_size = batch // 2
    config.evaluation_interval = frames
    config.evaluation_episodes = 1
    config.render = False
    config.loggers = ["csv"]
    config.save_folder = str(tmp_path)
    algorithm_config = {"mappo": MappoConfig, "ippo": IppoConfig}[algorithm].get_from_yaml()
    return Experiment(
        task=task,
        algorithm_config=algorithm_config,
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=config,
    )


def test_benchmarl_trains_mappo_on_the_packages_dahl2004_task(tmp_path: Path) -> None:
    pytest.importorskip("benchmarl")
    import torch

    from tavc_env.adapters.benchmarl import register

    torch.set_num_threads(1)
    tasks = register()
    from benchmarl.environments import task_config_registry

    assert task_config_registry["tavc/dahl2004"] is tasks.DAHL2004
    task = tasks.DAHL2004.get_from_yaml()  # the shipped YAML: max_steps 200, paper_id, box
    task.config.update(max_steps=50)  # a short evaluation episode
    experiment = quick_experiment(tmp_path, task, frames=300, batch=100)
    assert experiment.group_map == {"robot": [f"robot_{i}" for i in range(6)]}
    actor = experiment.policy
    before = [p.detach().clone() for p in actor.parameters()]
    experiment.run()

    assert experiment.total_frames == 300 and experiment.n_iters_performed == 3
    after = list(actor.parameters())
    assert any(not torch.equal(a, b) for a, b in zip(before, after)), "no parameter moved"
    (log,) = Path(experiment.folder_name).glob("*.json")
    runs = json.loads(log.read_text())
    (scores,) = runs["tavc"]["dahl2004"]["mappo"].values()
    final = scores[max(k for k in scores if k.startswith("step_"))]
    assert all(torch.isfinite(torch.tensor(r)) for r in final["return"])  # one evaluation episode


def test_speed_class_names_give_one_group_and_policy_per_class(tmp_path: Path) -> None:
    pytest.importorskip("benchmarl")
    import torch

    from tavc_env.adapters.benchmarl import register

    torch.set_num_threads(1)
    tasks = register()
    task = tasks.DAHL2004.get_task(
        {**tasks.DAHL2004.get_from_yaml().config, "agent_names": "speed_class", "max_steps": 20}
    )
    experiment = quick_experiment(tmp_path, task, frames=40, batch=40, algorithm="ippo")
    assert experiment.group_map == {
        "fast": ["fast_0", "fast_1", "fast_2"],
        "slow": ["slow_0", "slow_1", "slow_2"],
    }
    assert set(experiment.losses) == {"fast", "slow"}  # a loss (and a policy) per class
    experiment.run()
    assert experiment.total_frames == 40


def test_a_bad_task_config_is_refused_when_the_task_is_made() -> None:
    pytest.importorskip("benchmarl")
    from tavc_env.adapters.benchmarl import register

    tasks = register()
    with pytest.raises(ValueError, match=r"^task tavc/dahl2004: max_steps = 0 is invalid"):
        tasks.DAHL2004.get_task({"max_steps": 0, "preset": "dahl2004"})
