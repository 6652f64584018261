"""Every command in the documentation's ```bash blocks works as written.

- `tavc trial`, `tavc record` and `tavc plot` lines run for real, block by block in one working
  folder, in order, so a documented chain (`tavc trial ... --out trial.json`, then
  `tavc plot timeline trial.json`) cannot break.
- Study commands (`python benchmarks/<name>.py ...`)
  take minutes to hours: their options are parsed and validated by the study's own settings,
  exactly as the command would, without running it.
- Example scripts (`python docs/examples/<name>.py ...`) train deep networks: their options are
  checked against the example's own (its `train` parameters and `RunOptions`).
- BenchMARL's command line (`python -m tavc_env.adapters.benchmarl task=tavc/<task> ...`): its
  task is one of the shipped YAML files; BenchMARL itself (a venv of its own) is not needed.
- `tavc evaluate` lines run for real on one evaluation episode of each scenario cut to 0.1 h
  (`--seeds 1 --episode-h 0.1` appended; the whole suite takes minutes), in the same working
  folder, so the row a block writes is the row the block's next command reads.
- Installs, the test suite and `mkdocs serve` are what CI itself runs; they are not repeated.
"""

from __future__ import annotations

import ast
import dataclasses
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tavc_agents.experiments.study import parse_settings
from tavc_agents.learning_runs import RunOptions
from tavc_env.adapters.benchmarl import task_ids
from tests.docs.markdown import ROOT, Block, documentation_files, fenced_blocks
from tests.helpers import study_programs

SKIPPED = ("pip", "mkdocs")  # (and `python -m pytest`)


def commands(block: Block) -> list[list[str]]:
    """The commands of a bash block: one per line, comments dropped, `&&` chains split."""
    out = []
    for line in block.code.splitlines():
        for part in line.split("#", 1)[0].split("&&"):
            words = shlex.split(part)
            if words:
                out.append(words)
    return out


BASH = [b for p in documentation_files() for b in fenced_blocks(p)[0] if b.language == "bash"]


def example_options(script: Path) -> set[str]:
    """The options of an example of docs/examples (its `train` parameters and `RunOptions`'
    fields, or the fields of its `Settings` where it has one, as flags), read from its source:
    the deep-learning libraries it imports need not be installed."""
    tree = ast.parse(script.read_text(encoding="utf-8"))
    train = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "train")
    names = {a.arg for a in train.args.args} - {"options", "settings"}
    names |= {f.name for f in dataclasses.fields(RunOptions)}
    for node in tree.body:  # a tyro-style example: the fields of its Settings are its flags
        if isinstance(node, ast.ClassDef) and node.name == "Settings":
            names |= {
                s.target.id
                for s in node.body
                if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name)
            }
    return {"--" + n.replace("_", "-") for n in names}


def study_of(words: list[str]) -> tuple[str, list[str]] | None:
    """(study name, its arguments) if `words` runs a study, else None."""
    if words[:1] == ["python"] and len(words) > 1 and words[1].startswith("benchmarks/"):
        return Path(words[1]).stem, words[2:]
    return None


@pytest.mark.parametrize("block", BASH, ids=[b.where for b in BASH])
def test_documented_commands_work_as_written(
    block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in ("benchmarks", "docs"):  # as from a clone, writing only into tmp_path
        (tmp_path / name).symlink_to(ROOT / name)
    monkeypatch.chdir(tmp_path)  # a study's file options resolve where the commands ran
    for words in commands(block):
        if words[0] in SKIPPED or words[:3] == ["python", "-m", "pytest"]:
            continue
        if words[:1] == ["python"] and words[1].startswith("docs/examples/"):
            script = ROOT / words[1]
            assert script.is_file(), f"{block.where}: {script} does not exist"
            flags = {w for w in words[2:] if w.startswith("--")}
            unknown = flags - example_options(script)
            assert not unknown, f"{block.where}: {script.name} has no options {sorted(unknown)}"
            continue
        if words[:3] == ["python", "-m", "tavc_env.adapters.benchmarl"]:
            overrides = dict(w.split("=", 1) for w in words[3:])  # Hydra's key=value
            assert overrides.get("task") in task_ids(), f"{block.where}: no such task {overrides}"
            continue
        study = study_of(words)
        if study is not None:
            name, args = study
            programs = study_programs()
            if name in programs:
                parse_settings(programs[name].Settings, args, name)  # refuses a bad option
            else:  # scripts that are not studies (profile_env, reproduce_trials): their help
                script = ROOT / "benchmarks" / f"{name}.py"
                assert script.is_file(), f"{block.where}: {script} does not exist"
            continue
        assert words[0] == "tavc", f"{block.where}: no rule for documented command {words}"
        quick = ["--seeds", "1", "--episode-h", "0.1"] if words[1:2] == ["evaluate"] else []
        command = [sys.executable, "-m", "tavc_agents.cli", *words[1:], *quick]
        done = subprocess.run(
            command, cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False
        )
        assert done.returncode == 0, f"{block.where}: {shlex.join(words)}\n{done.stderr[-2000:]}"
