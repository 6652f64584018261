"""The congestion design search: every candidate is a valid arena, and the committed rule picks
the lowest e among candidates with the knee (or the closest), no learning involved."""

from __future__ import annotations

import pytest

from tavc_agents.studies import congestion_design as design


def test_every_candidate_is_a_valid_physical_arena() -> None:
    assert len(design.CANDIDATES) == 15
    for c in design.CANDIDATES:
        config = c.config()
        assert config.clearance_governor_m == c.governor_m
        assert config.source_service_s == c.loading_s
        assert config.clearance_governor_m <= config.sensing_range_m - 2 * config.robot_radius


def _row(name: str, e: float, knee: float) -> dict[str, object]:
    return {"candidate": name, "e": e, "knee": knee}


def test_the_rule_takes_the_lowest_e_among_candidates_with_the_knee() -> None:
    rows = [_row("a", 0.9, 1.05), _row("b", 1.2, 1.3), _row("c", 1.1, 1.12), _row("d", 1.5, 1.4)]
    assert design.choose(rows, 1.1)["candidate"] == "c"  # type: ignore[index]
    assert design.choose(rows, 1.5) is None
    assert [r["candidate"] for r in design.frontier(rows)] == ["a", "c", "b", "d"]
    # e beats b and c on both counts
    more = [*rows, _row("e", 1.0, 1.35)]
    assert [r["candidate"] for r in design.frontier(more)] == ["a", "e", "d"]


def test_bad_settings_are_refused_naming_the_field() -> None:
    for field, value in (("seeds", 1), ("hours", 0.0), ("knee", 0.5)):
        with pytest.raises(ValueError, match=rf"^{field} = "):
            design.Settings(**{field: value})


def test_the_congestion_preset_is_the_committed_search_s_choice() -> None:
    import json

    import tavc_env
    from tavc_agents.studies.common import RESULTS_DIR

    report = json.loads((RESULTS_DIR / "congestion_design" / "congestion_design.json").read_text())
    chosen = report["summary"]["chosen"]["candidate"]
    (candidate,) = [c for c in design.CANDIDATES if c.name == chosen]
    assert tavc_env.preset("dahl2004_congestion") == candidate.config()


def test_the_bays_search_is_valid_and_keeps_the_first_search_s_names() -> None:
    assert len(design.BAYS_CANDIDATES) == 12
    for c in design.BAYS_CANDIDATES:
        config = c.config()
        assert config.station_bays == c.bays > 1
        assert c.name.endswith(f"_bays{c.bays}")
    # the first search's candidates (and so their stored runs) are named as they were
    assert design.CANDIDATES[-1].name == "gov2.56_load40"
    s = design.Settings(search="bays")
    assert s.candidates() == design.BAYS_CANDIDATES
    assert s.reference_dir().name == "congestion_design_bays"
    assert design.Settings().reference_dir().name == "congestion_design"
