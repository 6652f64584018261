"""The BenchMARL classes of the `tavc` task family (`tavc_env.adapters.benchmarl`): imported only
by its `register`, since BenchMARL and torch are an optional extra.

The env goes in through TorchRL's `PettingZooWrapper`, which groups robots by the prefix of their
names (`robot` by default; `fast`, `slow`, ... with `agent_names="speed_class"`) and takes each
robot's action mask from the info (`observation_format="box"`) or the observation (`"dict"`). The
mask is the env's own: all circuits for a robot that must decide, only its current circuit for one
that need not, whose action the env ignores; a masked categorical policy then gives that forced
step a log-probability of 0, so it adds nothing to the policy gradient.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from benchmarl.environments import Task, TaskClass, task_config_registry
from torchrl.data import Composite
from torchrl.envs import EnvBase, PettingZooWrapper, RewardScaling, Transform

from tavc_env.adapters.benchmarl.config import (
    ENV_NAME,
    TavcTaskConfig,
    load_task_config,
    make_env,
    task_ids,
    task_names,
)


class TavcTaskClass(TaskClass):
    """A `tavc` task: its configuration (checked on construction) and the env it builds."""

    def __init__(self, name: str, config: dict[str, Any] | None) -> None:
        super().__init__(name, config)
        self.checked  # noqa: B018 (a bad configuration is refused here, not at the first env)

    @property
    def checked(self) -> TavcTaskConfig:
        # Read from `config` at each use: BenchMARL's users change a task by updating its config
        return TavcTaskConfig.of(self.config, f"task {ENV_NAME}/{self.name.lower()}")

    def get_env_fun(
        self, num_envs: int, continuous_actions: bool, seed: int | None, device: Any
    ) -> Callable[[], EnvBase]:
        # One arena per env: BenchMARL batches non-vectorised envs itself (num_envs copies)
        kwargs = dict(self.checked.env_kwargs)
        return lambda: PettingZooWrapper(
            make_env(kwargs),
            categorical_actions=True,
            seed=seed,
            device=device,
            return_state=True,  # the env's global state, for centralised critics (MAPPO)
        )

    def supports_continuous_actions(self) -> bool:
        return False

    def supports_discrete_actions(self) -> bool:
        return True

    def max_steps(self, env: EnvBase) -> int:
        return self.checked.max_steps

    def has_render(self, env: EnvBase) -> bool:
        # Rendering needs pygame (the `render` extra), which the `benchmarl` extra does not bring
        return False

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        return dict(env.group_map)

    def _group_entries(self, env: EnvBase, keep: str) -> Composite:
        """The observation spec with only each group's `keep` entry, and no global state."""
        spec = env.observation_spec.clone()
        for group in self.group_map(env):
            for key in list(spec[group].keys()):
                if key != keep:
                    del spec[group][key]
            if spec[group].is_empty():
                del spec[group]
        if "state" in spec.keys():  # noqa: SIM118 (the top-level keys, as a Composite lists them)
            del spec["state"]
        return spec

    def observation_spec(self, env: EnvBase) -> Composite:
        return self._group_entries(env, "observation")

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        spec = self._group_entries(env, "action_mask")
        return None if spec.is_empty() else spec

    def info_spec(self, env: EnvBase) -> Composite | None:
        spec = self._group_entries(env, "info")
        return None if spec.is_empty() else spec

    def state_spec(self, env: EnvBase) -> Composite | None:
        if "state" in env.observation_spec.keys():  # noqa: SIM118 (as above)
            return Composite({"state": env.observation_spec["state"].clone()})
        return None

    def action_spec(self, env: EnvBase) -> Composite:
        return env.full_action_spec

    def get_env_transforms(self, env: EnvBase) -> list[Transform]:
        keys = [(group, "reward") for group in self.group_map(env)]
        return [RewardScaling(0.0, self.checked.reward_scale, in_keys=keys)]

    @staticmethod
    def env_name() -> str:
        return ENV_NAME


class _TavcTasks(Task):
    """The enum of `tavc` tasks: its members are made from the shipped YAML files below."""

    @staticmethod
    def associated_class() -> type[TaskClass]:
        return TavcTaskClass

    def get_from_yaml(self, path: str | None = None) -> TaskClass:
        # BenchMARL's default looks in its own conf folder; the shipped YAML is in this package's
        config = load_task_config(self.name.lower(), None if path is None else Path(path))
        return self.get_task(config=config)


# One member per YAML file (BenchMARL's Task numbers its members itself)
# (`module` and `qualname` let pickle find them: BenchMARL pickles the task with each experiment)
TavcTask: Any = _TavcTasks(
    "TavcTask", [name.upper() for name in task_names()], module=__name__, qualname="TavcTask"
)


def register() -> Any:
    """Add the tasks to BenchMARL's registry (`tavc/<task>`) and return their enum."""
    for key, member in task_ids().items():
        task_config_registry[key] = TavcTask[member]
    return TavcTask
