"""The team allocators' decision rules on hand-built situations: static, greedy (Equation 1 slot
values), the auction (Bertsekas' forward auction against brute force, then the allocator's bids
from hand-fed task times) and response thresholds (stimuli, tendencies, reinforcement, choice
frequencies); each team through the trial runner (determinism, refilling a vacancy after a
breakdown); and the env's priority change (`set_circuit_values`).

Teams are driven directly: `team.policies(agents, config)` with a real configuration, members reset
with seeded generators, the team's view (current circuits, who is broken, values, time, learned
state) set by hand or through `observe` / `update`, then `member.act(observation, mask)`.

Synthetic models: a robot of class j alone completes a task every T_j seconds (fast 60 s, slow
90 s); a group completes sum_j n_j / T_j tasks per second times a crowding factor of its size.
`collapse`: no loss up to three robots, a quarter above (the optimum of the paper's team puts the
three fast robots on circuit 0 and the three slow ones on circuit 1). `gradual`:
1 / (1 + 0.1 (n - 1)).

Frequency tests count n seeded draws of a choice with probability p, a Binomial(n, p) count, and
accept n p +- 5 sqrt(n p (1 - p)).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pytest

import tavc_env
from tavc_agents.allocators.market import AuctionAllocator, auction
from tavc_agents.allocators.teams import (
    GreedyAllocator,
    StaticAllocator,
    TeamAllocator,
    prefer_current,
)
from tavc_agents.allocators.threshold import ResponseThresholdAllocator
from tavc_agents.experiments.runner import Event, TrialResult, run_trial
from tavc_agents.model import Allocation, CompletionModel
from tavc_agents.policy import Policy, Team
from tavc_env import PHASES, completed_task_s

T_FAST, T_SLOW = 60.0, 90.0
VALUES = (2200.0, 2000.0)
ONES2 = np.ones(2, np.int8)
ONES3 = np.ones(3, np.int8)


def collapse(n: int) -> float:
    return 1.0 if n <= 3 else 0.25


def gradual(n: int) -> float:
    return 1.0 / (1.0 + 0.1 * (n - 1))


def crowd_rate(
    group: Sequence[int], crowd: Callable[[int], float], times: Sequence[float] = (T_FAST, T_SLOW)
) -> float:
    n = sum(group)
    return 0.0 if n == 0 else sum(k / t for k, t in zip(group, times)) * crowd(n)


def crowd_model(
    crowd: Callable[[int], float] = collapse,
    values: tuple[float, ...] = VALUES,
    team: tuple[int, ...] = (3, 3),
    classes: tuple[str, ...] = ("fast", "slow"),
    times: Sequence[float] = (T_FAST, T_SLOW),
) -> CompletionModel:
    rates = np.zeros((len(values), *(n + 1 for n in team)))
    for i in range(len(values)):
        for group in itertools.product(*(range(n + 1) for n in team)):
            index = (i, *group)
            rates[index] = crowd_rate(group, crowd, times)
    return CompletionModel(classes, team, values, rates)


def onehot(i: int, n: int = 2) -> np.ndarray:
    v = np.zeros(n, np.float32)
    v[i] = 1.0
    return v


def start(
    team: TeamAllocator, config: tavc_env.ArenaConfig | str = "dahl2004"
) -> tuple[tavc_env.ArenaConfig, list[Policy]]:
    """Make the team's members for `config` (or a preset name), each reset with its own seed."""
    cfg = tavc_env.make_config(config) if isinstance(config, str) else config
    agents = [f"robot_{i}" for i in range(cfg.n_robots)]
    table = team.policies(agents, cfg)
    members = [table[a] for a in agents]
    for i, member in enumerate(members):
        member.reset(np.random.default_rng(100 + i), cfg.n_circuits)
    return cfg, members


def info(
    *,
    circuit: int = 0,
    sim_time_s: float = 0.0,
    broken: bool = False,
    task_time_s: float | None = None,
) -> dict[str, Any]:
    """An info dict as the env reports it (the keys the teams read)."""
    return {
        "action_required": task_time_s is not None,
        "circuit": circuit,
        "phase": PHASES.index("broken" if broken else "deciding"),
        "broken": broken,
        "task_time_s": task_time_s,
        "elapsed_s": 0.0,
        "sim_time_s": sim_time_s,
        "completed_tasks": 0,
    }


def quiet_infos(n: int, now: float, broken: Sequence[int] = ()) -> dict[str, dict[str, Any]]:
    """Infos of `n` robots at `now` with no delivery; the robots in `broken` are broken."""
    return {f"robot_{i}": info(sim_time_s=now, broken=i in broken) for i in range(n)}


def allocation_of(team: TeamAllocator) -> Allocation:
    return tuple(tuple(g) for g in team.groups())


def assert_binomial(count: int, n: int, p: float, sigmas: float = 5.0) -> None:
    sd = math.sqrt(n * p * (1 - p))
    assert abs(count - n * p) <= sigmas * sd + 1e-9, (
        f"count {count} of {n}, expected {n * p:.1f} +- {sigmas} x {sd:.1f}"
    )


# -- static ------------------------------------------------------------------------------------


def test_static_follows_the_models_optimum_by_class() -> None:
    # interleaved classes: fast robots are 1, 3, 4 and slow robots 0, 2, 5
    config = tavc_env.make_config("dahl2004", speeds=[0.2, 0.3, 0.2, 0.3, 0.3, 0.2])
    team = StaticAllocator(model=crowd_model())
    _, members = start(team, config)
    assert [m.act(onehot(0), ONES2) for m in members] == [1, 0, 1, 0, 0, 1]
    # the same frequencies under swapped values: the fast robots take circuit 1
    swapped = StaticAllocator(model=crowd_model().with_values((2000.0, 2200.0)).to_dict())
    _, members = start(swapped, config)
    assert [m.act(onehot(0), ONES2) for m in members] == [0, 1, 0, 1, 1, 0]


def test_static_with_given_circuits_and_no_adaptation() -> None:
    team = StaticAllocator(circuits=[1, 0, 1, 1, 0, 0])
    _, members = start(team)
    assert [m.act(onehot(0), ONES2) for m in members] == [1, 0, 1, 1, 0, 0]
    # a breakdown and a priority change change nothing
    team.observe(quiet_infos(6, 100.0, broken=[1, 4]), (1.0, 5000.0))
    assert team.broken == [False, True, False, False, True, False]
    assert [m.act(onehot(1), ONES2) for m in members] == [1, 0, 1, 1, 0, 0]
    # a mask that forbids the planned circuit is an error, not a silent change
    with pytest.raises(ValueError, match=r"StaticAllocator's choice for robot 0 = 1 is invalid"):
        members[0].act(onehot(0), np.array([1, 0], np.int8))


@pytest.mark.parametrize(
    "kwargs", [{}, {"model": crowd_model(), "circuits": [0, 0, 0, 1, 1, 1]}], ids=["none", "both"]
)
def test_static_needs_exactly_one_of_model_and_circuits(kwargs: dict[str, Any]) -> None:
    with pytest.raises(
        ValueError, match=r"static allocation = .*exactly one of model= or circuits="
    ):
        StaticAllocator(**kwargs)


def test_static_bad_circuits_raise() -> None:
    with pytest.raises(ValueError, match=r"circuits = \[0, -1\] .*one circuit index >= 0"):
        StaticAllocator(circuits=[0, -1])
    with pytest.raises(ValueError, match=r"circuits = \[None\] is invalid; allowed: one circuit"):
        StaticAllocator(circuits=[None])  # type: ignore[list-item]
    with pytest.raises(ValueError, match=r"circuits = \[0, 1\] .*6 circuit indices in \[0, 1\]"):
        start(StaticAllocator(circuits=[0, 1]))
    with pytest.raises(ValueError, match=r"circuits = \[0, 0, 0, 2, 1, 1\] .*in \[0, 1\]"):
        start(StaticAllocator(circuits=[0, 0, 0, 2, 1, 1]))


@pytest.mark.parametrize("preset", ["three_circuits_three_classes", "dahl2004_homogeneous"])
def test_static_and_greedy_reject_a_model_of_another_team(preset: str) -> None:
    for team in (StaticAllocator(model=crowd_model()), GreedyAllocator(crowd_model())):
        with pytest.raises(ValueError, match=r"arena team = .*the model's team \{'fast': 3"):
            start(team, preset)


# -- greedy ------------------------------------------------------------------------------------


def test_greedy_slow_robot_takes_the_less_crowded_slot_a_fast_one_does_not() -> None:
    """Others: fast robots 1, 2 on circuit 0, slow robots 4, 5 on circuit 1; robots 0 (fast) and 3
    (slow) undecided. A newcomer slows its group down by the same factor on either circuit, which
    costs more among fast robots; only a fast robot's own speed outweighs that on circuit 0."""
    model = crowd_model(gradual)
    team = GreedyAllocator(model)
    _, members = start(team)
    team.current = [-1, 0, 0, -1, 1, 1]
    assert team.groups(exclude=0) == [[2, 0], [0, 2]]

    def slot(i: int, group: tuple[int, int], k: int) -> float:
        joined = tuple(n + (j == k) for j, n in enumerate(group))
        return VALUES[i] * (crowd_rate(joined, gradual) - crowd_rate(group, gradual))

    fast = [slot(0, (2, 0), 0), slot(1, (0, 2), 0)]
    slow = [slot(0, (2, 0), 1), slot(1, (0, 2), 1)]
    assert fast[0] > fast[1] > 0 and slow[1] > slow[0] > 0
    np.testing.assert_allclose(team.slot_values(0), fast, rtol=1e-12)
    np.testing.assert_allclose(team.slot_values(3), slow, rtol=1e-12)
    assert members[3].act(onehot(0), ONES2) == 1
    team.current[3] = -1
    assert members[0].act(onehot(1), ONES2) == 0
    assert team.current == [0, 0, 0, -1, 1, 1]
    # the mask wins over the slot values
    team.current[0] = -1
    assert members[0].act(onehot(1), np.array([0, 1], np.int8)) == 1


def test_greedy_does_not_count_broken_robots() -> None:
    team = GreedyAllocator(crowd_model(collapse))
    _, members = start(team)
    team.current = [0, 0, 0, -1, 1, 1]
    # a fourth robot on circuit 0 collapses it: the slow robot 3 serves circuit 1
    assert members[3].act(onehot(0), ONES2) == 1
    # robot 0 breaks down (reported through the infos): circuit 0 has a vacancy worth 2200 / 90
    team.observe(quiet_infos(6, 50.0, broken=[0]), VALUES)
    assert team.broken == [True, False, False, False, False, False]
    assert team.groups(exclude=3) == [[2, 0], [0, 2]]
    np.testing.assert_allclose(team.slot_values(3), [2200 / 90, 2000 / 90], rtol=1e-12)
    assert members[3].act(onehot(1), ONES2) == 0
    # repaired: counted again
    team.observe(quiet_infos(6, 60.0), VALUES)
    assert members[3].act(onehot(0), ONES2) == 1


def test_greedy_follows_a_priority_change_delivered_through_observe() -> None:
    team = GreedyAllocator(crowd_model(collapse))
    _, members = start(team)
    team.current = [-1, 0, 0, 1, 1, 1]
    assert members[0].act(onehot(0), ONES2) == 0  # 2200 / 60 against a collapsing circuit 1
    team.current = [-1, -1, -1, -1, -1, -1]
    assert members[0].act(onehot(0), ONES2) == 0  # empty arena: the more valuable circuit
    team.current[0] = -1
    team.observe(quiet_infos(6, 100.0), (2000.0, 2200.0))
    assert team.values == [2000.0, 2200.0]
    np.testing.assert_allclose(team.slot_values(0), [2000 / 60, 2200 / 60], rtol=1e-12)
    assert members[0].act(onehot(0), ONES2) == 1


def test_greedy_ties_go_to_the_current_circuit_then_the_lowest_index() -> None:
    team = GreedyAllocator(crowd_model(collapse, values=(2000.0, 2000.0)))
    _, members = start(team)
    team.observe(quiet_infos(6, 0.0), (2000.0, 2000.0))
    assert team.slot_values(0)[0] == team.slot_values(0)[1]
    assert members[0].act(onehot(0), ONES2) == 0  # undecided: the lowest index
    team.current[0] = 1
    assert members[0].act(onehot(1), ONES2) == 1  # on circuit 1: it stays
    assert members[0].act(onehot(1), ONES2) == 1


def test_prefer_current() -> None:
    scores = np.array([1.0, 3.0, 3.0])
    allowed = np.array([0, 1, 2])
    assert prefer_current(scores, allowed, current=2) == 2
    assert prefer_current(scores, allowed, current=0) == 1
    assert prefer_current(scores, allowed, current=-1) == 1
    assert prefer_current(scores, np.array([0, 2]), current=-1) == 2
    assert prefer_current(scores, np.array([0]), current=1) == 0
    # a difference below the relative tolerance is a tie; a real one is not
    assert prefer_current(np.array([1.0, 1.0 + 1e-14]), np.array([0, 1]), current=0) == 0
    assert prefer_current(np.array([1.0, 1.0 + 1e-9]), np.array([0, 1]), current=0) == 1


def drive_to_rest(team: GreedyAllocator, members: list[Policy], rounds: int = 30) -> int:
    """Let the robots decide in turn, from nobody placed, until a full round changes nothing;
    return the rounds taken. After the first round, every move must raise the value rate."""
    n_actions = team.n_actions
    mask = np.ones(n_actions, np.int8)
    model = team.model.with_values(team.values)
    for r in range(rounds):
        changed = False
        for i, member in enumerate(members):
            before = team.current[i]
            value = model.value_rate(allocation_of(team))
            after = member.act(onehot(max(before, 0), n_actions), mask)
            if after != before:
                changed = True
                if r > 0:
                    assert model.value_rate(allocation_of(team)) > value
        if not changed:
            return r + 1
    raise AssertionError(f"greedy did not settle in {rounds} rounds")


def assert_no_single_move_improves(model: CompletionModel, allocation: Allocation) -> None:
    value = model.value_rate(allocation)
    for other in model.neighbours(allocation):
        assert model.value_rate(other) <= value + 1e-12 * value, (allocation, other)


def test_greedy_settles_at_the_optimum_of_the_collapse_model() -> None:
    team = GreedyAllocator(crowd_model(collapse))
    _, members = start(team)
    drive_to_rest(team, members)
    assert allocation_of(team) == ((3, 0), (0, 3)) == team.model.optimum()
    assert team.current == [0, 0, 0, 1, 1, 1]


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_greedy_settles_where_no_single_move_improves(seed: int) -> None:
    """Arbitrary (seeded random) frequencies on three circuits and three classes: sequential best
    responses stop at a local optimum of single-robot moves (not necessarily the global one)."""
    rng = np.random.default_rng(seed)
    rates = rng.uniform(0.0, 0.05, size=(3, 4, 4, 4))
    rates[:, 0, 0, 0] = 0.0
    values = (2200.0, 2000.0, 1800.0)
    model = CompletionModel(("fast", "medium", "slow"), (3, 3, 3), values, rates)
    team = GreedyAllocator(model.to_dict())
    _, members = start(team, "three_circuits_three_classes")
    drive_to_rest(team, members)
    allocation = allocation_of(team)
    assert sum(map(sum, allocation)) == 9
    assert_no_single_move_improves(model, allocation)


def test_greedy_settles_at_a_local_optimum_of_the_gradual_model() -> None:
    model = crowd_model(gradual)
    team = GreedyAllocator(model)
    _, members = start(team)
    drive_to_rest(team, members)
    assert_no_single_move_improves(model, allocation_of(team))


# -- auction -----------------------------------------------------------------------------------


def brute_force_best(bids: np.ndarray, places: Sequence[int]) -> float:
    n, m = bids.shape
    best = -math.inf
    for circuits in itertools.product(range(m), repeat=n):
        if all(circuits.count(c) <= k for c, k in enumerate(places)):
            best = max(best, float(sum(bids[r, c] for r, c in enumerate(circuits))))
    return best


def check_auction(bids: np.ndarray, places: Sequence[int], epsilon: float) -> None:
    n = len(bids)
    won = auction(bids, places, epsilon)
    assert len(won) == n
    assert all(0 <= c < len(places) for c in won)
    assert all(won.count(c) <= k for c, k in enumerate(places))
    total = sum(bids[r, c] for r, c in enumerate(won))
    assert total >= brute_force_best(bids, places) - n * epsilon - 1e-12, (bids, won)


@pytest.mark.parametrize(
    "places", [[1, 1, 1], [2, 2], [3, 3], [2, 2, 1], [5, 0, 1], [1, 1, 1, 1], [4], [0, 2, 3]]
)
@pytest.mark.parametrize("epsilon", [1e-3, 1e-7])
def test_auction_fills_every_place_within_n_epsilon_of_the_best(
    places: list[int], epsilon: float
) -> None:
    """As many robots as places (the allocator's case while nobody is broken)."""
    rng = np.random.default_rng(sum(places) * 31 + len(places))
    for _ in range(12):
        check_auction(rng.uniform(0.0, 1.0, size=(sum(places), len(places))), places, epsilon)


@pytest.mark.parametrize(
    ("places", "n"), [([1, 1], 1), ([1, 1, 1], 1), ([1, 1, 1], 2), ([3, 3], 5), ([2, 2, 2], 4)]
)
def test_auction_with_more_places_than_robots_is_within_n_epsilon_of_the_best(
    places: list[int], n: int
) -> None:
    rng = np.random.default_rng(sum(places) * 31 + n)
    for _ in range(12):
        check_auction(rng.uniform(0.0, 1.0, size=(n, len(places))), places, 1e-4)


def test_auction_gives_a_lone_robot_its_best_circuit() -> None:
    assert auction(np.array([[2.2, 2.0]]), [1, 1], 1e-4) == [0]


def test_auction_is_deterministic_and_leaves_its_input_alone() -> None:
    rng = np.random.default_rng(7)
    bids = rng.uniform(0.0, 1.0, size=(5, 3))
    copy = bids.copy()
    first = auction(bids, [2, 2, 2], 1e-4)
    assert all(auction(bids, [2, 2, 2], 1e-4) == first for _ in range(3))
    assert np.array_equal(bids, copy)
    # equal bids: ties toward lower indices, the same every time
    assert auction(np.ones((2, 2)), [1, 1], 1e-3) == auction(np.ones((2, 2)), [1, 1], 1e-3)
    assert auction(np.zeros((0, 2)), [1, 1], 1e-3) == []


def test_auction_needs_a_place_per_robot_and_a_positive_epsilon() -> None:
    with pytest.raises(ValueError, match=r"places = \[1, 1\] .*at least one place per robot \(3\)"):
        auction(np.ones((3, 2)), [1, 1], 1e-3)
    for epsilon in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match=r"epsilon = .*a number > 0"):
            auction(np.ones((2, 2)), [1, 1], epsilon)


def feed(member: Policy, circuit: int, task_time_s: float, n_circuits: int = 2) -> None:
    """One completed task on `circuit` that did not start with a switch."""
    obs = onehot(circuit, n_circuits)
    member.update(obs, circuit, 0.0, obs, {"task_time_s": task_time_s})


def test_auction_allocator_running_mean_of_task_times() -> None:
    team = AuctionAllocator(places=[3, 3], rate=0.2)
    _, members = start(team)
    assert np.isnan(team.times).all()
    # before any task every bid is the circuit's value
    np.testing.assert_allclose(team.bids(), np.tile(VALUES, (6, 1)))
    feed(members[2], 0, 100.0)
    feed(members[2], 0, 50.0)
    assert team.times[2, 0] == pytest.approx(100.0 + 0.2 * (50.0 - 100.0))
    # a task that started with a switch (last circuit 1, served 0) is not counted
    members[2].update(onehot(1), 0, 0.0, onehot(0), {"task_time_s": 10.0})
    assert team.times[2, 0] == pytest.approx(90.0)
    members[3].update(onehot(1), 0, 0.0, onehot(0), {"task_time_s": 10.0})
    assert np.isnan(team.times[3]).all()
    # nor is an update without a task time
    members[2].update(onehot(0), 0, 0.0, onehot(0), {"task_time_s": None})
    assert team.times[2, 0] == pytest.approx(90.0)
    # an untimed circuit is bid at the robot's mean time on the others
    np.testing.assert_allclose(team.bids()[2], [2200 / 90, 2000 / 90])


def test_auction_allocator_gives_the_valuable_places_to_the_faster_robots() -> None:
    """Robots 3-5 (slow by configuration, which the auction does not know) deliver in 40 s, robots
    0-2 in 90 s: the quick ones win circuit 0."""
    team = AuctionAllocator(places=[3, 3], switch_penalty=0.05)
    _, members = start(team)
    for j in range(3):
        feed(members[j], 0, 90.0)
        feed(members[3 + j], 1, 40.0)
    np.testing.assert_allclose(team.bids()[0], [2200 / 90, 2000 / 90])
    np.testing.assert_allclose(team.bids()[4], [2200 / 40, 2000 / 40])
    choices = [m.act(onehot(0), ONES2) for m in members]
    assert choices == [1, 1, 1, 0, 0, 0]
    # bids for leaving the current circuit are lowered by the switch penalty
    np.testing.assert_allclose(team.bids()[0], [0.95 * 2200 / 90, 2000 / 90])
    np.testing.assert_allclose(team.bids()[4], [2200 / 40, 0.95 * 2000 / 40])
    # asked again, everyone stays
    assert [m.act(onehot(c), ONES2) for m, c in zip(members, choices)] == choices


def broken_auction_situation() -> tuple[AuctionAllocator, list[Policy]]:
    """Robots 3-5 deliver in 40 s, robot 0 in 80 s, robots 1-2 in 90 s; 3-5 serve circuit 0."""
    team = AuctionAllocator(places=[3, 3], switch_penalty=0.05)
    _, members = start(team)
    for j, t in enumerate([80.0, 90.0, 90.0, 40.0, 40.0, 40.0]):
        feed(members[j], 0, t)
        feed(members[j], 1, t)
    team.current = [1, 1, 1, 0, 0, 0]
    return team, members


def test_auction_allocator_keeps_robots_out_of_full_places() -> None:
    _, members = broken_auction_situation()
    choices = [m.act(onehot(c), ONES2) for m, c in zip(members, [1, 1, 1, 0, 0, 0])]
    assert choices == [1, 1, 1, 0, 0, 0]


def test_auction_allocator_refills_a_broken_robots_place() -> None:
    team, members = broken_auction_situation()
    team.observe(quiet_infos(6, 500.0, broken=[3]), VALUES)
    # Robot 0 gains most from the vacancy: 0.95 * 2200 / 80 - 2000 / 80 = 1.125 against 1.0 for
    # robots 1, 2 (best total 180.6 against 179.4 when the place stays empty). With 5 bidders for
    # 6 places the auction leaves the valuable place empty instead.
    assert members[0].act(onehot(1), ONES2) == 0
    assert members[1].act(onehot(1), ONES2) == 1
    assert members[2].act(onehot(1), ONES2) == 1
    assert members[4].act(onehot(0), ONES2) == 0
    # circuit 0's places are full again; one place on the less valuable circuit stays empty
    assert team.groups() == [[1, 2], [2, 0]]


def test_auction_allocator_places_from_the_model_and_bad_arguments() -> None:
    team = AuctionAllocator(model=crowd_model())
    start(team)
    assert team.places == [3, 3]
    bad: list[tuple[dict[str, Any], str]] = [
        ({}, r"auction places = .*exactly one of places= or model="),
        ({"places": [3, 3], "model": crowd_model()}, r"exactly one of places= or model="),
        ({"places": [3, -1]}, r"places = \[3, -1\] .*a count >= 0"),
        ({"places": [3, 3], "rate": 0.0}, r"rate = 0\.0 .*a weight in \(0, 1\]"),
        ({"places": [3, 3], "switch_penalty": 1.0}, r"switch_penalty = 1\.0 .*\[0, 1\)"),
    ]
    for kwargs, message in bad:
        with pytest.raises(ValueError, match=message):
            AuctionAllocator(**kwargs)
    for places in ([2, 3], [3, 3, 3]):
        with pytest.raises(ValueError, match=r"places = .*2 counts adding up to at least the 6"):
            start(AuctionAllocator(places=places))
    with pytest.raises(ValueError, match=r"arena team"):
        start(AuctionAllocator(model=crowd_model()), "dahl2004_homogeneous")


# -- response thresholds -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"theta_min": 0.0, "theta_max": 60.0},
            r"theta bounds = \(0\.0, 60\.0\) .*0 < theta_min <= theta_max",
        ),
        (
            {"theta_min": 70.0, "theta_max": 60.0, "theta0": 65.0},
            r"theta bounds = \(70\.0, 60\.0\)",
        ),
        ({"theta0": 61.0, "theta_max": 60.0}, r"theta0 = 61\.0 .*\[1\.0, 60\.0\] s"),
        ({"theta0": float("nan")}, r"theta0 = nan"),
        ({"xi": -0.1}, r"xi = -0\.1 .*a rate >= 0 per second"),
        ({"phi": float("inf")}, r"phi = inf .*a rate >= 0"),
        ({"memory": 0.0}, r"memory = 0\.0 .*a weight in \(0, 1\]"),
        ({"memory": 1.5}, r"memory = 1\.5"),
    ],
)
def test_threshold_bad_parameters_raise(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ResponseThresholdAllocator(**kwargs)


def test_threshold_tendency_formula_by_hand() -> None:
    team = ResponseThresholdAllocator(theta0=30.0)
    start(team)
    team.now = 100.0
    team.last = np.array([40.0, 90.0])
    team.gap = np.array([np.nan, 30.0])
    team.theta[0] = [20.0, 5.0]
    # circuit 0: never a gap, waiting 60 s; circuit 1: max(gap 30, waiting 10), times 2000 / 2200
    s = np.array([60.0, 30.0 * 2000 / 2200])
    np.testing.assert_allclose(team.stimuli(), s, rtol=1e-12)
    expected = s**2 / (s**2 + np.array([20.0, 5.0]) ** 2)
    np.testing.assert_allclose(team.tendencies(0), expected, rtol=1e-12)
    assert team.tendencies(0)[0] == pytest.approx(0.9)
    # robot 1 still has the initial thresholds of 30 s
    np.testing.assert_allclose(team.tendencies(1), s**2 / (s**2 + 900.0), rtol=1e-12)


def delivery_infos(
    n: int, now: float, robot: int, circuit: int, task_time_s: float = 50.0
) -> dict[str, dict[str, Any]]:
    infos = quiet_infos(n, now)
    infos[f"robot_{robot}"] = info(circuit=circuit, sim_time_s=now, task_time_s=task_time_s)
    return infos


def test_threshold_stimuli_grow_without_deliveries_and_scale_with_value() -> None:
    team = ResponseThresholdAllocator(memory=0.5)
    start(team)
    for robot, t in [(0, 100.0), (1, 110.0), (0, 120.0)]:
        team.observe(delivery_infos(6, t, robot, 0), VALUES)
    # gaps on circuit 0: 100, then 100 + 0.5 (10 - 100) = 55, then 55 + 0.5 (10 - 55) = 32.5
    assert team.gap[0] == pytest.approx(32.5)
    assert team.last[0] == 120.0
    assert np.isnan(team.gap[1]) and team.last[1] == 0.0
    team.observe(quiet_infos(6, 130.0), VALUES)
    # circuit 0 was served recently: its usual gap; circuit 1 has waited since the start
    np.testing.assert_allclose(team.stimuli(), [32.5, 130.0 * 2000 / 2200], rtol=1e-12)
    team.observe(quiet_infos(6, 200.0), VALUES)
    np.testing.assert_allclose(team.stimuli(), [80.0, 200.0 * 2000 / 2200], rtol=1e-12)
    # a priority change reweights the stimuli
    team.observe(quiet_infos(6, 200.0), (2000.0, 2200.0))
    np.testing.assert_allclose(team.stimuli(), [80.0 * 2000 / 2200, 200.0], rtol=1e-12)
    # a delivery on circuit 1 resets its waiting time
    team.observe(delivery_infos(6, 210.0, 4, 1), (2000.0, 2200.0))
    assert team.gap[1] == pytest.approx(210.0)
    team.observe(quiet_infos(6, 215.0), (2000.0, 2200.0))
    np.testing.assert_allclose(team.stimuli(), [95.0 * 2000 / 2200, 210.0], rtol=1e-12)


def test_threshold_reinforcement_after_a_task() -> None:
    team = ResponseThresholdAllocator(theta0=30.0, xi=0.02, phi=0.01, theta_min=1.0, theta_max=60.0)
    _, members = start(team, "three_circuits_three_classes")
    members[4].update(onehot(0, 3), 1, 1.0, onehot(1, 3), {"task_time_s": 100.0})
    # served circuit 1: 30 - 0.02 * 100; the others: 30 + 0.01 * 100
    np.testing.assert_allclose(team.theta[4], [31.0, 28.0, 31.0], rtol=1e-12)
    assert np.all(np.delete(team.theta, 4, axis=0) == 30.0)
    # no task time: no change
    members[4].update(onehot(1, 3), 1, 0.0, onehot(1, 3), {"task_time_s": None})
    np.testing.assert_allclose(team.theta[4], [31.0, 28.0, 31.0], rtol=1e-12)
    # long tasks: clipped to [theta_min, theta_max]
    members[4].update(onehot(1, 3), 2, 1.0, onehot(2, 3), {"task_time_s": 5000.0})
    np.testing.assert_allclose(team.theta[4], [60.0, 60.0, 1.0], rtol=1e-12)


def choice_counts(member: Policy, n_circuits: int, mask: np.ndarray, draws: int) -> np.ndarray:
    counts = np.zeros(n_circuits, np.int64)
    for _ in range(draws):
        counts[member.act(onehot(0, n_circuits), mask)] += 1
    return counts


def test_threshold_choice_frequencies_follow_the_normalised_tendencies() -> None:
    team = ResponseThresholdAllocator()
    _, members = start(team, "three_circuits_three_classes")
    team.values = [1.0, 1.0, 1.0]
    team.now = 20.0  # every stimulus is 20 (no delivery yet)
    team.theta[2] = [20.0 / 3.0, 20.0, 60.0]  # tendencies 0.9, 0.5, 0.1
    tendencies = team.tendencies(2)
    np.testing.assert_allclose(tendencies, [0.9, 0.5, 0.1], rtol=1e-12)
    draws = 10_000
    counts = choice_counts(members[2], 3, ONES3, draws)
    for c, p in enumerate(tendencies / tendencies.sum()):
        assert_binomial(int(counts[c]), draws, float(p))
    # a masked circuit is never chosen; the rest renormalise
    counts = choice_counts(members[2], 3, np.array([1, 0, 1], np.int8), draws)
    assert counts[1] == 0
    assert_binomial(int(counts[0]), draws, 0.9)


def test_threshold_without_stimuli_chooses_uniformly() -> None:
    team = ResponseThresholdAllocator()
    _, members = start(team, "three_circuits_three_classes")
    assert np.all(team.stimuli() == 0.0)
    draws = 6_000
    counts = choice_counts(members[0], 3, ONES3, draws)
    for c in range(3):
        assert_binomial(int(counts[c]), draws, 1 / 3)


def test_threshold_draws_come_from_the_members_own_generators() -> None:
    team = ResponseThresholdAllocator()
    _, members = start(team, "three_circuits_three_classes")
    first = [members[0].act(onehot(0, 3), ONES3) for _ in range(50)]
    members[0].reset(np.random.default_rng(100), 3)  # the seed `start` gave robot 0
    assert [members[0].act(onehot(0, 3), ONES3) for _ in range(50)] == first
    assert len(set(first)) == 3


# -- through the trial runner ------------------------------------------------------------------

TEAMS: dict[str, Callable[[], Team]] = {
    "static": lambda: StaticAllocator(model=crowd_model()),
    "greedy": lambda: GreedyAllocator(crowd_model()),
    "auction": lambda: AuctionAllocator(places=[3, 3]),
    "response_threshold": lambda: ResponseThresholdAllocator(),
}
EVENTS = (
    Event(200.0, "break_down", robot=1),
    Event(300.0, "set_values", values=(2000.0, 2200.0)),
    Event(400.0, "repair", robot=1),
)


def trial(team: Team, seed: int = 0, events: Sequence[Event] = EVENTS) -> TrialResult:
    return run_trial(
        team, seed=seed, convergence_s=0.0, measured_s=600.0, events=events, arena="dahl2004"
    )


def record(result: TrialResult) -> tuple[Any, ...]:
    return (
        result.initial_circuits,
        result.changes,
        result.delivery_time_s,
        result.delivery_robot,
        result.delivery_circuit,
        result.delivery_task_time_s,
        result.delivery_value,
        result.events,
        result.end_s,
    )


@pytest.mark.parametrize("name", sorted(TEAMS))
def test_each_team_runs_deterministically(name: str) -> None:
    team = TEAMS[name]()
    first = trial(team)
    assert len(first.delivery_time_s) > 10
    assert [kind for _, kind, _ in first.events] == ["break_down", "set_values", "repair"]
    assert record(trial(TEAMS[name]())) == record(first)
    assert record(trial(team)) == record(first)  # a team object is reusable: policies() resets it
    assert record(trial(team, seed=1)) != record(first)
    # deliveries after the priority change (applied at the first step boundary after 300 s) are
    # paid the new values
    applied = first.events[1][0]
    assert 300.0 <= applied < 330.0
    for t, c, w in zip(first.delivery_time_s, first.delivery_circuit, first.delivery_value):
        assert w == ((2000.0, 2200.0)[c] if t > applied else VALUES[c])


def test_greedy_team_refills_a_vacancy_after_a_breakdown() -> None:
    """Collapse model: greedy settles at 3 fast on circuit 0, 3 slow on circuit 1. When fast robot 0
    breaks down, the slot on circuit 0 (2200 / 90 for a slow robot) beats staying on circuit 1
    (2000 / 90): exactly one slow robot moves; a second would collapse circuit 0."""

    def run(events: Sequence[Event]) -> TrialResult:
        return run_trial(
            GreedyAllocator(crowd_model(collapse)),
            seed=3,
            convergence_s=0.0,
            measured_s=1200.0,
            events=events,
            arena="dahl2004",
        )

    calm = run(())
    assert all(t == 0.0 for t, _, _ in calm.changes)
    final = list(calm.initial_circuits)
    for _, robot, circuit in calm.changes:
        final[robot] = circuit
    assert final == [0, 0, 0, 1, 1, 1]

    broken = run((Event(300.0, "break_down", robot=0),))
    assert broken.changes[: len(calm.changes)] == calm.changes
    later = [(t, robot, circuit) for t, robot, circuit in broken.changes if t > 0.0]
    assert len(later) == 1
    t, robot, circuit = later[0]
    assert t >= 300.0 and robot in (3, 4, 5) and circuit == 0
    assert broken.events[0][1:] == ("break_down", 0)
    # the moved robot then delivers on circuit 0
    assert any(
        r == robot and c == 0 and s > t
        for s, r, c in zip(broken.delivery_time_s, broken.delivery_robot, broken.delivery_circuit)
    )
    # robot 0 delivers nothing after its breakdown
    broke_at = broken.events[0][0]
    assert 300.0 <= broke_at <= t
    assert all(
        s <= broke_at or r != 0 for s, r in zip(broken.delivery_time_s, broken.delivery_robot)
    )


# -- priority changes in the env ---------------------------------------------------------------


def run_until_deliveries(
    env: tavc_env.TavcArenaEnv, infos: dict[str, Any], circuits: set[int]
) -> tuple[list[tuple[float, float, int]], dict[str, Any]]:
    """Step (every deciding robot keeps its circuit) until deliveries on every circuit in
    `circuits` have been seen; return (reward, task time, circuit) of each delivery."""
    seen: list[tuple[float, float, int]] = []
    for _ in range(500):
        actions = {a: i["circuit"] for a, i in infos.items() if i["action_required"]}
        _, rewards, _, _, infos = env.step(actions)
        for agent, i in infos.items():
            if completed_task_s(i) is not None:
                seen.append((rewards[agent], i["task_time_s"], i["circuit"]))
        if circuits <= {c for _, _, c in seen}:
            return seen, infos
    raise AssertionError("no delivery on every circuit within 500 steps")


def test_set_circuit_values_pays_later_deliveries_and_reset_restores() -> None:
    env = tavc_env.parallel_env(preset="dahl2004", reward_time_unit="s")
    _, infos = env.reset(seed=0)
    assert env.circuit_values == VALUES
    before, infos = run_until_deliveries(env, infos, {0, 1})
    for reward, t, c in before:
        assert reward == pytest.approx(VALUES[c] / t, rel=1e-12)
    env.set_circuit_values([1.0, 5.0])
    assert env.circuit_values == (1.0, 5.0)
    after, infos = run_until_deliveries(env, infos, {0, 1})
    for reward, t, c in after:
        assert reward == pytest.approx((1.0, 5.0)[c] / t, rel=1e-12)
    env.set_circuit_values(np.array([3, 4]))  # integers and arrays are fine
    assert env.circuit_values == (3.0, 4.0)
    env.reset(seed=1)
    assert env.circuit_values == VALUES


@pytest.mark.parametrize(
    "values",
    [
        [1.0],
        [1.0, 2.0, 3.0],
        [0.0, 1.0],
        [-1.0, 1.0],
        [float("nan"), 1.0],
        [math.inf, 1.0],
        ["a", 1.0],
        "ab",
        None,
        5.0,
        [True, 1.0],
    ],
)
def test_set_circuit_values_rejects_bad_values(values: Any) -> None:
    env = tavc_env.parallel_env(preset="dahl2004")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"circuit values = .*a sequence of 2 finite values > 0"):
        env.set_circuit_values(values)
    assert env.circuit_values == VALUES


def test_auction_rejects_non_finite_or_misshaped_bids() -> None:
    with pytest.raises(ValueError, match=r"bids = .* allowed: finite numbers"):
        auction(np.array([[1.0, np.inf], [1.0, 1.0]]), [1, 1], 0.01)
    with pytest.raises(
        ValueError, match=r"bids.shape = \(2, 3\) is invalid; allowed: \(robots, 2\)"
    ):
        auction(np.ones((2, 3)), [1, 1], 0.01)
