"""The reproduction check: a saved trial re-runs bit for bit, and a changed one is caught."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import reproduce_trials as reproduce
from tavc_agents.experiments.files import write_manifest
from tavc_agents.experiments.sweep import TrialSpec, result_path, run_sweep


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("saved")
    spec = TrialSpec(
        key="s", allocator="softmax_tavc", seed=5, convergence_s=60.0, measured_s=120.0
    )
    run_sweep([spec], out, workers=1)
    return result_path(out, "s")


def test_a_saved_trial_reproduces(saved: Path) -> None:
    outcome = reproduce.run(reproduce.Settings(patterns=(str(saved),), workers=1))
    assert outcome.text.startswith("IDENTICAL")
    assert reproduce.all_reproduced(outcome)


def test_a_trial_whose_spec_changed_is_different(saved: Path, tmp_path: Path) -> None:
    data = json.loads(saved.read_text())
    data["spec"]["seed"] = 6  # same file, other settings: a fresh run differs
    data.pop("checksum"), data.pop("schema")
    changed = tmp_path / "changed.json"
    changed.write_text(json.dumps(data))
    write_manifest(tmp_path)  # an old record without a checksum is read only if one vouches
    outcome = reproduce.run(reproduce.Settings(patterns=(str(changed),), workers=1))
    assert outcome.text.startswith("DIFFERENT") and not reproduce.all_reproduced(outcome)


def test_patterns_must_match_and_samples_are_seeded(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"match no whole trial file \(0 files matched\)"):
        reproduce.Settings(patterns=(str(tmp_path / "*.json"),)).paths()
    # a study's compact records and manifests are not whole trials
    (tmp_path / "compact.json").write_text('{"record": {"seed": 0}, "result": {}}')
    (tmp_path / "CHECKSUMS.sha256").write_text("")
    with pytest.raises(ValueError, match=r"\(2 files matched\)"):
        reproduce.Settings(patterns=(str(tmp_path / "*"),)).paths()
    for k in range(5):
        (tmp_path / f"t{k}.json").write_text("{}")
    pick = reproduce.Settings(patterns=(str(tmp_path / "*.json"),), sample=2, seed=3)
    assert pick.paths() == pick.paths() and len(pick.paths()) == 2
    assert "compact.json" not in " ".join(
        reproduce.Settings(patterns=(str(tmp_path / "*"),)).paths()
    )
