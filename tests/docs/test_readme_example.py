"""The README's example is reproducible: run twice, in two fresh interpreters, it prints the same
labelled lines (the env is seeded at reset, the random actions come from a seeded generator, the
trial from its seed)."""

from __future__ import annotations

import subprocess
import sys

from tests.docs.markdown import ROOT, fenced_blocks


def test_the_readme_example_prints_the_same_labelled_lines_twice() -> None:
    readme = ROOT / "README.md"
    example = next(b for b in fenced_blocks(readme)[0] if b.info.split()[:1] == ["python"])
    runs = [
        subprocess.run(
            [sys.executable, "-c", example.code],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
            timeout=300,
        ).stdout
        for _ in range(2)
    ]
    assert runs[0] == runs[1]
    lines = runs[0].splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("random choices, 1 h: delivered value ")
    assert lines[1].startswith("softmax TAVC, 1 h 10 min: ") and "deliveries" in lines[1]
