"""Every command in the documentation's ```bash blocks works as written.

- `tavc trial`, `tavc record` and `tavc plot` lines run for real, block by block in one working
  folder, in order, so a documented chain (`tavc trial ... --out trial.json`, then
  `tavc plot timeline trial.json`) cannot break.
- Study commands (`python benchmarks/<name>.py ...`, `tavc bench <name> ...`, `tavc reproduce ...`)
  take minutes to hours: their options are parsed and validated by the study's own settings,
  exactly as the command would, without running it.
- Installs, the test suite and `mkdocs serve` are what CI itself runs; they are not repeated.
"""

from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from agents import studies
from agents.studies.common import parse_settings
from tests.docs.markdown import ROOT, Block, documentation_files, fenced_blocks

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


def study_of(words: list[str]) -> tuple[str, list[str]] | None:
    """(study name, its arguments) if `words` runs a study, else None."""
    if words[:1] == ["python"] and len(words) > 1 and words[1].startswith("benchmarks/"):
        return Path(words[1]).stem, words[2:]
    if words[:2] == ["tavc", "bench"]:
        return words[2], [w for w in words[3:] if w != "--"]
    if words[:2] == ["tavc", "reproduce"]:
        return "table1", [w for w in words[2:] if w != "--"]
    return None


@pytest.mark.parametrize("block", BASH, ids=[b.where for b in BASH])
def test_documented_commands_work_as_written(block: Block, tmp_path: Path) -> None:
    for words in commands(block):
        if words[0] in SKIPPED or words[:3] == ["python", "-m", "pytest"]:
            continue
        study = study_of(words)
        if study is not None:
            name, args = study
            if name in studies.STUDIES:
                parse_settings(studies.load(name).Settings, args, name)  # refuses a bad option
            else:  # scripts that are not studies (profile_env, reproduce_trials): their help
                script = ROOT / "benchmarks" / f"{name}.py"
                assert script.is_file(), f"{block.where}: {script} does not exist"
            continue
        assert words[0] == "tavc", f"{block.where}: no rule for documented command {words}"
        command = [sys.executable, "-m", "agents.cli", *words[1:]]
        done = subprocess.run(
            command, cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False
        )
        assert done.returncode == 0, f"{block.where}: {shlex.join(words)}\n{done.stderr[-2000:]}"
