"""The arena as a BenchMARL task family, `tavc`: one task per YAML file shipped in this package
(`conf/task/tavc/<task>.yaml`; what a task's keys mean: `config`), registered with one call.

    from tavc_env.adapters.benchmarl import register
    tasks = register()                         # tavc/dahl2004, tavc/dahl2004_passing, ...
    task = tasks.DAHL2004.get_from_yaml()      # a BenchMARL TaskClass, for `Experiment(task=...)`

    python -m tavc_env.adapters.benchmarl algorithm=mappo task=tavc/dahl2004   # BenchMARL's CLI

`register` imports BenchMARL (the `benchmarl` extra) and adds the tasks to its
`task_config_registry`, the only state it changes; the rest of this package needs neither
BenchMARL nor torch.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from tavc_env.adapters.benchmarl.config import (
    CONF_DIR,
    ENV_NAME,
    TavcTaskConfig,
    load_task_config,
    task_ids,
    task_names,
)

__all__ = [
    "CONF_DIR",
    "ENV_NAME",
    "TavcTaskConfig",
    "load_task_config",
    "main",
    "register",
    "task_ids",
    "task_names",
]


def register() -> Any:
    """Add every shipped task to BenchMARL's `task_config_registry` as `tavc/<task>` (again on
    a second call: the same entries) and return the task enum (`TavcTask.DAHL2004`, ...).
    Needs BenchMARL: the `benchmarl` extra."""
    try:
        from tavc_env.adapters.benchmarl import tasks
    except ImportError as error:
        raise ImportError(
            f"tavc_env.adapters.benchmarl.register needs BenchMARL ({error}): "
            "pip install 'tavc-env[benchmarl]' (docs/tutorials/deep_marl.md: torch's CPU build first)"
        ) from error
    return tasks.register()


def main(argv: Sequence[str] | None = None) -> None:
    """BenchMARL's own command line (`benchmarl/run.py`) with the `tavc` tasks registered and the
    shipped YAML on Hydra's search path: `algorithm=mappo task=tavc/dahl2004 ...`."""
    register()
    from benchmarl.run import hydra_experiment

    args = list(sys.argv[1:] if argv is None else argv)
    # Hydra reads its overrides from sys.argv; the search path is one more override
    sys.argv = [sys.argv[0], *args, f"hydra.searchpath=[file://{CONF_DIR}]"]
    hydra_experiment()
