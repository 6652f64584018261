"""CI runs the README's test command verbatim: the second command of the README's command block is
a line of `.ci/run`, and it comes before anything else installs into CI's venv, so a test that needs
more than that command installs is caught by CI as it would be on a newcomer's machine."""

from __future__ import annotations

import re

from tests.docs.markdown import ROOT


def readme_commands() -> list[str]:
    """The lines of the README's first bash block (its two commands)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"```bash\n(.*?)```", text, re.DOTALL)
    assert block is not None, "the README has no bash block"
    return [line.strip() for line in block.group(1).splitlines() if line.strip()]


def test_the_readme_opens_with_two_commands() -> None:
    commands = readme_commands()
    assert len(commands) == 2, commands
    assert commands[1].endswith("python -m pytest -n 2 -q"), commands[1]


def test_ci_runs_the_readme_test_command_verbatim_before_other_installs() -> None:
    test_command = readme_commands()[1]
    lines = [line.strip() for line in (ROOT / ".ci" / "run").read_text("utf-8").splitlines()]
    assert test_command in lines, f"{test_command!r} is not a line of .ci/run"
    before = lines[: lines.index(test_command)]
    installs = [line for line in before if "pip install" in line and "--upgrade pip" not in line]
    assert installs == [], f".ci/run installs before the README's test command: {installs}"
