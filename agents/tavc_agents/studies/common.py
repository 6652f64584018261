"""What studies share beyond the study contract (`tavc_agents.experiments.study`, whose names are
also importable from here): checks of their settings, comma-separated choices, `KEY=VALUE`
arena overrides, and the `--figure-only` redraw of a finished run's figure.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Collection, Sequence
from pathlib import Path
from typing import Annotated, Any, TypeVar

import tyro

from tavc_agents.experiments.files import atomic_path
from tavc_agents.experiments.study import (
    RESULTS_DIR,
    RUNS_DIR,
    Outcome,
    StudySettings,
    compare_tables,
    differing_cells,
    new_run_dir,
    parse_settings,
    recorded_settings,
    run_study,
)
from tavc_env._validation import is_integer, is_number

__all__ = [
    "RESULTS_DIR",
    "RUNS_DIR",
    "Outcome",
    "Overrides",
    "StudySettings",
    "SweepOptions",
    "arena_overrides",
    "at_least",
    "choices",
    "compare_tables",
    "differing_cells",
    "new_run_dir",
    "parse_key_values",
    "parse_settings",
    "positive",
    "recorded_settings",
    "redraw",
    "redraw_source",
    "refuse_invalid",
    "replace",
    "run_study",
]

SweepOptions = StudySettings
"""The contract's settings under their earlier name."""

Overrides = Annotated[tuple[str, ...], tyro.conf.UseAppendAction]
"""The type of a study's `set` field: arena overrides `KEY=VALUE`, one per `--set` (repeatable)."""


def at_least(value: object, least: int) -> bool:
    """An integer (numpy's too, not a bool) >= `least`: a count of trials, seeds, workers."""
    return is_integer(value) and value >= least  # type: ignore[operator]


def positive(value: object) -> bool:
    """A finite real number > 0 (not a bool): hours, a duration, a rate."""
    return is_number(value) and value > 0  # type: ignore[operator]


def refuse_invalid(settings: object, checks: Sequence[tuple[str, bool, str]]) -> None:
    """A ValueError for the first (field name, is valid, what is allowed) of `checks` that is not
    valid, naming the field and its value in `settings`."""
    for name, ok, allowed in checks:
        if not ok:
            raise ValueError(f"{name} = {getattr(settings, name)!r} is invalid; allowed: {allowed}")


def choices(settings: object, name: str, known: Collection[str]) -> list[str]:
    """The comma-separated items of the text field `name` of `settings` (blanks dropped); a
    ValueError naming the field unless there is at least one and each is one of `known`."""
    text = getattr(settings, name)
    chosen = [item.strip() for item in text.split(",") if item.strip()]
    if not chosen or any(item not in known for item in chosen):
        raise ValueError(
            f"{name} = {text!r} is invalid; allowed: a comma-separated subset of {', '.join(known)}"
        )
    return chosen


def parse_key_values(items: Sequence[str], option: str, example: str) -> dict[str, Any]:
    """`KEY=VALUE` items (as given to `option`) as a dict: values that parse as JSON (numbers,
    true/false, lists) are used as such, anything else as a string; whoever receives them then
    names any key or value it does not accept. A ValueError shows `example` for a malformed one."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise ValueError(f"{option} {item!r} is invalid; allowed: KEY=VALUE, e.g. {example}")
        try:
            out[key] = json.loads(text)
        except json.JSONDecodeError:
            out[key] = text
    return out


def arena_overrides(items: Sequence[str]) -> dict[str, Any]:
    """Arena overrides from `--set KEY=VALUE` items; the arena's own validation then names any
    key or value it rejects."""
    return parse_key_values(items, "--set", "source_service_s=15")


S = TypeVar("S")


def replace(settings: S, **changes: Any) -> S:
    """`settings` with some fields changed (validated again)."""
    return dataclasses.replace(settings, **changes)  # type: ignore[type-var]


def redraw_source(path: Path) -> Path:
    """`path`, the report file a `--figure-only` run redraws its figure from; a ValueError naming
    it when it is not there (such a run computes nothing, so it needs a finished run's report)."""
    if not Path(path).is_file():
        raise ValueError(
            f"figure_only: there is no report {str(path)!r} to redraw from; allowed: the output "
            "folder of a finished run (--update-reference, --out or --resume)"
        )
    return Path(path)


def redraw(out: Path, figure: str, draw: Callable[[Path], None]) -> Outcome:
    """A `--figure-only` run: draw the figure `figure` into `out` with `draw` (replacing it whole,
    or not at all on an error) and write nothing else: the report it reads stays as it was."""
    with atomic_path(Path(out) / figure) as tmp:
        draw(tmp)
    text = f"Redrew {figure} from the report in {out}/ (nothing run; no other file written)."
    return Outcome(Path(out), [Path(out) / figure], text)
