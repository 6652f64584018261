"""The congestion design search: every candidate is a valid arena, and the committed rule picks
the lowest e among candidates with the knee (or the closest), no learning involved."""

from __future__ import annotations

import pytest

import congestion_design as design


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
    from tavc_agents.experiments.study import RESULTS_DIR

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


def test_the_passing_search_is_valid_and_keeps_the_other_searches_names() -> None:
    assert len(design.PASSING_CANDIDATES) == 18
    names = {c.name for c in design.PASSING_CANDIDATES}
    assert len(names) == 18 and all(n.endswith("_pass") for n in names)
    assert not names & {c.name for c in design.CANDIDATES + design.BAYS_CANDIDATES}
    for c in design.PASSING_CANDIDATES:
        config = c.config()
        assert config.overtaking and config.station_bays == c.bays > 1
        assert config.clearance_governor_m <= config.sensing_range_m - 2 * config.robot_radius
    assert design.Settings(search="passing").n_seeds == 5
    assert design.Settings(search="bays").n_seeds == 3
    assert design.Settings(search="passing", seeds=7).n_seeds == 7


def _prow(name: str, e: float, e_high: float, knee: float, rho: float) -> dict[str, object]:
    return {"candidate": name, "e": e, "e_high": e_high, "knee": knee, "rho": rho}


def test_the_passing_rule_ranks_by_targets_met_then_by_e() -> None:
    rows = [
        _prow("low_e_no_knee", 0.80, 0.90, 1.05, 1.30),  # 2 targets
        _prow("all_three", 0.93, 0.99, 1.12, 1.26),  # 3 targets
        _prow("wide_interval", 0.90, 1.05, 1.20, 1.25),  # e's upper end misses: 2 targets
        _prow("held_back", 1.30, 1.40, 1.30, 1.00),  # 1 target
    ]
    order = [r["candidate"] for r in design.passing_order(rows, 1.1)]
    assert order == ["all_three", "low_e_no_knee", "wide_interval", "held_back"]
    assert design.targets_met(rows[2], 1.1) == {"e": False, "knee": True, "rho": True}
    without = [r for r in rows if r["candidate"] != "all_three"]
    assert design.passing_order(without, 1.1)[0]["candidate"] == "low_e_no_knee"
    # on e and the knee alone "all_three" is beaten by "wide_interval"; with rho it is not
    assert "all_three" not in [r["candidate"] for r in design.frontier(rows)]
    assert "all_three" in [r["candidate"] for r in design.frontier(rows, with_rho=True)]


def test_the_passing_preset_is_the_committed_search_s_choice() -> None:
    import json

    import tavc_env
    from tavc_agents.experiments.study import RESULTS_DIR

    folder = RESULTS_DIR / "congestion_design_passing"
    report = json.loads((folder / "congestion_design.json").read_text())
    chosen = report["summary"]["chosen"]["candidate"]
    assert chosen == report["summary"]["order"][0]
    (candidate,) = [c for c in design.PASSING_CANDIDATES if c.name == chosen]
    assert tavc_env.preset("dahl2004_passing") == candidate.config()
