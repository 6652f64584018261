"""The start-up benchmark and what it guards: `tavc --help` does not import the package."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import cli_startup


def test_the_cli_module_imports_nothing_heavy() -> None:
    code = "import sys, tavc_agents.cli; print(sorted(m for m in ('tavc_env', 'numba', 'numpy') if m in sys.modules))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_a_small_run_times_every_command_against_the_baseline(tmp_path: Path) -> None:
    outcome = cli_startup.run(cli_startup.Settings(repeats=2, out=tmp_path))
    text = (tmp_path / "cli_startup.csv").read_text()
    assert text.count("\n") == 4  # header + three commands
    assert "| python -c pass | 2 |" in outcome.text and "| tavc --help | 2 |" in outcome.text
    with pytest.raises(ValueError, match=r"repeats = 1 is invalid; allowed: an integer >= 2"):
        cli_startup.Settings(repeats=1)
