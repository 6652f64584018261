"""The arena digests and spec records of committed trials stay what they were saved with: a changed
digest would make every sweep refuse to resume its own results ("run with different settings")."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

import regime_map
import tavc_env
from tavc_agents.experiments.sweep import (
    FIELDS_OF_FIRST_DIGESTS,
    arena_digest,
    digest_text,
    spec_from_record,
    spec_record,
)

RESULTS = Path(__file__).resolve().parents[3] / "benchmarks" / "results"
PER_FOLDER = 3  # the first files of every results folder: every arena a study ran, at little cost


def committed_trials() -> list[Path]:
    paths = []
    for folder in sorted(RESULTS.glob("*/trials")):
        paths += sorted(folder.glob("*.json"))[:PER_FOLDER]
    return paths


def stored_spec(path: Path) -> dict[str, Any] | None:
    data = json.loads(path.read_text(encoding="utf-8"))
    if "record" in data and "result" in data:  # a study's compact record: no spec
        return None
    spec: dict[str, Any] | None = data.get("data", data).get("spec")
    return spec


@pytest.mark.parametrize("path", committed_trials(), ids=lambda p: f"{p.parts[-3]}/{p.name}")
def test_a_committed_trial_keeps_its_spec_record_and_arena_digest(path: Path) -> None:
    stored = stored_spec(path)
    if not stored:
        pytest.skip("a compact record or a trial run outside a sweep: no spec to check")
    record = spec_record(spec_from_record(stored))
    if "arena" not in stored:  # saved before records carried digests
        del record["arena"]
    assert record == stored


def test_the_regime_maps_arenas_keep_their_committed_digests() -> None:
    """Digests as the regime map's committed records store them (`arena_sha`)."""
    found: dict[str, str] = {}
    for path in sorted((RESULTS / "regime_map").glob("**/*.json")):
        with path.open("rb") as f:
            if f.read(11) != b'{"record": ':
                continue
        record = json.loads(path.read_text(encoding="utf-8"))["record"]
        if "arena_sha" in record:
            found.setdefault(record["arena"], record["arena_sha"])
    assert found, "no committed regime-map record carries a digest"
    assert {arena: regime_map.digest(arena) for arena in found} == found


def test_a_field_added_after_the_first_digests_enters_only_when_set() -> None:
    """Fields are derived from ArenaConfig: a new one needs no list of its own."""
    fields = {f.name: f for f in dataclasses.fields(tavc_env.ArenaConfig)}
    assert set(fields) > FIELDS_OF_FIRST_DIGESTS
    later = set(fields) - FIELDS_OF_FIRST_DIGESTS
    assert {"clearance_governor_m", "station_bays"} <= later
    plain = digest_text(tavc_env.preset("dahl2004"))
    for name in later:
        assert f"{name}=" not in plain
    bays = tavc_env.make_config("dahl2004", station_bays=2)
    assert "station_bays=2" in digest_text(bays)
    assert arena_digest({"preset": "dahl2004", "station_bays": 2}) != arena_digest({})


def test_env_options_do_not_enter_the_arena_digest() -> None:
    plain = arena_digest({"preset": "dahl2004"})
    assert arena_digest({"preset": "dahl2004", "decision_interval_s": 5.0}) == plain
    assert arena_digest({}) == plain
    with pytest.raises(ValueError, match=r"unknown configuration key\(s\) \['convergence_h'\]"):
        arena_digest({"preset": "dahl2004", "convergence_h": 1.0})
