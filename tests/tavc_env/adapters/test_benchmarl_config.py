"""The BenchMARL task family's YAML files and registration, checked without BenchMARL or torch
(`tavc_env.adapters.benchmarl.config`); the family trains in tests/marl/test_benchmarl.py."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

import tavc_env
from tavc_env.adapters import benchmarl as family
from tavc_env.adapters.benchmarl.config import TASK_DIR, TavcTaskConfig, make_env

ROOT = Path(__file__).resolve().parents[3]


def test_the_shipped_tasks_and_their_registry_keys() -> None:
    assert {"dahl2004", "dahl2004_passing"} <= set(family.task_names())
    assert family.task_ids()["tavc/dahl2004"] == "DAHL2004"
    assert family.task_ids()["tavc/dahl2004_passing"] == "DAHL2004_PASSING"
    assert family.CONF_DIR / "task" / family.ENV_NAME == TASK_DIR


@pytest.mark.parametrize("name", family.task_names())
def test_every_yaml_is_a_hydra_task_config_that_builds_its_env(name: str) -> None:
    raw = yaml.safe_load((TASK_DIR / f"{name}.yaml").read_text(encoding="utf-8"))
    assert raw["defaults"] == ["_self_"]  # Hydra composes it with no dataclass of BenchMARL's
    config = family.load_task_config(name)
    assert "defaults" not in config
    checked = TavcTaskConfig.of(config, name)
    assert checked.env_kwargs["max_cycles"] == checked.max_steps == config["max_steps"]
    env = make_env(checked.env_kwargs)
    observations, _ = env.reset(seed=0)
    assert set(observations) == set(env.possible_agents)
    if "preset" in config:  # a preset's task is that preset's arena
        assert env.config == tavc_env.make_config(config["preset"])
    if "scenario" in config:  # a scenario's task is that scenario, schedule and all
        assert env.scenario == tavc_env.SCENARIOS[config["scenario"]]


def test_the_yaml_files_are_package_data() -> None:
    tomllib = pytest.importorskip("tomllib")
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = pyproject["tool"]["setuptools"]["package-data"]["tavc_env"]
    package = ROOT / "tavc_env"
    for path in TASK_DIR.glob("*.yaml"):
        relative = path.relative_to(package)
        assert any(relative.match(p) for p in patterns), f"{relative} is not in the wheel"


@pytest.mark.parametrize(
    ("changes", "pattern"),
    [
        ({"max_steps": 0}, r"^task t: max_steps = 0 is invalid; allowed: an integer >= 1"),
        ({"max_steps": None}, r"^task t: max_steps = None is invalid"),
        ({"max_cycles": 10}, r"^task t: max_cycles = 10 is invalid; allowed: no max_cycles key"),
        (
            {"reward_scale": -1.0},
            r"^task t: reward_scale = -1\.0 is invalid; allowed: a number > 0",
        ),
        ({"speed": 0.3}, r"^task t: unknown configuration key\(s\) \['speed'\]"),
        ({"preset": "dahl"}, r"^task t: preset = 'dahl' is invalid"),
        ({"agent_names": "class"}, r"^task t: agent_names = 'class' is invalid"),
    ],
)
def test_a_bad_task_config_is_refused_naming_the_task_and_key(
    changes: dict[str, Any], pattern: str
) -> None:
    config = {**family.load_task_config("dahl2004"), **changes}
    with pytest.raises(ValueError, match=pattern):
        TavcTaskConfig.of(config, "task t")


def test_a_missing_max_steps_and_an_unknown_task_are_refused() -> None:
    config = family.load_task_config("dahl2004")
    del config["max_steps"]
    with pytest.raises(ValueError, match=r"^task t keys = .* allowed: a max_steps key"):
        TavcTaskConfig.of(config, "task t")
    with pytest.raises(
        ValueError, match=r"^task = 'nope' is invalid; allowed: one of \['bad_start'"
    ):
        family.load_task_config("nope")


def test_a_task_read_from_another_path_is_checked_too(tmp_path: Path) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text("defaults:\n  - _self_\nmax_steps: 50\npreset: dahl2004_homogeneous\n")
    assert family.load_task_config("mine", path)["preset"] == "dahl2004_homogeneous"
    path.write_text("max_steps: 50\nstation_bays: 0\n")
    with pytest.raises(ValueError, match=re.escape(f"task tavc/mine ({path}): station_bays")):
        family.load_task_config("mine", path)


def test_register_without_benchmarl_says_which_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(sys.modules, "tavc_env.adapters.benchmarl.tasks", raising=False)
    monkeypatch.setitem(sys.modules, "benchmarl", None)  # as if not installed
    monkeypatch.setitem(sys.modules, "benchmarl.environments", None)
    with pytest.raises(ImportError, match=r"pip install 'tavc-env\[benchmarl\]'"):
        family.register()


def _alias_bomb(levels: int) -> str:
    """`levels` levels of nine aliases each: a few hundred bytes that expand ninefold a level."""
    lines = ["a0: &a0 [x]"]
    for k in range(1, levels + 1):
        lines.append(f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    "text",
    [_alias_bomb(9), "a: &a [*a]\n", "max_steps: &n 100\nother: *n\n"],
    ids=["nine_levels", "self_reference", "plain_alias"],
)
def test_a_task_yaml_with_aliases_is_refused_at_once_in_one_line(tmp_path: Path, text: str) -> None:
    """Defect 2: nine levels of aliases (about 350 bytes) hung load_task_config (ninefold a
    level); a self-referencing alias gave a raw RecursionError. Aliases are refused."""
    import time

    from tavc_env.adapters.benchmarl.config import load_task_config
    from tavc_env.safe_files import CorruptFileError
    from tests.damage import no_hang

    path = tmp_path / "bomb.yaml"
    path.write_text(text)
    start = time.perf_counter()
    with no_hang(20), pytest.raises(CorruptFileError) as caught:  # a failure, not a hang
        load_task_config("dahl2004", path)
    assert time.perf_counter() - start < 5
    message = str(caught.value)
    assert "\n" not in message and str(path) in message
    assert "aliases are refused" in message
