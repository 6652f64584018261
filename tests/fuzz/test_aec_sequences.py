"""Fuzzing the AEC view's call sequences (issue 28, items 3 and 6): random sequences of `reset`,
`step`, `observe`, `last`, `agent_iter` (and the iterator's `next`) and `state`, with valid and
invalid agents and actions, before reset, mid-episode and after the end. Every call either does
what PettingZoo's AEC contract says (checked against a small model of the call order and the
documented action rule) or raises the package's ValueError of the kind the model predicts, naming
the call or the value; a refused call changes nothing. `TALLY` counts the outcomes per call."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

import tavc_env
from tavc_env.env import _arena_digest
from tests.fuzz.strategies import bad_actions, fuzz_settings, integer_like, is_valid_action

TALLY: Counter[str] = Counter()
"""Outcomes of the calls made, by `call: outcome` (read by a long run's summary)."""

N_CIRCUITS = 2  # dahl2004
AGENTS = st.one_of(
    st.sampled_from([f"robot_{i}" for i in range(6)]),
    st.sampled_from(["robot_99", "robot_6", "fast_0", "", "ROBOT_0"]),
    st.integers(-1, 7),
    st.none(),
    st.just(("robot_0",)),
)
ACTIONS = st.one_of(integer_like(0, N_CIRCUITS - 1), st.none(), bad_actions(N_CIRCUITS))
CALLS = st.one_of(
    st.tuples(st.just("reset"), st.integers(0, 2**32 - 1)),
    st.tuples(st.just("step"), ACTIONS),
    st.tuples(st.just("step"), integer_like(0, N_CIRCUITS - 1)),  # mostly valid: reach the end
    st.tuples(st.just("step"), integer_like(0, N_CIRCUITS - 1)),
    st.tuples(st.just("observe"), AGENTS),
    st.tuples(st.just("last"), st.booleans()),
    st.tuples(st.just("agent_iter"), st.none()),
    st.tuples(st.just("next"), st.none()),
    st.tuples(st.just("next"), st.none()),
    st.tuples(st.just("state"), st.none()),
    st.tuples(st.just("play"), st.integers(1, 14)),  # that many steps with good actions
    st.tuples(st.just("play"), st.integers(6, 14)),
)
BEFORE = r"called before reset\(\); allowed: call reset\(\) first$"
ENDED = r"called after the episode ended \(every agent is done\); allowed: call reset\(\) first$"


def _fingerprint(aec: Any, was_reset: bool) -> tuple[Any, ...]:
    if not was_reset:
        return ()
    inner = aec.env
    return (
        _arena_digest(aec.unwrapped.sim),
        inner.agent_selection,
        tuple(inner.agents),
        repr(sorted(inner._actions.items())),
        repr(sorted(inner._cumulative_rewards.items())),
        aec._has_updated,
    )


def _expected_step_error(aec: Any, action: Any) -> str | None:
    """What `step(action)` must refuse with (a regex), or None if it must be taken."""
    agent = aec.agent_selection
    if aec.terminations[agent] or aec.truncations[agent]:
        return None if action is None else rf"^action of {agent} = .* \(the agent is done\)$"
    if aec.unwrapped.must_decide(agent) and not is_valid_action(action, N_CIRCUITS):
        return rf"^(action of {agent} = .* is invalid; allowed: |missing action for {agent})"
    return None  # a valid action, or any action of a robot that need not decide (ignored)


def _check_contract(aec: Any) -> None:
    """PettingZoo's bookkeeping after a step taken (what api_test's play test checks)."""
    agents = set(aec.agents)
    assert agents <= set(aec.possible_agents)
    for table in (aec.rewards, aec.terminations, aec.truncations, aec.infos):
        assert set(table) == agents
    if agents:
        assert aec.agent_selection in agents


def _expanded(aec: Any, calls: list[tuple[str, Any]]) -> Iterator[tuple[str, Any]]:
    """The calls, each `play` as that many steps with an action the agent to step can take (0,
    or None once it is done), chosen when its turn comes (so the episode's end is reached)."""
    for call, arg in calls:
        if call != "play":
            yield call, arg
            continue
        for _ in range(arg):
            done = (
                aec._has_reset
                and bool(aec.agents)
                and (aec.terminations[aec.agent_selection] or aec.truncations[aec.agent_selection])
            )
            yield "step", None if done else 0


@fuzz_settings(60)
@given(
    max_cycles=st.integers(1, 3),
    reset_first=st.sampled_from([True, True, True, False]),
    calls=st.lists(CALLS, min_size=1, max_size=40),
)
def test_every_aec_call_sequence_is_correct_or_the_packages_error(
    max_cycles: int, reset_first: bool, calls: list[tuple[str, Any]]
) -> None:
    aec = tavc_env.env(max_cycles=max_cycles)
    was_reset = False
    loop: Iterator[str] | None = None
    if reset_first:
        calls = [("reset", 0), *calls]
    for k, (call, arg) in enumerate(_expanded(aec, calls)):
        where = f"call {k}: {call}({arg!r})"
        error: str | None = None
        if call == "reset":
            pass
        elif not was_reset and call != "next":
            error = f"^{call}\\(.*\\) {BEFORE}"
        elif call == "step":
            error = f"^step\\(.*\\) {ENDED}" if not aec.agents else _expected_step_error(aec, arg)
        elif call == "observe" and not (isinstance(arg, str) and arg in aec.possible_agents):
            error = r"^agent .* is unknown; allowed: \['robot_0', "
        elif call == "last" and not aec.agents:
            error = f"^last\\(\\) {ENDED}"
        elif call == "next" and loop is not None and aec.agents and not aec._has_updated:
            error = r"^the next agent of agent_iter\(\) was asked for before step\(\) of robot_\d"
        if call == "next" and loop is None:
            TALLY["next: no loop yet"] += 1
            continue
        before = _fingerprint(aec, was_reset)
        if error is not None:
            with pytest.raises(ValueError, match=error):
                _call(aec, call, arg, loop)
            assert _fingerprint(aec, was_reset) == before, (
                f"{where}: a refused call changed the env"
            )
            TALLY[f"{call}: refused, {_kind(error)}"] += 1
            continue
        selected = aec.agent_selection if was_reset and aec.agents else None
        out = _call(aec, call, arg, loop)
        TALLY[f"{call}: ok{', episode over' if was_reset and not aec.agents else ''}"] += 1
        if call == "reset":
            was_reset = True
            assert aec.agents == aec.possible_agents and aec.agent_selection == "robot_0"
        elif call == "step":
            assert out is None
            _check_contract(aec)
        elif call == "observe":
            assert aec.observation_space(arg).contains(out), where
        elif call == "last":
            observation, reward, terminated, truncated, info = out
            assert (observation is None) != arg, where
            assert info == aec.infos[selected] and float(reward) == reward
            assert (terminated, truncated) == (
                aec.terminations[selected],
                aec.truncations[selected],
            )
        elif call == "agent_iter":
            loop = iter(out)
        elif call == "next":
            assert out == "StopIteration" if not aec.agents else out == selected, where
        elif call == "state":
            assert aec.unwrapped.state_space.contains(out), where


def _kind(error: str) -> str:
    for part, kind in (
        ("before reset", "before reset"),
        ("episode ended", "after the end"),
        ("unknown", "unknown agent"),
        ("done", "action of a done agent"),
        ("action", "bad action"),
        ("next agent", "no step between"),
    ):
        if part in error:
            return kind
    raise AssertionError(error)


def _call(aec: Any, call: str, arg: Any, loop: Iterator[str] | None) -> Any:
    if call == "reset":
        return aec.reset(seed=arg)
    if call == "step":
        return aec.step(arg)
    if call == "observe":
        return aec.observe(arg)
    if call == "last":
        return aec.last(observe=arg)
    if call == "agent_iter":
        return aec.agent_iter()
    if call == "next":
        assert loop is not None
        return next(loop, "StopIteration")
    return aec.state()


def test_the_model_predicts_every_kind_of_outcome() -> None:
    """The checker itself: a fixed sequence through every refusal and success path gives the
    tally it should (a fuzz test whose model never predicted a refusal would prove nothing)."""
    TALLY.clear()
    calls: list[tuple[str, Any]] = [("step", 0), ("observe", "robot_99"), ("reset", 0)]
    calls += [("observe", "robot_99"), ("observe", "robot_3"), ("agent_iter", None)]
    calls += [("next", None), ("next", None), ("step", 5), ("step", 0), ("play", 5)]
    calls += [("step", 1), ("play", 6), ("step", 0), ("last", True), ("state", None)]
    test_every_aec_call_sequence_is_correct_or_the_packages_error.hypothesis.inner_test(  # type: ignore[attr-defined]
        max_cycles=1, reset_first=False, calls=calls
    )
    expected = {
        "step: refused, before reset": 1,
        "observe: refused, before reset": 1,
        "reset: ok": 1,
        "observe: refused, unknown agent": 1,
        "observe: ok": 1,
        "agent_iter: ok": 1,
        "next: ok": 1,
        "next: refused, no step between": 1,
        "step: refused, bad action": 1,
        "step: ok": 11,  # robots 0-5 decide (the cycle ends truncated), 5 done agents step out
        "step: refused, action of a done agent": 1,
        "step: ok, episode over": 1,  # the last one
        "step: refused, after the end": 1,
        "last: refused, after the end": 1,
        "state: ok, episode over": 1,
    }
    assert dict(TALLY) == expected
