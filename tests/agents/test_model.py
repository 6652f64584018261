"""The TAVC model (`tavc_agents.model`) on synthetic data with known answers: Equation 1 slot values, the
team's value rate and the paper's performance measure by hand, the exhaustive optimum against hand
reasoning and against brute force over robot-level assignments, neighbours, storage, bad input,
speed classes, robot-level realisations, the model built from measured runs, and one small real
estimation from simulation.

The synthetic model: a robot of class j alone completes a task every T_j seconds (fast 60 s, slow
90 s); a group on a circuit completes sum_j n_j / T_j tasks per second while it has at most three
robots, and a quarter of that above three (the crowd collapses). With values (2200, 2000) and the
team (3 fast, 3 slow), every allocation with four or more robots on a circuit loses a lot, so the
optimum splits 3 + 3, and moving a robot from circuit 1 to circuit 0 gains 200 / T_j: the three
fast robots take circuit 0.
"""

from __future__ import annotations

import itertools
import json
import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import tavc_env
from arena_runs import estimate_model, group_specs, measured_rate
from tavc_agents.model import (
    Allocation,
    CompletionModel,
    SpeedClasses,
    fs_label,
    model_from_runs,
    robot_circuits,
)
from tavc_env import Robot

T_FAST, T_SLOW = 60.0, 90.0
VALUES = (2200.0, 2000.0)
OPTIMUM = ((3, 0), (0, 3))


def crowd(n: int) -> float:
    """The synthetic interference: no loss up to three robots, a collapse to a quarter above."""
    return 1.0 if n <= 3 else 0.25


def synthetic_rate(group: tuple[int, ...], times: tuple[float, ...] = (T_FAST, T_SLOW)) -> float:
    return sum(n / t for n, t in zip(group, times)) * crowd(sum(group))


def synthetic_model(
    values: tuple[float, ...] = VALUES, team: tuple[int, ...] = (3, 3)
) -> CompletionModel:
    rates = np.zeros((len(values), *(n + 1 for n in team)))
    for i in range(len(values)):
        for group in itertools.product(*(range(n + 1) for n in team)):
            index = (i, *group)
            rates[index] = synthetic_rate(group)
    return CompletionModel(("fast", "slow"), team, values, rates)


def hand_value_rate(allocation: Allocation, values: tuple[float, ...] = VALUES) -> float:
    return sum(w * synthetic_rate(g) for w, g in zip(values, allocation))


# -- the optimum and the search ----------------------------------------------------------------


def test_optimum_is_three_fast_on_the_valuable_circuit() -> None:
    model = synthetic_model()
    assert model.optimum() == OPTIMUM
    # 2200 * 3/60 + 2000 * 3/90 = 110 + 66.67 tasks-value per second
    assert model.value_rate(OPTIMUM) == pytest.approx(2200 * 3 / 60 + 2000 * 3 / 90, rel=1e-12)
    # The runner-up swaps one fast and one slow robot: it loses 200 * (1/60 - 1/90).
    best, second = model.ranked()[:2]
    assert best[0] - second[0] == pytest.approx(200 * (1 / 60 - 1 / 90), rel=1e-9)
    assert second[1] == ((2, 1), (1, 2))


def test_ranked_is_sorted_complete_and_scored_by_value_rate() -> None:
    model = synthetic_model()
    ranked = model.ranked()
    scores = [score for score, _ in ranked]
    assert scores == sorted(scores, reverse=True)
    # product over classes of C(n_k + m - 1, m - 1): C(4, 1)^2 = 16 for (3, 3) on two circuits
    assert len(ranked) == math.comb(3 + 1, 1) ** 2 == 16
    allocations = [a for _, a in ranked]
    assert len(set(allocations)) == len(allocations)
    assert set(allocations) == set(model.allocations())
    for score, allocation in ranked:
        assert all(sum(g[k] for g in allocation) == 3 for k in range(2))
        assert score == pytest.approx(hand_value_rate(allocation), rel=1e-12)


def test_allocation_count_for_three_circuits_and_uneven_team() -> None:
    rates = np.zeros((3, 3, 5, 2))
    rates[:, 1:, :, :] = 0.01
    rates[:, :, 1:, :] = 0.01
    rates[:, :, :, 1:] = 0.01
    model = CompletionModel(("a", "b", "c"), (2, 4, 1), (3.0, 2.0, 1.0), rates)
    expected = math.comb(2 + 2, 2) * math.comb(4 + 2, 2) * math.comb(1 + 2, 2)
    assert len(list(model.allocations())) == len(model.ranked()) == expected == 6 * 15 * 3


def test_slot_values_follow_equation_1_by_hand() -> None:
    model = synthetic_model()
    # a slow robot joining two fast ones on circuit 0: 2200 * ((2/60 + 1/90) - 2/60) = 2200/90
    assert model.slot_value(0, (2, 0), 1) == pytest.approx(2200 / 90, rel=1e-12)
    # a fast robot joining an empty circuit 1: 2000 / 60
    assert model.slot_value(1, (0, 0), 0) == pytest.approx(2000 / 60, rel=1e-12)
    # a fourth robot collapses the crowd: 2200 * ((3/60 + 1/90) / 4 - 3/60) < 0
    fourth = 2200 * ((3 / 60 + 1 / 90) * 0.25 - 3 / 60)
    assert fourth < 0
    assert model.slot_value(0, (3, 0), 1) == pytest.approx(fourth, rel=1e-12)
    for i, w in enumerate(VALUES):
        for group in itertools.product(range(4), range(4)):
            for k in range(2):
                if group[k] == 3:
                    continue
                joined = tuple(n + (j == k) for j, n in enumerate(group))
                expected = w * (synthetic_rate(joined) - synthetic_rate(group))
                assert model.slot_value(i, group, k) == pytest.approx(
                    expected, rel=1e-12, abs=1e-15
                )
                assert model.rate(i, group) == pytest.approx(synthetic_rate(group), rel=1e-12)


def test_value_rate_and_performance_by_hand() -> None:
    model = synthetic_model()
    allocation = ((2, 1), (1, 1))
    value_rate = 2200 * (2 / 60 + 1 / 90) + 2000 * (1 / 60 + 1 / 90)
    assert model.value_rate(allocation) == pytest.approx(value_rate, rel=1e-12)
    # w / max w per delivery, per robot (5 here), per 10 s
    assert model.performance(allocation) == pytest.approx(value_rate / 2200 / 5 * 10, rel=1e-12)
    assert model.performance(OPTIMUM) == pytest.approx(
        (3 / 60 + 2000 / 2200 * 3 / 90) / 6 * 10, rel=1e-12
    )
    # nobody: nothing delivered, and no division by zero
    assert model.value_rate(((0, 0), (0, 0))) == 0.0
    assert model.performance(((0, 0), (0, 0))) == 0.0


def test_neighbours_are_exactly_the_single_robot_moves() -> None:
    model = synthetic_model()
    allocation = ((2, 1), (1, 2))
    found = model.neighbours(allocation)
    # two circuits x two classes, every (circuit, class) cell non-empty: 4 moves
    assert len(found) == len(set(found)) == 4
    for other in found:
        diff = np.array(other) - np.array(allocation)
        assert np.abs(diff).sum() == 2  # one robot left a circuit, one arrived on another
        assert diff.sum(axis=0).tolist() == [0, 0]  # of the same class
    assert set(found) == {((1, 1), (2, 2)), ((2, 0), (1, 3)), ((3, 1), (0, 2)), ((2, 2), (1, 1))}
    # an empty cell cannot lose a robot: from the optimum only the fast robots on 0 and the slow
    # robots on 1 can move
    assert sorted(model.neighbours(OPTIMUM)) == [((2, 0), (1, 3)), ((3, 1), (0, 2))]


def test_neighbours_on_three_circuits_count_moves() -> None:
    model = synthetic_model(values=(3.0, 2.0, 1.0))
    allocation = ((3, 0), (0, 2), (0, 1))
    found = model.neighbours(allocation)
    # three non-empty (circuit, class) cells, each can move to 2 other circuits
    assert len(found) == len(set(found)) == 6
    for other in found:
        diff = np.array(other) - np.array(allocation)
        assert np.abs(diff).sum() == 2 and diff.sum(axis=0).tolist() == [0, 0]


def test_optimum_of_a_reduced_team_fills_the_valuable_circuit_first() -> None:
    model = synthetic_model()
    # Five robots: three on circuit 0 (each robot is worth 200 / T more there), the fast ones first.
    assert model.optimum((2, 3)) == ((2, 1), (0, 2))
    assert all(sum(sum(g[k] for g in a) for k in range(2)) == 5 for _, a in model.ranked((2, 3)))
    assert len(model.ranked((2, 3))) == 3 * 4
    # one robot of each class: both on circuit 0
    assert model.optimum((1, 1)) == ((1, 1), (0, 0))


def test_with_values_moves_the_fast_robots_to_the_now_valuable_circuit() -> None:
    model = synthetic_model()
    swapped = model.with_values((2000.0, 2200.0))
    assert swapped.optimum() == ((0, 3), (3, 0))
    assert swapped.values == (2000.0, 2200.0)
    assert model.values == VALUES  # the original is unchanged
    assert np.array_equal(swapped.rates, model.rates)
    assert swapped.value_rate(((0, 3), (3, 0))) == pytest.approx(model.value_rate(OPTIMUM))


def test_rates_are_read_only() -> None:
    model = synthetic_model()
    with pytest.raises(ValueError, match="read-only"):
        model.rates[0, 1, 0] = 5.0


def test_dict_round_trip_including_json_and_standard_errors() -> None:
    model = synthetic_model()
    se = np.full(model.rates.shape, 0.001)
    with_se = CompletionModel(model.classes, model.team, model.values, model.rates, se)
    for original in (model, with_se):
        data = json.loads(json.dumps(original.to_dict()))
        copy = CompletionModel.from_dict(data)
        assert copy.classes == original.classes
        assert copy.team == original.team
        assert copy.values == original.values
        assert np.array_equal(copy.rates, original.rates)
        if original.rates_se is None:
            assert copy.rates_se is None
        else:
            assert copy.rates_se is not None
            assert np.array_equal(copy.rates_se, original.rates_se)
        assert copy.ranked() == original.ranked()
    assert "rates_se" not in model.to_dict()


def test_three_circuits_three_classes_optimum_agrees_with_robot_level_brute_force() -> None:
    """Arbitrary (seeded random, non-monotone) frequencies: the exhaustive search over class counts
    finds the best of all 3^9 robot-level assignments."""
    rng = np.random.default_rng(12345)
    team = (3, 3, 3)
    values = (2200.0, 2000.0, 1800.0)
    rates = rng.uniform(0.0, 0.05, size=(3, 4, 4, 4))
    rates[:, 0, 0, 0] = 0.0
    model = CompletionModel(("fast", "medium", "slow"), team, values, rates)
    of_robot = [k for k, n in enumerate(team) for _ in range(n)]
    best = -1.0
    best_allocations: set[Allocation] = set()
    for circuits in itertools.product(range(3), repeat=9):
        counts = [[0, 0, 0] for _ in range(3)]
        for c, k in zip(circuits, of_robot):
            counts[c][k] += 1
        score = sum(values[i] * float(rates[i][tuple(counts[i])]) for i in range(3))
        allocation = tuple(tuple(g) for g in counts)
        if score > best + 1e-12:
            best, best_allocations = score, {allocation}
        elif abs(score - best) <= 1e-12:
            best_allocations.add(allocation)
    assert model.value_rate(model.optimum()) == pytest.approx(best, rel=1e-12)
    assert model.optimum() in best_allocations
    assert len(model.ranked()) == math.comb(5, 2) ** 3 == 1000


# -- bad input ---------------------------------------------------------------------------------


def rates_33() -> np.ndarray:
    return np.array(synthetic_model().rates)


def test_wrong_rates_shape_raises() -> None:
    with pytest.raises(ValueError, match=r"rates\.shape = \(2, 4, 3\).*\(2, 4, 4\)"):
        CompletionModel(("fast", "slow"), (3, 3), VALUES, np.zeros((2, 4, 3)))
    with pytest.raises(ValueError, match=r"rates\.shape .*\(3, 4, 4\)"):
        CompletionModel(("fast", "slow"), (3, 3), (3.0, 2.0, 1.0), rates_33())


@pytest.mark.parametrize("bad", [-0.01, float("nan"), float("inf")])
def test_negative_or_non_finite_rates_raise(bad: float) -> None:
    rates = rates_33()
    rates[1, 2, 1] = bad
    with pytest.raises(ValueError, match=r"rates = .*allowed: finite frequencies >= 0"):
        CompletionModel(("fast", "slow"), (3, 3), VALUES, rates)


def test_rate_of_the_empty_group_must_be_zero() -> None:
    rates = rates_33()
    rates[1, 0, 0] = 0.5
    with pytest.raises(
        ValueError, match=r"rates of the empty group = \[0\.0, 0\.5\].*0 \(no robot"
    ):
        CompletionModel(("fast", "slow"), (3, 3), VALUES, rates)


def test_rates_se_shape_must_match() -> None:
    with pytest.raises(ValueError, match=r"rates_se\.shape = \(2, 4\).*like rates"):
        CompletionModel(("fast", "slow"), (3, 3), VALUES, rates_33(), np.zeros((2, 4)))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"classes": ()}, r"classes = \(\) .*at least one speed class"),
        ({"team": (3,)}, r"team = \(3,\) .*2 robot counts >= 0"),
        ({"team": (3, -1)}, r"team = \(3, -1\) .*2 robot counts >= 0"),
        ({"values": (2200.0, 0.0)}, r"values = .*one value > 0 per circuit"),
        ({"values": (2200.0, float("nan"))}, r"values = .*one value > 0 per circuit"),
    ],
)
def test_bad_classes_team_or_values_raise(kwargs: dict[str, Any], message: str) -> None:
    args: dict[str, Any] = {
        "classes": ("fast", "slow"),
        "team": (3, 3),
        "values": VALUES,
        "rates": rates_33(),
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        CompletionModel(**args)


def test_group_outside_the_team_raises() -> None:
    model = synthetic_model()
    allowed = r"allowed: counts per class within the team \[3, 3\]"
    with pytest.raises(ValueError, match=rf"group = \[4, 0\] is invalid; {allowed}"):
        model.rate(0, (4, 0))
    with pytest.raises(ValueError, match=rf"group = \[0, -1\] is invalid; {allowed}"):
        model.rate(0, (0, -1))
    with pytest.raises(ValueError, match=rf"group = \[1, 1, 1\] is invalid; {allowed}"):
        model.rate(0, (1, 1, 1))
    # joining a full class leaves the team
    with pytest.raises(ValueError, match=r"group = \[4, 1\]"):
        model.slot_value(0, (3, 1), 0)
    with pytest.raises(ValueError, match=r"cls = 2 is invalid; allowed: a class in \[0, 2\)"):
        model.slot_value(0, (0, 0), 2)
    with pytest.raises(ValueError, match=r"group = \[4, 3\]"):
        model.optimum((4, 3))


def test_unknown_or_missing_keys_in_from_dict_raise() -> None:
    data = synthetic_model().to_dict()
    with pytest.raises(ValueError, match=r"model keys = \['speeds'\] .*only \["):
        CompletionModel.from_dict({**data, "speeds": [0.3, 0.2]})
    partial = {k: v for k, v in data.items() if k != "rates"}
    with pytest.raises(ValueError, match=r"model keys missing = \['rates'\]"):
        CompletionModel.from_dict(partial)


def test_allocation_with_more_robots_than_the_team_raises() -> None:
    model = synthetic_model()
    with pytest.raises(ValueError, match=r"allocation = .*at most the team \[3, 3\] in total"):
        model.value_rate(((3, 3), (1, 0)))
    with pytest.raises(ValueError, match=r"allocation = .*at most the team"):
        model.neighbours(((2, 2), (2, 0)))
    with pytest.raises(ValueError, match=r"allocation = .*one group per circuit \(2\)"):
        model.value_rate(((3, 3),))
    with pytest.raises(ValueError, match=r"allocation = .*one group per circuit \(2\)"):
        model.performance(((1, 1), (1, 1), (1, 1)))


# -- speed classes and robot-level allocations -------------------------------------------------


def test_speed_classes_of_the_paper_arena() -> None:
    classes = SpeedClasses.of(tavc_env.make_config("dahl2004"))
    assert classes.labels == ("fast", "slow")
    assert classes.team == (3, 3)
    assert classes.of_robot == (0, 0, 0, 1, 1, 1)
    assert [r.speed for r in classes.robots] == [0.30, 0.20]


def test_speed_classes_of_three_classes_are_fastest_first() -> None:
    classes = SpeedClasses.of(tavc_env.make_config("three_circuits_three_classes"))
    assert classes.labels == ("fast", "medium", "slow")
    assert classes.team == (3, 3, 3)
    assert classes.of_robot == (0, 0, 0, 1, 1, 1, 2, 2, 2)
    assert [r.speed for r in classes.robots] == [0.30, 0.25, 0.20]


def test_speed_classes_of_interleaved_robots() -> None:
    config = tavc_env.make_config("dahl2004", speeds=[0.2, 0.3, 0.2, 0.3, 0.3, 0.2])
    classes = SpeedClasses.of(config)
    assert classes.labels == ("fast", "slow")
    assert classes.of_robot == (1, 0, 1, 0, 0, 1)
    assert classes.team == (3, 3)


def test_a_label_shared_by_two_speeds_raises() -> None:
    robots = (Robot(0.3, "fast"), Robot(0.25, "fast"), *(Robot(0.2, "slow") for _ in range(4)))
    config = tavc_env.make_config("dahl2004", robots=robots)
    with pytest.raises(
        ValueError, match=r"robots\[1\]\.speed = 0\.25 .*0\.3 like the other 'fast'"
    ):
        SpeedClasses.of(config)


def test_robot_circuits_fill_circuit_0_first_within_each_class() -> None:
    config = tavc_env.make_config("dahl2004", speeds=[0.2, 0.3, 0.2, 0.3, 0.3, 0.2])
    classes = SpeedClasses.of(config)  # fast: robots 1, 3, 4; slow: robots 0, 2, 5
    assert robot_circuits(((2, 1), (1, 2)), classes) == [0, 0, 1, 0, 1, 1]
    assert robot_circuits(((3, 0), (0, 3)), classes) == [1, 0, 1, 0, 0, 1]
    assert robot_circuits(((0, 3), (3, 0)), classes) == [0, 1, 0, 1, 1, 0]
    three = SpeedClasses.of(tavc_env.make_config("three_circuits_three_classes"))
    assert robot_circuits(((1, 0, 2), (1, 3, 0), (1, 0, 1)), three) == [0, 1, 2, 1, 1, 1, 0, 0, 2]


def test_robot_circuits_reject_an_allocation_that_is_not_the_team() -> None:
    classes = SpeedClasses.of(tavc_env.make_config("dahl2004"))
    with pytest.raises(ValueError, match=r"allocation for robot 5 = .*a place per robot"):
        robot_circuits(((3, 0), (0, 2)), classes)
    with pytest.raises(ValueError, match=r"allocation = .*exactly the team \[3, 3\]"):
        robot_circuits(((3, 1), (0, 3)), classes)


def test_fs_label() -> None:
    assert fs_label(((2, 1), (1, 2))) == "2:1"
    assert fs_label(((2, 1), (1, 2)), circuit=1) == "1:2"
    assert fs_label(((1, 0, 2), (0, 0, 0)), circuit=1) == "0:0:0"


# -- estimation --------------------------------------------------------------------------------


def two_robot_config() -> tavc_env.ArenaConfig:
    return tavc_env.make_config("dahl2004", speeds=[0.3, 0.2])


def test_model_from_runs_averages_repeats_with_standard_errors() -> None:
    config = two_robot_config()  # one fast, one slow robot, two circuits
    runs = [
        (0, (1, 0), 0.01),
        (0, (1, 0), 0.02),
        (0, (1, 0), 0.03),
        (0, (0, 1), 0.012),
        (0, (1, 1), 0.025),
        (0, (1, 1), 0.027),
        (1, (1, 0), 0.016),
        (1, (0, 1), 0.011),
        (1, (1, 1), 0.022),
    ]
    model = model_from_runs(config, runs)
    assert model.classes == ("fast", "slow")
    assert model.team == (1, 1)
    assert model.values == VALUES
    assert model.rates.shape == (2, 2, 2)
    assert model.rate(0, (1, 0)) == pytest.approx(0.02, rel=1e-12)
    assert model.rate(0, (1, 1)) == pytest.approx(0.026, rel=1e-12)
    assert model.rate(1, (0, 1)) == pytest.approx(0.011, rel=1e-12)
    assert model.rate(1, (0, 0)) == 0.0
    assert model.rates_se is not None
    # sample sd of (0.01, 0.02, 0.03) is 0.01; se = 0.01 / sqrt(3)
    assert model.rates_se[0, 1, 0] == pytest.approx(0.01 / math.sqrt(3), rel=1e-9)
    assert model.rates_se[0, 1, 1] == pytest.approx(np.std([0.025, 0.027], ddof=1) / math.sqrt(2))
    assert model.rates_se[1, 1, 1] == 0.0  # one repeat


def test_model_from_runs_with_a_missing_group_raises() -> None:
    config = two_robot_config()
    runs = [
        (i, g, 0.01) for i in range(2) for g in ((1, 0), (0, 1), (1, 1)) if (i, g) != (1, (0, 1))
    ]
    with pytest.raises(ValueError, match=r"no run of group \(0, 1\) on circuit 1"):
        model_from_runs(config, runs)


def test_measured_rate_counts_deliveries_in_the_measured_window() -> None:
    result = SimpleNamespace(
        measured_window=(100.0, 300.0), delivery_time_s=[50.0, 100.0, 150.0, 299.9, 300.0]
    )
    assert measured_rate(result) == pytest.approx(3 / 200)


def test_group_specs_cover_every_non_empty_group_on_every_circuit() -> None:
    config = two_robot_config()
    specs = group_specs(config, seeds=(0, 1), warmup_s=60.0, measure_s=600.0)
    assert len(specs) == 2 * 3 * 2  # circuits x non-empty groups x seeds
    assert len({s.key for s in specs}) == len(specs)
    both = [s for s in specs if s.key == "c1_g1-1_s1"]
    assert len(both) == 1
    spec = both[0]
    assert spec.allocator == "fixed" and dict(spec.allocator_kwargs) == {"circuit": 1}
    assert [r.speed_class for r in spec.env_kwargs["robots"]] == ["fast", "slow"]
    assert spec.seed == 1 and spec.convergence_s == 60.0 and spec.measured_s == 600.0


def test_estimate_model_on_a_two_robot_arena() -> None:
    """A real (small) estimation: one fast and one slow robot, each group alone on each circuit."""
    model = estimate_model(
        two_robot_config(), seeds=(0,), warmup_s=60.0, measure_s=1200.0, workers=1
    )
    assert model.classes == ("fast", "slow")
    assert model.team == (1, 1)
    assert model.rates.shape == (2, 2, 2)
    assert model.rates_se is not None and np.all(model.rates_se == 0.0)  # one seed
    for i in range(2):
        assert model.rate(i, (0, 0)) == 0.0
        for group in ((1, 0), (0, 1), (1, 1)):
            assert model.rate(i, group) > 0
        # two robots complete more than either alone
        assert model.rate(i, (1, 1)) > max(model.rate(i, (1, 0)), model.rate(i, (0, 1)))
        # a task takes a robot roughly 50-100 s here (travel plus 24 s at the stations)
        assert 1 / 150 < model.rate(i, (0, 1)) < model.rate(i, (1, 0)) < 1 / 40


def test_short_groups_and_bad_static_circuits_are_named() -> None:
    model = synthetic_model()
    with pytest.raises(
        ValueError, match=r"allocation group = \(3,\) is invalid; allowed: one count"
    ):
        model.value_rate(((3,), (3,)))
    bad = np.array(model.rates)
    bad[0, 1, 0] = np.inf
    with pytest.raises(ValueError, match=r"rates = \[inf\] is invalid"):
        CompletionModel(model.classes, model.team, model.values, bad)


def test_the_optimum_by_circuit_equals_the_exhaustive_search() -> None:
    # beyond EXHAUSTIVE_LIMIT allocations the optimum comes from a search circuit by circuit;
    # on every shipped model and under other values, it is worth what the exhaustive one is
    from tavc_agents.model import REFERENCE_MODELS, CompletionModel

    for path in sorted(REFERENCE_MODELS.glob("*.json")):
        model = CompletionModel.load(path)
        if model.n_circuits > 3:
            continue
        for values in (model.values, tuple(1000.0 * (i + 1) for i in range(model.n_circuits))):
            at = model.with_values(values)
            best = at.ranked()[0][0]
            assert at.value_rate(at._optimum_by_circuit(at.team)) == pytest.approx(best, rel=1e-12)
