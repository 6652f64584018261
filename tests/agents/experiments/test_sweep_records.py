"""A saved trial's spec record makes its `TrialSpec` again, whatever facts the record derives from
it (the arena's digest; on a scenario, that the env is reset with the seed itself)."""

from __future__ import annotations

import pytest

from tavc_agents.experiments.sweep import TrialSpec, spec_from_record, spec_record


@pytest.mark.parametrize("env_kwargs", [{"scenario": "bad_start"}, {"preset": "dahl2004"}, {}])
def test_a_spec_record_makes_its_spec_again(env_kwargs: dict[str, str]) -> None:
    spec = TrialSpec(key="k", allocator="stay", seed=3, env_kwargs=env_kwargs, measured_s=60.0)
    record = spec_record(spec)
    assert ("reset_seed" in record) == ("scenario" in env_kwargs)
    assert spec_from_record(record) == spec
