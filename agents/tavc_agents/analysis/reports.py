"""Reports: every result set is written as `<name>.csv` (the numbers), `<name>.md` (a report that
starts with the provenance of its run) and `<name>.json` (the provenance and a summary), side by
side, plus any figures."""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tavc_agents.experiments.files import atomic_path, check_writable, write_text
from tavc_agents.experiments.provenance import CHECKOUT


def metadata_markdown(meta: Mapping[str, Any]) -> str:
    """The provenance as a Markdown block (goes at the top of every report). Paths inside the
    checkout the run came from are shown relative to it, so a committed report reads the same on
    every machine; the JSON beside it keeps them as they were (`cwd` says where)."""
    m, v, g = meta["machine"], meta["versions"], meta["git"]
    dirty = {True: " (dirty working tree)", False: "", None: ""}[g.get("dirty")]
    lines = [
        f"- Generated: {meta['timestamp_utc']}",
        f"- Command: `{meta['command']}`",
        f"- Git commit: `{g.get('commit')}`{dirty}",
        f"- Machine: {m['platform']}; {m['cpu_model']}; {m['cores']} cores; {m['ram_gib']} GiB RAM",
        "- Versions: " + ", ".join(f"{k} {val}" for k, val in v.items() if val is not None),
    ]
    if "wall_time_s" in meta:
        wall = f"- Wall time: {meta['wall_time_s']:.1f} s"
        counts = []
        if meta.get("trials_resumed") or meta.get("interrupted"):
            counts.append(
                f"{meta['trials_run']} trials run, {meta['trials_resumed']} resumed from earlier runs"
            )
        if "trial_wall_s_total" in meta and counts:
            counts.append(f"{meta['trial_wall_s_total']:.0f} s of trial time in all")
        if meta.get("interrupted"):
            counts.append("run interrupted; report rendered later from its saved jobs")
        wall += f" ({'; '.join(counts)})" if counts else ""
        lines.append(wall)
    if "settings" in meta:
        settings = ", ".join(f"{k}={val}" for k, val in meta["settings"].items())
        lines.append(f"- Settings: {settings}")
    text = "\n".join(lines)
    return text.replace(f"{CHECKOUT}{os.sep}", "") if CHECKOUT is not None else text


def jsonable(obj: Any) -> Any:
    """`obj` as plain JSON data: numpy scalars and arrays as numbers and lists, non-finite floats
    as None."""
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _cell(value: Any) -> Any:
    if isinstance(value, (float, np.floating)):
        return "" if not math.isfinite(value) else repr(float(value))
    if value is None:
        return ""
    return value


def write_csv(
    path: Path, rows: Sequence[Mapping[str, Any]], fields: Sequence[str] | None = None
) -> None:
    """Write `rows` (dicts) to a CSV; columns are `fields` or the union of keys in first-seen order."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if fields is None:
        seen: dict[str, None] = {}
        for row in rows:
            for k in row:
                seen.setdefault(k, None)
        fields = list(seen)
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(fields), extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell(row.get(k)) for k in fields})


class CsvAppender:
    """A CSV written row by row (flushed each row), so long runs leave results as they go."""

    def __init__(self, path: Path, fields: Sequence[str]) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = check_writable(path)
        self.fields = list(fields)
        self._fh = open(path, "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._writer = csv.DictWriter(self._fh, fieldnames=self.fields, extrasaction="ignore")
        self._writer.writeheader()
        self._fh.flush()

    def write(self, row: Mapping[str, Any]) -> None:
        self._writer.writerow({k: _cell(row.get(k)) for k in self.fields})
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()


def write_results(
    out_dir: Path,
    name: str,
    rows: Sequence[Mapping[str, Any]],
    markdown_body: str,
    meta: Mapping[str, Any],
    title: str,
    summary: Mapping[str, Any] | None = None,
    fields: Sequence[str] | None = None,
) -> dict[str, Path]:
    """Write `<name>.csv`, `<name>.md` (provenance header + body) and `<name>.json` (provenance +
    summary) into `out_dir`; returns the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {
        "csv": out_dir / f"{name}.csv",
        "md": out_dir / f"{name}.md",
        "json": out_dir / f"{name}.json",
    }
    write_csv(paths["csv"], rows, fields)
    md = f"# {title}\n\n{metadata_markdown(meta)}\n\n{markdown_body.rstrip()}\n"
    write_text(paths["md"], md)
    payload = {"metadata": dict(meta), "summary": dict(summary or {}), "csv": paths["csv"].name}
    write_text(paths["json"], json.dumps(jsonable(payload), indent=2, allow_nan=False) + "\n")
    return paths


@dataclass
class Report:
    """A study's findings, ready to write: a title, a Markdown body, the CSV rows, a JSON summary
    and figures (each a file name and a function that draws it into a folder)."""

    name: str
    title: str
    body: str
    rows: list[dict[str, Any]]
    summary: dict[str, Any] = field(default_factory=dict)
    fields: list[str] | None = None
    figures: list[tuple[str, Callable[[Path], None]]] = field(default_factory=list)

    def write(self, out_dir: Path, meta: Mapping[str, Any]) -> list[Path]:
        """Write the report's files and every figure (figures need matplotlib, the `plot`
        extra; without it they are skipped and not listed)."""
        paths = write_results(
            out_dir, self.name, self.rows, self.body, meta, self.title, self.summary, self.fields
        )
        written = [paths["md"], paths["csv"], paths["json"]]
        if self.figures and have_matplotlib():
            for file_name, draw in self.figures:
                with atomic_path(out_dir / file_name) as tmp:
                    draw(tmp)
                written.append(out_dir / file_name)
        return written


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(str(c) for c in row) + " |")
    return "\n".join(lines)


def fmt(x: float, digits: int = 1) -> str:
    """`x` to `digits` decimals, or '-' when it is not finite."""
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


def fmt_ci(mean: float, low: float, high: float, digits: int = 1) -> str:
    """'m [lo, hi]' (or just 'm' when the interval is undefined, or '-' when m is)."""
    if not math.isfinite(mean):
        return "-"
    if not (math.isfinite(low) and math.isfinite(high)):
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def fmt_ci_of(row: Mapping[str, Any], key: str, digits: int = 1) -> str:
    """`fmt_ci` of the columns `key`, `key_low` and `key_high` of a summary row."""
    return fmt_ci(row[key], row[f"{key}_low"], row[f"{key}_high"], digits)


def have_matplotlib() -> bool:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True
