"""Shared helpers for the benchmark scripts: run metadata, result writers, confidence intervals.

Every result set is written as three files side by side, `<name>.csv`, `<name>.md` and
`<name>.json`: the CSV holds the numbers, the Markdown a human-readable report that starts with the
run metadata, and the JSON sidecar the metadata plus any summary the script adds.
"""

from __future__ import annotations

import argparse
import csv
import datetime as _dt
import json
import math
import os
import platform
import subprocess
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

REPO_ROOT = Path(__file__).resolve().parent.parent
RESULTS_DIR = Path(__file__).resolve().parent / "results"


# -- metadata ----------------------------------------------------------------------------------
def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _ram_gib() -> float | None:
    try:
        with open("/proc/meminfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return round(int(line.split()[1]) / 1024**2, 1)
    except OSError:
        pass
    return None


def _version(module: str) -> str | None:
    try:
        mod = __import__(module)
    except ImportError:
        return None
    version = getattr(mod, "__version__", None) or getattr(mod, "version", None)
    return str(version) if version is not None else None


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(
            ["git", *args],
            cwd=REPO_ROOT,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


def run_metadata(**extra: Any) -> dict[str, Any]:
    """Machine, software versions, git state, UTC time and the exact command line of this run."""
    commit = _git("rev-parse", "HEAD")
    # Dirty means changed code or docs; result files written by this or a concurrent run do not count.
    status = _git("status", "--porcelain", "--", ".", ":(exclude)benchmarks/results")
    meta: dict[str, Any] = {
        "timestamp_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "cwd": os.getcwd(),
        "machine": {
            "platform": platform.platform(),
            "cpu_model": _cpu_model(),
            "cores": os.cpu_count(),
            "ram_gib": _ram_gib(),
        },
        "versions": {
            "python": platform.python_version(),
            "numpy": _version("numpy"),
            "scipy": _version("scipy"),
            "pymunk": _version("pymunk"),
            "numba": _version("numba"),
            "pettingzoo": _version("pettingzoo"),
            "gymnasium": _version("gymnasium"),
            "tavc_env": _version("tavc_env"),
        },
        "git": {
            "commit": commit,
            "dirty": None if status is None else bool(status),
        },
    }
    meta.update(extra)
    return meta


def metadata_markdown(meta: Mapping[str, Any]) -> str:
    """The metadata as a Markdown block (goes at the top of every report)."""
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
        if meta.get("trials_resumed"):
            wall += (
                f" ({meta['trials_run']} trials run, {meta['trials_resumed']} resumed from earlier "
                f"runs; {meta['trial_wall_s_total']:.0f} s of trial time in all)"
            )
        lines.append(wall)
    if "settings" in meta:
        settings = ", ".join(f"{k}={val}" for k, val in meta["settings"].items())
        lines.append(f"- Settings: {settings}")
    return "\n".join(lines)


# -- writers -----------------------------------------------------------------------------------
def _jsonable(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]], fields: Sequence[str] | None = None):
    """Write `rows` (dicts) to a CSV; columns are `fields` or the union of keys in first-seen order."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if fields is None:
        seen: dict[str, None] = {}
        for row in rows:
            for k in row:
                seen.setdefault(k, None)
        fields = list(seen)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(fields), extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _fmt_cell(row.get(k)) for k in fields})


def _fmt_cell(value: Any) -> Any:
    if isinstance(value, (float, np.floating)):
        return "" if not math.isfinite(value) else repr(float(value))
    if value is None:
        return ""
    return value


class CsvAppender:
    """A CSV written row by row (flushed each row), so long runs leave results as they go."""

    def __init__(self, path: Path, fields: Sequence[str]) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.fields = list(fields)
        self._fh = open(path, "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._writer = csv.DictWriter(self._fh, fieldnames=self.fields, extrasaction="ignore")
        self._writer.writeheader()
        self._fh.flush()

    def write(self, row: Mapping[str, Any]) -> None:
        self._writer.writerow({k: _fmt_cell(row.get(k)) for k in self.fields})
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
    """Write `<name>.csv`, `<name>.md` (metadata header + body) and `<name>.json` (metadata +
    summary) into `out_dir`; returns the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {
        "csv": out_dir / f"{name}.csv",
        "md": out_dir / f"{name}.md",
        "json": out_dir / f"{name}.json",
    }
    write_csv(paths["csv"], rows, fields)
    md = f"# {title}\n\n{metadata_markdown(meta)}\n\n{markdown_body.rstrip()}\n"
    paths["md"].write_text(md, encoding="utf-8")
    payload = {"metadata": dict(meta), "summary": dict(summary or {}), "csv": paths["csv"].name}
    paths["json"].write_text(
        json.dumps(_jsonable(payload), indent=2, allow_nan=False) + "\n", encoding="utf-8"
    )
    return paths


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(str(c) for c in row) + " |")
    return "\n".join(lines)


# -- statistics --------------------------------------------------------------------------------
def mean_ci(values: Iterable[float], confidence: float = 0.95) -> tuple[float, float, float, int]:
    """Mean and Student-t confidence interval over independent replicates (e.g. seeds).

    Returns (mean, low, high, n). With one value the interval is (nan, nan); with none everything
    is nan. Non-finite values are dropped.
    """
    from scipy import stats

    x = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    n = len(x)
    if n == 0:
        return (math.nan, math.nan, math.nan, 0)
    m = float(x.mean())
    if n == 1:
        return (m, math.nan, math.nan, 1)
    half = float(stats.t.ppf(0.5 + confidence / 2, n - 1) * x.std(ddof=1) / math.sqrt(n))
    return (m, m - half, m + half, n)


def ratio_ci(
    num: Sequence[float], den: Sequence[float], confidence: float = 0.95
) -> tuple[float, float, float]:
    """Ratio of means mean(num) / mean(den) of two independent samples (e.g. per-seed means of two
    separate sets of runs), with a delta-method interval on the log scale:

        log R = log mean(num) - log mean(den),
        SE(log R)^2 = (SE_num / mean_num)^2 + (SE_den / mean_den)^2,

    and a Student-t quantile with Welch-Satterthwaite degrees of freedom. The interval is
    exp(log R +- t * SE), asymmetric and positive. Returns (ratio, low, high).
    """
    from scipy import stats

    a = np.asarray([v for v in num if math.isfinite(v)], dtype=float)
    b = np.asarray([v for v in den if math.isfinite(v)], dtype=float)
    if len(a) == 0 or len(b) == 0:
        return (math.nan, math.nan, math.nan)
    ma, mb = float(a.mean()), float(b.mean())
    ratio = ma / mb
    if len(a) < 2 or len(b) < 2:
        return (ratio, math.nan, math.nan)
    va = (a.var(ddof=1) / len(a)) / ma**2  # squared relative standard errors
    vb = (b.var(ddof=1) / len(b)) / mb**2
    se = math.sqrt(va + vb)
    if se == 0:
        return (ratio, ratio, ratio)
    df = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    t = float(stats.t.ppf(0.5 + confidence / 2, df))
    return (ratio, ratio * math.exp(-t * se), ratio * math.exp(t * se))


def bootstrap_ratio_ci(
    num: Sequence[float],
    den: Sequence[float],
    rng: np.random.Generator,
    reps: int = 10_000,
    confidence: float = 0.95,
) -> tuple[float, float]:
    """Percentile bootstrap of mean(num) / mean(den), resampling each sample's seeds independently.
    With few seeds this interval is too narrow (it cannot see beyond the observed spread); it is
    reported next to the delta-method interval as a cross-check."""
    a = np.asarray(num, dtype=float)
    b = np.asarray(den, dtype=float)
    if len(a) < 2 or len(b) < 2:
        return (math.nan, math.nan)
    ra = a[rng.integers(0, len(a), size=(reps, len(a)))].mean(axis=1)
    rb = b[rng.integers(0, len(b), size=(reps, len(b)))].mean(axis=1)
    q = np.quantile(ra / rb, [0.5 - confidence / 2, 0.5 + confidence / 2])
    return (float(q[0]), float(q[1]))


def fmt_ci(mean: float, low: float, high: float, digits: int = 1) -> str:
    """'m [lo, hi]' (or just 'm' when the interval is undefined, or '-' when m is)."""
    if not math.isfinite(mean):
        return "-"
    if not (math.isfinite(low) and math.isfinite(high)):
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """Arena overrides from `KEY=VALUE` strings (as given to `--set`), parsed as the `tavc`
    command parses them; the arena's own validation then names any key or value it rejects."""
    from agents.cli import parse_key_values

    return parse_key_values(items, "--set", "source_service_s=15")


def add_sweep_options(parser: argparse.ArgumentParser) -> None:
    """`--workers` and `--backend`, for scripts that run their trials through `run_trials`."""
    parser.add_argument(
        "--workers", type=int, default=None, help="processes, or Ray CPUs (default: all cores)"
    )
    parser.add_argument(
        "--backend",
        choices=["local", "ray"],
        default="local",
        help="local process pool (default) or Ray tasks (pip install 'tavc-env[ray]'; set "
        "RAY_ADDRESS to use a cluster); results and resume are the same either way",
    )


def run_trials(
    specs: Sequence[Any],
    out_dir: Path,
    workers: int | None,
    settings: Mapping[str, Any],
    backend: str = "local",
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run (or resume) a sweep of `agents.experiments.sweep.TrialSpec`s with a progress bar; return the
    results by key and the run metadata, taken before the trials run (the commit they ran from),
    with the wall time and how many trials were run or resumed."""
    import time

    from agents.experiments.sweep import run_sweep

    meta = run_metadata(settings=dict(settings))
    resumed: list[str] = []

    def note(spec: Any, result: Any, was_resumed: bool) -> None:
        if was_resumed:
            resumed.append(spec.key)

    started = time.perf_counter()
    results = run_sweep(
        specs, out_dir, workers=workers, on_done=note, progress_bar=True, backend=backend
    )
    meta.update(
        wall_time_s=time.perf_counter() - started,
        trials_resumed=len(resumed),
        trials_run=len(specs) - len(resumed),
        trial_wall_s_total=sum(r.wall_s for r in results.values()),
    )
    return results, meta


def add_override_option(parser: argparse.ArgumentParser) -> None:
    """The `--set KEY=VALUE` option (repeatable) for arena overrides."""
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="arena override for every run, e.g. --set source_service_s=15 or "
        "--set service_scales_with_speed=true (repeatable)",
    )


def parsed_overrides(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict[str, Any]:
    """The parsed `--set` overrides, or a usage error naming the bad item."""
    try:
        return parse_overrides(args.set)
    except ValueError as error:
        parser.error(str(error))


def have_matplotlib() -> bool:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True
