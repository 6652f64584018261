"""The batched twin: it refuses what it does not model, is reproducible from its generator, keeps
its measures in range, and agrees in distribution with the Policy-based twin run by `run_trial`
(Welch intervals of the difference; the random streams differ, so not trial by trial)."""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np
import pytest
from scipy import stats

import tavc_env
from arena_runs import Learner, run_batch
from tavc_agents.analysis.measures import measure
from tavc_agents.experiments.registry import make_allocator
from tavc_agents.experiments.runner import run_trial
from tavc_agents.learners.tavc import TavcParams
from tavc_env.config import Breakdown
from tavc_env.twin import InterferenceTables, random_allocation_run

DAHL = tavc_env.preset("dahl2004")


def mean_of(circuit: int, counts: tuple[int, ...], cls: str) -> float:
    lone = 60.0 if cls == "fast" else 80.0
    return lone * (1 + 0.25 * (sum(counts) - 1)) * (1.2 if circuit == 0 else 1.0)


TABLES = InterferenceTables.from_function(DAHL, mean_of, 10.0, switch_cost=1.3)
HOURS: dict[str, Any] = {"convergence_s": 2 * 3600.0, "measured_s": 2 * 3600.0}


def test_it_refuses_what_it_does_not_model() -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match=r"^learner.kind = 'auction' is invalid"):
        Learner("auction")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^learner.parameter = 0.0 is invalid"):
        Learner("softmax")
    broken = DAHL.replace(breakdowns=(Breakdown(0, 3600.0, 600.0),))
    with pytest.raises(ValueError, match=r"^config.breakdowns = .* is invalid"):
        run_batch(broken, TABLES, Learner("random"), 10, rng)
    with pytest.raises(ValueError, match=r"^trials = 0 is invalid"):
        run_batch(DAHL, TABLES, Learner("random"), 0, rng)
    three = tavc_env.preset("three_circuits_three_classes")
    with pytest.raises(ValueError, match=r"^tables = .* is invalid"):
        run_batch(three, TABLES, Learner("random"), 10, rng)


def test_same_generator_same_batch_and_measures_in_range() -> None:
    learner = Learner("softmax", 0.005)
    a = run_batch(DAHL, TABLES, learner, 40, np.random.default_rng(7), **HOURS)
    b = run_batch(DAHL, TABLES, learner, 40, np.random.default_rng(7), **HOURS)
    for field in ("fast_share", "slow_share", "performance", "q_gap_fast", "states"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert a.fast_share.shape == (40,) and a.states.shape == (40, 4, 4)
    np.testing.assert_allclose(a.states.sum(axis=(1, 2)), 1.0)
    assert ((a.fast_share >= 0) & (a.fast_share <= 1)).all()
    # 3 robots per class: the mean share of each class on circuit 0 is the states' marginal
    f = np.arange(4)[None, :, None]
    np.testing.assert_allclose((a.states * f).sum(axis=(1, 2)) / 3, a.fast_share)
    assert np.isnan(
        run_batch(DAHL, TABLES, Learner("random"), 5, np.random.default_rng(0), **HOURS).q_gap_fast
    ).all()


# tables measured among learners: first tasks from the start (staying or leaving) and a switch
# cost per class (`tavc_env.twin.learner_tables`)
LEARNER_TABLES = dataclasses.replace(
    TABLES,
    class_switch_costs=(0.9, 1.6),
    first_own_cells=tuple(dataclasses.replace(c, mean_s=c.mean_s * 0.6) for c in TABLES.cells),
    first_switch_cells=tuple(dataclasses.replace(c, mean_s=c.mean_s * 2.0) for c in TABLES.cells),
)


@pytest.mark.parametrize(
    ("allocator", "params", "learner", "tables"),
    [
        (
            "softmax_tavc",
            {"temperature": 0.005, "init": "scaled"},
            Learner("softmax", 0.005),
            TABLES,
        ),
        ("epsilon_tavc", {"epsilon": 0.1, "init": "scaled"}, Learner("epsilon", 0.1), TABLES),
        (
            "softmax_tavc",
            {"temperature": 0.005, "init": "scaled"},
            Learner("softmax", 0.005),
            LEARNER_TABLES,
        ),
        (
            "softmax_tavc",
            {"temperature": 0.005, "init": "paper"},
            Learner("softmax", 0.005, TavcParams(init="paper")),
            LEARNER_TABLES,
        ),
    ],
)
def test_it_agrees_with_the_policy_based_twin(
    allocator: str, params: dict[str, object], learner: Learner, tables: InterferenceTables
) -> None:
    twin = functools.partial(tavc_env.twin_parallel_env, tables=tables)
    trials = [
        measure(
            run_trial(
                make_allocator(allocator, **params),
                seed=seed,
                env_factory=twin,
                snapshot_every_s=4 * 3600.0,
                arena="dahl2004",
                **HOURS,
            )
        )
        for seed in range(40)
    ]
    batch = run_batch(DAHL, tables, learner, 400, np.random.default_rng(1), **HOURS)
    pairs = {
        "fast - slow": (
            batch.fast_share - batch.slow_share,
            [t.fast_share - t.slow_share for t in trials],
        ),
        "performance": (batch.performance, [t.performance for t in trials]),
    }
    pairs["Q gap"] = (
        batch.q_gap_fast - batch.q_gap_slow,
        [t.q_gap_fast - t.q_gap_slow for t in trials],
    )
    for name, (ours, theirs) in pairs.items():
        # 6 comparisons in this test: each at the 0.1 % level, so that a correct batch passes
        # them all with probability 0.99
        ci = stats.ttest_ind(ours, theirs, equal_var=False).confidence_interval(0.999)
        assert ci.low <= 0 <= ci.high, (name, np.mean(ours) - np.mean(theirs), ci)


def test_random_choice_agrees_with_the_twin_engine_driven_directly() -> None:
    """Random choice has no learner to get wrong, so the twin's own engine, driven by
    `random_allocation_run`, is the reference here (fast enough for 300 trials)."""
    batch = run_batch(DAHL, TABLES, Learner("random"), 400, np.random.default_rng(1), **HOURS)
    engine = [
        random_allocation_run(DAHL, seed, 4.0, 2 * 3600.0, "twin", TABLES).performance
        for seed in range(300)
    ]
    ci = stats.ttest_ind(batch.performance, engine, equal_var=False).confidence_interval(0.99)
    assert ci.low <= 0 <= ci.high, ci
    assert abs(np.mean(batch.performance) / np.mean(engine) - 1) < 0.005
