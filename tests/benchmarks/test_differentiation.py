"""The differentiation study at a tiny size: its cells, tags, report and resume."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

import differentiation as study


def test_specs_are_tagged_and_keyed_from_their_tags() -> None:
    settings = study.Settings(regimes="stations,competence", temperatures="0.005,0.02", trials=2)
    specs = study.specs(settings)
    assert len(specs) == 2 * (2 + 2) * 2  # regimes x (temperatures + epsilon + random) x trials
    first = specs[0]
    assert first.tags == {
        "regime": "stations",
        "condition": "softmax_T0p005",
        "seed": 0,
        "temperature": 0.005,
    }
    assert first.key == "stations__softmax_T0p005__seed0"
    competence = [s for s in specs if s.tags["regime"] == "competence"]
    assert all(s.env_kwargs["service_scales_with_speed"] is True for s in competence)
    assert {s.allocator for s in specs} == {"softmax_tavc", "epsilon_tavc", "random"}


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"regimes": "stations,moon"}, "regimes = 'stations,moon' is invalid"),
        ({"temperatures": "0.01,-1"}, "temperatures = '0.01,-1' is invalid"),
        ({"temperatures": "hot"}, "temperatures = 'hot' is invalid"),
        ({"trials": 0}, "trials = 0 is invalid"),
        ({"measured_h": 0.0}, "measured_h = 0.0 is invalid"),
    ],
)
def test_bad_settings_name_the_field(changes: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        study.Settings(**changes)  # type: ignore[arg-type]


def test_a_tiny_run_reports_every_cell_and_resumes(tmp_path: Path) -> None:
    settings = study.Settings(
        regimes="stations",
        temperatures="0.005,0.05",
        trials=2,
        convergence_h=0.05,
        measured_h=0.05,
        workers=1,
        out=tmp_path,
    )
    outcome = study.run(settings)
    with open(tmp_path / "differentiation.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["regime"], r["condition"], r["trials"]) for r in rows] == [
        ("stations", "softmax_T0p005", "2"),
        ("stations", "softmax_T0p05", "2"),
        ("stations", "epsilon", "2"),
        ("stations", "random", "2"),
    ]
    for r in rows:
        share_gap = float(r["fast_share"]) - float(r["slow_share"])
        assert float(r["fast_minus_slow"]) == pytest.approx(share_gap)
    assert float(rows[-1]["ratio_to_random"]) == pytest.approx(1.0)
    md = (tmp_path / "differentiation.md").read_text()
    assert "## Paired against the lowest temperature" in md and "0.05 vs 0.005" in md
    assert "wall time" in outcome.text
    before = md
    study.run(settings)  # everything resumed: the same report, byte for byte
    assert (tmp_path / "differentiation.md").read_text() == before
