"""The `tavc` task family's configuration, read and checked without BenchMARL or torch: the task
names (one YAML file each under `conf/task/tavc/`), and each task's keys.

A task's YAML holds `max_steps` (the env's `max_cycles` and BenchMARL's evaluation rollout
length), `reward_scale` (rewards, `w / t` with t in ms, are multiplied by it) and any keyword of
`tavc_env.parallel_env` (a preset, arena overrides, env options), so a new arena is one YAML file.
"""

from __future__ import annotations

import types
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tavc_env.adapters import checked_reward_scale
from tavc_env.arena import make_env as arena_env
from tavc_env.arena import resolve_env_kwargs
from tavc_env.env import ArenaEnv
from tavc_env.safe_files import MIB, CorruptFileError, first_not_finite, read_text
from tavc_env.validation import is_integer, require

ENV_NAME = "tavc"
# The root of the shipped configuration, laid out as BenchMARL's own `conf` folder so that Hydra
# finds `task/tavc/<task>.yaml` when this folder is on its search path.
CONF_DIR = Path(__file__).resolve().parent / "conf"
TASK_DIR = CONF_DIR / "task" / ENV_NAME
TASK_MAX_BYTES = 1 * MIB  # a shipped task file is well under 1 KiB
# The keys of a task's YAML that are not `tavc_env.parallel_env` keywords
TASK_KEYS = ("max_steps", "reward_scale")
HYDRA_KEYS = ("defaults",)  # Hydra's composition list, read by Hydra only


def task_names() -> tuple[str, ...]:
    """The shipped tasks' names (their YAML files' stems), sorted."""
    return tuple(sorted(p.stem for p in TASK_DIR.glob("*.yaml")))


def task_ids() -> dict[str, str]:
    """BenchMARL's registry key (`tavc/<task>`) of each task, to its enum member's name."""
    return {f"{ENV_NAME}/{name}": name.upper() for name in task_names()}


@dataclass(frozen=True)
class TavcTaskConfig:
    """A `tavc` task's configuration, checked: `env_kwargs` build the env with
    `make_env(env_kwargs)` (its `max_cycles` is `max_steps`)."""

    max_steps: int
    reward_scale: float
    env_kwargs: Mapping[str, Any]

    @classmethod
    def of(cls, config: Mapping[str, Any], where: str) -> TavcTaskConfig:
        """`config` (a task's YAML as a mapping, or BenchMARL's task config) checked, or a
        ValueError that names `where` (the task), the key, its value and what is allowed."""
        require(isinstance(config, Mapping), where, config, "a mapping of task keys")
        require(all(isinstance(k, str) for k in config), f"{where} keys", list(config), "strings")
        require("max_steps" in config, f"{where} keys", sorted(config), "a max_steps key")
        steps = config["max_steps"]
        require(is_integer(steps) and steps >= 1, f"{where}: max_steps", steps, "an integer >= 1")
        require(
            "max_cycles" not in config,
            f"{where}: max_cycles",
            config.get("max_cycles"),
            "no max_cycles key: the env's max_cycles is the task's max_steps",
        )
        try:
            scale = checked_reward_scale(config.get("reward_scale", 1.0))
        except ValueError as error:
            raise ValueError(f"{where}: {error}") from None
        kwargs = {k: v for k, v in config.items() if k not in TASK_KEYS and k not in HYDRA_KEYS}
        kwargs["max_cycles"] = int(steps)
        try:
            resolve_env_kwargs(kwargs)  # which arena and the options, checked (tavc_env.arena)
        except (TypeError, ValueError) as error:
            raise ValueError(f"{where}: {error}") from None
        return cls(int(steps), scale, types.MappingProxyType(kwargs))


def make_env(env_kwargs: Mapping[str, Any]) -> ArenaEnv[Any]:
    """The env a task's `env_kwargs` describe (`tavc_env.arena.make_env`): a scenario's
    (`scenario: <name>`, then env options only), or a preset's (arena overrides, env options)."""
    return arena_env(**env_kwargs)


def load_task_config(name: str, path: str | Path | None = None) -> dict[str, Any]:
    """Task `name`'s configuration as BenchMARL holds it (the YAML's keys less Hydra's
    `defaults`), read from `path` or the shipped file, and checked (`TavcTaskConfig.of`)."""
    import yaml  # the extras that use this (benchmarl, dev) install PyYAML; the env does not

    names = task_names()
    if path is None:
        require(name in names, "task", name, f"one of {list(names)} (the YAML files in {TASK_DIR})")
        path = TASK_DIR / f"{name}.yaml"
    text = read_text(path, TASK_MAX_BYTES, "BenchMARL task YAML")

    class NoAliases(yaml.SafeLoader):
        """A safe loader that refuses aliases (`*name`): no task file needs one, and a few
        hundred bytes of nested aliases expand without bound (nine levels of nine ran for
        minutes) or, referring to themselves, make a structure that recurses forever."""

        def compose_node(self, parent: Any, index: Any) -> Any:
            if self.check_event(yaml.AliasEvent):
                event = self.peek_event()
                raise yaml.composer.ComposerError(
                    None,
                    None,
                    f"holds the alias *{event.anchor}; aliases are refused",
                    event.start_mark,
                )
            return super().compose_node(parent, index)

    try:
        loaded = yaml.load(text, Loader=NoAliases)  # a SafeLoader subclass: safe
    except (yaml.YAMLError, RecursionError) as error:
        raise CorruptFileError(
            f"{path} is not valid YAML ({' '.join(str(error).split())}); allowed: a task YAML "
            "file like the shipped ones"
        ) from None
    where = f"task {ENV_NAME}/{name} ({path})"
    not_finite = first_not_finite(loaded)
    require(not_finite is None, f"{where} value at", not_finite, "finite numbers only")
    require(isinstance(loaded, dict), where, type(loaded).__name__, "a YAML mapping")
    config = {k: v for k, v in loaded.items() if k not in HYDRA_KEYS}
    TavcTaskConfig.of(config, where)
    return config
