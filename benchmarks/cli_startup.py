"""How fast the `tavc` command answers: `tavc --help` against `python -c pass` and the package's
own import, each a whole command timed `--repeats` times in the same run (a ratio against the
baseline, not a timed test). The study is tavc_agents.studies.cli_startup.

    python benchmarks/cli_startup.py
"""

from __future__ import annotations

from collections.abc import Sequence

from tavc_agents.experiments.study import run_study
from tavc_agents.studies import cli_startup as study


def main(argv: Sequence[str] | None = None) -> int:
    return run_study(study, argv, __doc__ or "")


if __name__ == "__main__":
    raise SystemExit(main())
