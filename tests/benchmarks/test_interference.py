"""The interference study: its runs keep the keys and settings of the committed results, bad
settings are refused, and a quick run writes a report that a rerun regenerates from its saved runs
byte for byte."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

import interference as study
from arena_analysis import RUN_FIELDS

ROOT = Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "benchmarks" / "results"


def test_runs_keep_their_keys_and_allocations() -> None:
    jobs = study.make_jobs(study.Settings())
    keys = [study.job_key(j) for j in jobs]
    assert len(keys) == len(set(keys)) == 130
    for key in ("t_n_0-6_s0", "switch_others-3-2_s4", "switch_lone_lone_s2", "cross_3-1_s1"):
        assert key in keys
    by_key = dict(zip(keys, jobs))
    assert by_key["t_n_2-4_s0"].circuit_of == (0, 0, 1, 1, 1, 1)
    assert by_key["switch_others-2-3_s0"].circuit_of == (0, 0, 1, 1, 1, 1)
    assert by_key["switch_others-2-3_s0"].switcher == 5
    assert by_key["cross_1-2_s0"].circuit_of == (0, 1, 1, 0, 0, 1)
    assert by_key["cross_1-2_s0"].preset == "dahl2004"
    assert by_key["switch_lone_lone_s0"].speeds == (0.25,)
    assert jobs[-1].experiment == "switch_lone"  # the longest runs start first
    # only the switchers take --switch-every
    changed = study.make_jobs(study.Settings(switch_every=4))
    assert {j.switch_every for j in changed if j.switcher >= 0} == {4}
    assert {j.switch_every for j in changed if j.switcher < 0} == {3}


@pytest.mark.parametrize(
    ("folder", "settings"),
    [
        ("", study.Settings()),
        (
            "interference_competence",
            study.Settings(seeds=3, hours=2, workers=2, set=("service_scales_with_speed=true",)),
        ),
        (
            "interference_light_stations",
            study.Settings(
                seeds=3, hours=2, workers=2, set=("source_service_s=6", "sink_service_s=2")
            ),
        ),
    ],
)
def test_recorded_settings_are_those_of_the_committed_reports(
    folder: str, settings: study.Settings
) -> None:
    committed = json.loads((COMMITTED / folder / "interference.json").read_text())
    recorded = json.loads(json.dumps(settings.recorded()))
    expected = committed["metadata"]["settings"]
    assert list(recorded) == list(expected)
    del recorded["workers"], expected["workers"]  # how the runs ran, not what they measure
    assert recorded == expected


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"switch_every": 1}, "switch_every"),
        ({"seeds": 0}, "seeds"),
        ({"hours": -1.0}, "hours"),
        ({"skip_first": -1}, "skip_first"),
        ({"workers": 0}, "workers"),
    ],
)
def test_bad_settings_are_refused(changes: dict[str, object], field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field} = .* is invalid; allowed: "):
        study.Settings(**changes)  # type: ignore[arg-type]


def test_a_bad_arena_override_is_refused_before_any_run() -> None:
    with pytest.raises(ValueError, match="no_such_key"):
        study.Settings(set=("no_such_key=1",))


def test_quick_run_writes_the_report_and_regenerates_it_from_its_runs(tmp_path: Path) -> None:
    command = [sys.executable, "benchmarks/interference.py", "--quick", "--workers", "1"]
    command += ["--out", str(tmp_path)]
    first = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    assert "## Verdict" in first.stdout and "t(4)/t(3)" in first.stdout
    with open(tmp_path / "interference.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    sections = [r["section"] for r in rows]
    assert sections.count("t_ratio") == 10 and sections.count("t_n") == 36
    t1 = next(r for r in rows if r["quantity"] == "mean task time (s)" and r["n_on_circuit"] == "1")
    assert 55.0 < float(t1["mean"]) < 80.0 and t1["n_seeds"] == "2"
    with open(tmp_path / "interference_runs.csv", encoding="utf-8") as fh:
        runs = csv.DictReader(fh)
        assert runs.fieldnames == RUN_FIELDS
        assert {r["experiment"] for r in runs} == set(study.EXPERIMENTS)
    summary = json.loads((tmp_path / "interference.json").read_text())["summary"]
    assert summary["runs"] == 52 and summary["runs_per_experiment"]["cross"] == 32
    report = (tmp_path / "interference.md").read_text()
    again = study.run(study.Settings(quick=True, workers=1, out=tmp_path))  # every run resumed
    assert (tmp_path / "interference.md").read_text() == report
    assert again.text.startswith("## Verdict") and len(again.written) == 5


def _findings_with_cross(fast_shared: float, slow_shared: float) -> study.Findings:
    """Findings whose circuit-0 cross tables hold only what the notes read: 60 s fast and 75 s slow
    alone, and the given task times wherever both classes share the circuit."""
    nan = float("nan")
    fast = {(1, 0): (60.0, nan, nan, 5), (2, 0): (61.0, nan, nan, 5)}
    slow = {(0, 1): (75.0, nan, nan, 5), (0, 2): (76.0, nan, nan, 5)}
    for f in range(1, 4):
        for s in range(1, 4):
            fast[(f, s)] = (fast_shared, nan, nan, 5)
            slow[(f, s)] = (slow_shared, nan, nan, 5)
    queued = {(0, "fast"): {}, (0, "slow"): {}}
    return study.Findings(
        rows=[],
        t_n={},
        switch={},
        pooled={},
        cross={(0, "fast"): fast, (0, "slow"): slow},
        queued=queued,  # type: ignore[arg-type]
    )


def test_the_catch_up_story_is_told_only_where_the_classes_share_one_pace() -> None:
    settings = study.Settings(set=("source_service_s=12",))
    one_pace = "\n".join(study.cross_notes(_findings_with_cross(75.0, 75.5), settings))
    assert "differ by at most 0.5 s (alone, by 15.0 s)" in one_pace
    assert "catches up during the 12 s loading" in one_pace
    two_paces = "\n".join(study.cross_notes(_findings_with_cross(70.0, 80.0), settings))
    assert "differ by at most 10.0 s (alone, by 15.0 s)" in two_paces
    assert "catches up" not in two_paces and "not put the two classes on one pace" in two_paces
