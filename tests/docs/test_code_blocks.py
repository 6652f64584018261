"""The Python in the documentation runs.

Every fenced block whose info string is `python` in README.md, the pages under docs/ and the files
they include runs as it is, each in a fresh namespace and a temporary working directory, so each
must be self-contained and quick (a few seconds: an example that would simulate for hours says so
and simulates minutes). A block marked `python no-run` (pseudo-code) is only compiled. Shell
commands are not run here, but every fenced block must say its language, and shell is `bash`.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.docs.markdown import Block, documentation_files, fenced_blocks

BLOCKS = [block for path in documentation_files() for block in fenced_blocks(path)[0]]
PYTHON = [block for block in BLOCKS if block.language == "python"]
LANGUAGES = {"python", "bash", "text"}
SHELL_NAMES = {"sh", "shell", "console", "zsh", "shell-session"}


def runs(block: Block) -> bool:
    return "no-run" not in block.info.split()[1:]


@pytest.mark.parametrize("block", PYTHON, ids=lambda b: b.where)
def test_python_block_runs(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    compiled = compile(block.code, block.where, "exec")
    if not runs(block):
        return
    monkeypatch.chdir(tmp_path)
    exec(compiled, {"__name__": "__main__", "__file__": str(tmp_path / "block.py")})


def test_the_python_blocks_are_found() -> None:
    where = {b.where.split(":")[0] for b in PYTHON if runs(b)}
    # (the home page's example is the README's, included by section: run once, as the README's)
    assert {"README.md", "docs/env.md", "docs/tutorials/own_agent.md"} <= where
    assert sum(not runs(b) for b in PYTHON) <= 2  # pseudo-code stays rare


@pytest.mark.parametrize("block", BLOCKS, ids=lambda b: b.where)
def test_every_block_says_its_language(block: Block) -> None:
    assert block.language in LANGUAGES, (
        f"{block.where}: fence info {block.info!r}; use one of {sorted(LANGUAGES)}"
        + (" (shell commands are `bash`)" if block.language in SHELL_NAMES else "")
    )
