"""The README's example shows what it prints (issue 35): the example is run and its output compared
with the `text` block that follows it."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_readme_example_prints_what_the_readme_shows(tmp_path: Path) -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    found = re.search(
        r"--8<-- \[start:example\].*?```python\n(.*?)```.*?--8<-- \[end:example\] -->\n\n"
        r"It prints[^\n]*\n\n```text\n(.*?)```",
        readme,
        re.DOTALL,
    )
    assert found is not None, "the README's example and its printed output"
    code, shown = found.groups()
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=600
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == shown
