"""Multi-agent PPO on `dahl2004` with RLlib, in the semi-Markov (deciders-only) view.

`tavc_env.adapters.rllib.RllibArenaEnv` is the arena as an RLlib `MultiAgentEnv`: a robot appears
only when it must decide, with the reward it earned since its previous decision, so PPO learns
from decisions only (in the plain env five robots in six have nothing to decide in a step). One
policy is shared by all robots; RLlib's own action-masking module reads the mask.

    pip install "tavc-env[marl]"
    python docs/examples/rllib_ppo.py --iterations 2 --batch 200 --eval-every 1 --eval-hours 0.2 --out /tmp/rllib
    python docs/examples/rllib_ppo.py --preset dahl2004 --out benchmarks/results/marl/rllib_ppo_dahl2004

After every `--eval-every` iterations the policy network is exported
(`tavc_agents.learners.network.Mlp`) and run greedily on physics; `--out` gets the learning curve (CSV +
PNG), the final evaluation on fresh seeds and `network.npz`.
"""

from __future__ import annotations

from typing import Any

import ray
import torch
import tyro
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.examples.rl_modules.classes.action_masking_rlm import ActionMaskingTorchRLModule
from ray.tune.registry import register_env

from tavc_agents.learners.network import Mlp
from tavc_agents.learning_runs import (
    DEFAULT_OPTIONS,
    REWARD_SCALE,
    LearningRun,
    RunOptions,
    training_arena,
)
from tavc_env.adapters.rllib import RllibArenaEnv

MODEL = {"fcnet_hiddens": [64, 64], "fcnet_activation": "tanh", "vf_share_layers": False}


def make_env(config: dict[str, Any]) -> RllibArenaEnv:
    preset = str(config.get("preset", "dahl2004"))
    return RllibArenaEnv({**training_arena(preset), "reward_scale": REWARD_SCALE})


def network(module: Any) -> Mlp:
    """The policy module's layers: the actor encoder's, then the policy head's."""
    layers = [
        m
        for part in (module.encoder.actor_encoder, module.pi)  # (MODEL: the critic's is apart)
        for m in part.modules()
        if isinstance(m, torch.nn.Linear)
    ]
    return Mlp.from_torch(layers, activation="tanh")


def train(
    iterations: int = 100, batch: int = 2000, options: RunOptions = DEFAULT_OPTIONS
) -> LearningRun:
    """`iterations` PPO updates on `batch` robot decisions each."""
    torch.set_num_threads(1)
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    register_env("tavc_deciders", make_env)
    config = (
        PPOConfig()
        .environment("tavc_deciders", env_config={"preset": options.preset})
        .env_runners(num_env_runners=0, rollout_fragment_length="auto")
        .multi_agent(policies={"shared"}, policy_mapping_fn=lambda agent, *args, **kw: "shared")
        .rl_module(
            rl_module_spec=MultiRLModuleSpec(
                rl_module_specs={
                    "shared": RLModuleSpec(
                        module_class=ActionMaskingTorchRLModule,
                        model_config=MODEL,
                    )
                }
            )
        )
        .training(
            train_batch_size_per_learner=batch,
            minibatch_size=min(batch, 256),
            num_epochs=4,
            lr=3e-4,
            gamma=0.9,
        )
        .debugging(seed=options.seed)
    )
    algo = config.build_algo()
    run = options.start(
        "rllib_ppo",
        "RLlib PPO, deciders only, one policy for all robots",
        {"iterations": iterations, "batch": batch},
    )
    options.update_done(run, 0, iterations, 0, lambda: network(algo.get_module("shared")))
    for k in range(1, iterations + 1):
        result = algo.train()
        sampled = result["env_runners"]["num_agent_steps_sampled_lifetime"]  # per robot
        decisions = int(sum(sampled.values())) if isinstance(sampled, dict) else int(sampled)
        options.update_done(
            run, k, iterations, decisions, lambda: network(algo.get_module("shared"))
        )
    algo.stop()
    ray.shutdown()
    return options.finish(run)


if __name__ == "__main__":
    tyro.cli(train, config=(tyro.conf.OmitArgPrefixes,))
