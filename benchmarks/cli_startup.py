"""How fast the `tavc` command answers: `tavc --help` against `python -c pass` and the package's
own import, each a whole command timed `--repeats` times in the same run (a ratio against the
baseline, not a timed test).

    python benchmarks/cli_startup.py

How fast the `tavc` command answers: `tavc --help` against Python's own start-up
(`python -c pass`) and the import of the whole package, timed as whole commands, alternating, in
the same run. The script is `benchmarks/cli_startup.py`; outputs `cli_startup.{md,csv,json}` (the
committed reference in `benchmarks/results/cli_startup/`).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from tavc_agents.analysis.reports import Report, fmt_ci, markdown_table
from tavc_agents.analysis.stats import mean_ci, ratio_ci
from tavc_agents.experiments.provenance import run_metadata
from tavc_agents.experiments.study import (
    Outcome,
    StudySettings,
    at_least,
    refuse_invalid,
    run_study,
)


@dataclass(frozen=True, kw_only=True)
class Settings(StudySettings):
    """The start-up benchmark's settings (its command line)."""

    reference: ClassVar = "cli_startup"
    recorded_fields: ClassVar = "repeats"

    repeats: int = 20
    """timed runs of each command (>= 2, for intervals)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        refuse_invalid(self, [("repeats", at_least(self.repeats, 2), "an integer >= 2")])


def commands() -> dict[str, list[str]]:
    """The commands timed: the baseline first."""
    tavc = shutil.which("tavc")
    cli = [tavc] if tavc else [sys.executable, "-m", "tavc_agents.cli"]
    return {
        "python -c pass": [sys.executable, "-c", "pass"],
        "tavc --help": [*cli, "--help"],
        "python -c 'import tavc_env, tavc_agents.experiments.runner'": [
            sys.executable,
            "-c",
            "import tavc_env, tavc_agents.experiments.runner",
        ],
    }


def time_command(command: list[str]) -> float:
    started = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def run(settings: Settings) -> Outcome:
    """Time every command `repeats` times, alternating (after one untimed warm-up each)."""
    out = settings.out_dir()
    provenance = run_metadata(settings=settings.recorded())
    started = time.perf_counter()
    timed = commands()
    for command in timed.values():
        time_command(command)  # warm the file cache and compiled caches
    walls: dict[str, list[float]] = {name: [] for name in timed}
    for _ in range(settings.repeats):
        for name, command in timed.items():
            walls[name].append(time_command(command))
    provenance["wall_time_s"] = time.perf_counter() - started
    baseline = walls["python -c pass"]
    rows: list[dict[str, Any]] = []
    for name, w in walls.items():
        mean, low, high, n = mean_ci(w)
        ratio, r_low, r_high = ratio_ci(w, baseline)
        rows.append(
            {
                "command": name,
                "runs": n,
                "mean_s": mean,
                "low_s": low,
                "high_s": high,
                "vs_python": ratio,
                "vs_python_low": r_low,
                "vs_python_high": r_high,
            }
        )
    table = markdown_table(
        ["command", "runs", "wall s [95 % CI]", "x `python -c pass` [95 % CI]"],
        [
            [
                r["command"],
                r["runs"],
                fmt_ci(r["mean_s"], r["low_s"], r["high_s"], 3),
                fmt_ci(r["vs_python"], r["vs_python_low"], r["vs_python_high"], 2),
            ]
            for r in rows
        ],
    )
    body = (
        "Whole commands timed from a fresh process each, alternating, on this machine; the last "
        "row is what a command that needs the package pays once it runs.\n\n" + table
    )
    report = Report("cli_startup", "How fast the tavc command answers", body, rows, {"rows": rows})
    written = report.write(out, provenance)
    return Outcome(out, written, f"{body}\nwrote {out / 'cli_startup.md'}")


def main(argv: Sequence[str] | None = None) -> int:
    """The study's command line."""
    return run_study(sys.modules[__name__], argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
