"""Report writing: the three files, the provenance header, CSV cells, figures."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from tavc_agents.analysis.reports import (
    CsvAppender,
    Report,
    fmt,
    fmt_ci,
    jsonable,
    markdown_table,
    metadata_markdown,
    write_results,
)
from tavc_agents.experiments.provenance import CHECKOUT, run_metadata


def test_write_results_writes_csv_markdown_and_json(tmp_path: Path) -> None:
    meta = run_metadata(settings={"trials": 3}, wall_time_s=1.5)
    rows = [{"a": 1, "b": 0.1}, {"a": 2, "c": math.nan}]
    paths = write_results(tmp_path, "x", rows, "body text", meta, "Title", {"k": np.float64(2)})
    md = paths["md"].read_text()
    assert md.startswith("# Title\n\n- Generated: ")
    assert (
        "- Settings: trials=3" in md and "- Wall time: 1.5 s" in md and md.endswith("body text\n")
    )
    with open(paths["csv"], newline="") as fh:
        table = list(csv.DictReader(fh))
    assert table == [{"a": "1", "b": "0.1", "c": ""}, {"a": "2", "b": "", "c": ""}]
    data = json.loads(paths["json"].read_text())
    assert data["summary"] == {"k": 2.0} and data["metadata"]["settings"] == {"trials": 3}


def test_metadata_markdown_names_resumed_trials() -> None:
    meta = run_metadata(wall_time_s=3.0, trials_run=2, trials_resumed=4, trial_wall_s_total=10.0)
    assert "(2 trials run, 4 resumed from earlier runs; 10 s of trial time in all)" in (
        metadata_markdown(meta)
    )


def test_metadata_markdown_shows_checkout_paths_relative_to_it() -> None:
    """A committed report reads the same on every machine; the JSON keeps the real paths."""
    assert CHECKOUT is not None  # the tests run from a checkout
    out = CHECKOUT / "benchmarks" / "results" / "x"
    meta = run_metadata(settings={"out": out, "other": "/elsewhere/y"})
    meta["command"] = f"python benchmarks/x.py --out {out}"
    md = metadata_markdown(meta)
    assert "- Command: `python benchmarks/x.py --out benchmarks/results/x`" in md
    assert "out=benchmarks/results/x, other=/elsewhere/y" in md and str(CHECKOUT) not in md


def test_jsonable_and_formatting() -> None:
    assert jsonable({1: (np.int64(2), np.array([1.5]), math.inf)}) == {"1": [2, [1.5], None]}
    assert fmt(math.nan) == "-" and fmt(1.234, 2) == "1.23"
    assert fmt_ci(1.0, math.nan, 2.0) == "1.0" and fmt_ci(1.0, 0.5, 1.5) == "1.0 [0.5, 1.5]"
    assert markdown_table(["a", "b"], [[1, 2]]) == "| a | b |\n|---|---|\n| 1 | 2 |"


def test_csv_appender_flushes_each_row(tmp_path: Path) -> None:
    appender = CsvAppender(tmp_path / "rows.csv", ["x", "y"])
    appender.write({"x": 1.0, "y": None})
    assert (tmp_path / "rows.csv").read_text().splitlines() == ["x,y", "1.0,"]
    appender.close()


def test_report_writes_its_figures(tmp_path: Path) -> None:
    def draw(path: Path) -> None:
        path.write_bytes(b"png")

    report = Report("r", "R", "body", [{"a": 1}], figures=[("f.png", draw)])
    written = report.write(tmp_path, run_metadata())
    assert [p.name for p in written] == ["r.md", "r.csv", "r.json", "f.png"]
    assert (tmp_path / "f.png").read_bytes() == b"png"
