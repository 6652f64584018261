"""Provenance: what a run records, that a sweep computing nothing returns the provenance of the
run that computed its results, and that an interrupted sweep saves its own."""

from __future__ import annotations

from pathlib import Path

import pytest

from tavc_agents.analysis.reports import metadata_markdown
from tavc_agents.experiments.provenance import load_provenance, run_metadata, save_provenance
from tavc_agents.experiments.study import run_recorded
from tavc_agents.experiments.sweep import TRIALS, TrialResult, TrialSpec


def test_run_metadata_records_machine_versions_and_command() -> None:
    meta = run_metadata(settings={"a": 1})
    assert meta["machine"]["cores"] >= 1
    assert meta["versions"]["numpy"] and meta["versions"]["tavc_env"]
    assert meta["settings"] == {"a": 1} and "command" in meta and "git" in meta


def test_provenance_round_trips(tmp_path: Path) -> None:
    assert load_provenance(tmp_path) is None
    save_provenance(tmp_path, {"x": [1, 2]})
    assert load_provenance(tmp_path) == {"x": [1, 2]}
    assert [p.name for p in tmp_path.iterdir()] == ["provenance.json"]


def test_a_sweep_that_computes_nothing_keeps_the_provenance_of_the_one_that_did(
    tmp_path: Path,
) -> None:
    specs = [
        TrialSpec(
            key=f"r{seed}",
            allocator="random",
            seed=seed,
            convergence_s=0.0,
            measured_s=60.0,
            tags={"seed": seed},
        )
        for seed in (0, 1)
    ]
    run = {"workers": 1, "wall_of": lambda r: r.wall_s, "progress_bar": False}
    first, meta = run_recorded(specs, TRIALS, tmp_path / "t", tmp_path, {"n": 2}, **run)
    assert meta["trials_run"] == 2 and load_provenance(tmp_path) == meta | {
        "wall_time_s": meta["wall_time_s"]
    }
    again, meta2 = run_recorded(specs, TRIALS, tmp_path / "t", tmp_path, {"n": 2}, **run)
    assert meta2 == load_provenance(tmp_path)
    assert meta2["timestamp_utc"] == meta["timestamp_utc"] and meta2["trials_run"] == 2
    assert again["r1"].to_dict() == first["r1"].to_dict()
    # one more trial: this run computed something, so its own provenance replaces the old one
    more = [
        *specs,
        TrialSpec(key="r2", allocator="random", seed=2, convergence_s=0.0, measured_s=60.0),
    ]
    _, meta3 = run_recorded(more, TRIALS, tmp_path / "t", tmp_path, {"n": 3}, **run)
    assert meta3["trials_run"] == 1 and meta3["trials_resumed"] == 2
    assert load_provenance(tmp_path) == meta3


def test_an_interrupted_sweep_saves_the_provenance_of_the_jobs_it_computed(
    tmp_path: Path,
) -> None:
    """A report rendered later from the saved jobs names the run that made them, not an older one."""
    specs = [
        TrialSpec(key=f"r{seed}", allocator="random", seed=seed, convergence_s=0.0, measured_s=30.0)
        for seed in (0, 1, 2)
    ]
    save_provenance(tmp_path, {"timestamp_utc": "an older run"})
    calls: list[float] = []

    def wall_interrupted_at_the_second(result: TrialResult) -> float:
        calls.append(result.wall_s)
        if len(calls) == 2:
            raise KeyboardInterrupt("signal 15")  # as SIGTERM arrives during a sweep
        return result.wall_s

    run = {"workers": 1, "progress_bar": False}
    with pytest.raises(KeyboardInterrupt):
        run_recorded(
            specs,
            TRIALS,
            tmp_path / "t",
            tmp_path,
            {"n": 3},
            wall_of=wall_interrupted_at_the_second,
            **run,
        )
    saved = load_provenance(tmp_path)
    assert saved is not None and saved["timestamp_utc"] != "an older run"
    assert saved["interrupted"] is True and saved["trials_run"] == 1
    assert saved["trials_resumed"] == 0 and saved["trial_wall_s_total"] == calls[0]
    assert saved["settings"] == {"n": 3}
    assert "(1 trials run, 0 resumed from earlier runs; " in metadata_markdown(saved)
    assert "run interrupted; report rendered later from its saved jobs)" in metadata_markdown(saved)
    # interrupted again after resuming only: it computed nothing, so the provenance stays
    with pytest.raises(KeyboardInterrupt):
        run_recorded(specs, TRIALS, tmp_path / "t", tmp_path, {"n": 3}, wall_of=_interrupt, **run)
    assert load_provenance(tmp_path) == saved
    # finished: the provenance is the finishing run's, with no interrupted mark
    _, meta = run_recorded(
        specs, TRIALS, tmp_path / "t", tmp_path, {"n": 3}, wall_of=lambda r: r.wall_s, **run
    )
    assert "interrupted" not in meta and meta["trials_run"] == 1 and meta["trials_resumed"] == 2


def _interrupt(result: TrialResult) -> float:
    raise KeyboardInterrupt("signal 15")
