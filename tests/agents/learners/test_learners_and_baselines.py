"""The agent layer (DESIGN.md section 3): the TAVC Q-update against hand computations, both
Q-table initialisations, softmax and epsilon-greedy probabilities against their closed forms
(including extreme Q / temperature ratios, masks and ties), empirical choice frequencies within
binomial tolerances, the baselines and the registry.

Frequency tests: n draws of an action with probability p give a Binomial(n, p) count, standard
deviation sigma = sqrt(n p (1 - p)); every count is asserted within 4 sigma of n p (two-sided
false-alarm probability 6e-5 per count). The generators are seeded, so each test is deterministic;
the tolerance only has to be wide enough for the fixed seed and narrow enough to catch a wrong
distribution (for p = 0.1 and n = 20 000, 4 sigma is 170 draws = 0.85 percentage points, while
the usual alternative definition of epsilon-greedy, greedy with 1 - eps + eps / 2, would move the
count by 1000).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from tavc_agents.allocators.baselines import FixedAllocator, RandomAllocator, StayAllocator
from tavc_agents.experiments.registry import allocator_names, make_allocator, make_policy
from tavc_agents.learners.selection import EpsilonGreedy, Softmax, sample
from tavc_agents.learners.tavc import TavcLearner, TavcParams, epsilon_tavc, softmax_tavc
from tavc_agents.policy import Policy, allowed_actions, state_of

ALPHA, GAMMA = 0.1, 0.95
ONES2 = np.ones(2, np.int8)
ONES3 = np.ones(3, np.int8)
N_DRAWS = 20_000


def onehot(i: int, n: int = 2) -> np.ndarray:
    v = np.zeros(n, np.float32)
    v[i] = 1.0
    return v


def zero_learner(selection, n: int = 2, seed: int = 0) -> TavcLearner:
    """A learner whose Q-table starts at exactly zero (paper init with a zero half-width)."""
    learner = TavcLearner(
        selection=selection,
        params=TavcParams(alpha=ALPHA, gamma=GAMMA, init="paper", init_range=0.0),
    )
    learner.reset(np.random.default_rng(seed), n)
    assert np.array_equal(learner.q, np.zeros((n, n)))
    return learner


def assert_binomial(count: int, n: int, p: float, sigmas: float = 4.0) -> None:
    sd = math.sqrt(n * p * (1 - p))
    assert abs(count - n * p) <= sigmas * sd, (
        f"count {count} of {n}, expected {n * p} +- {sigmas} x {sd:.1f}"
    )


def act_counts(learner: TavcLearner, obs: np.ndarray, mask: np.ndarray, n: int) -> np.ndarray:
    counts = np.zeros(len(mask), np.int64)
    for _ in range(n):
        counts[learner.act(obs, mask)] += 1
    return counts


# -- Q update ----------------------------------------------------------------------------------


def test_q_update_matches_hand_computation() -> None:
    learner = zero_learner(Softmax(temperature=0.005))
    learner.q = np.array([[0.2, 0.4], [1.0, -0.3]])

    # s=0, a=1, r=0.5, s'=1: target 0.5 + 0.95 * max(1.0, -0.3) = 1.45; 0.4 + 0.1 * 1.05 = 0.505.
    learner.update(onehot(0), 1, 0.5, onehot(1), {"task_time_s": 50.0})
    np.testing.assert_allclose(learner.q, [[0.2, 0.505], [1.0, -0.3]], rtol=0, atol=1e-15)

    # s=1, a=0, r=0.2, s'=0: target 0.2 + 0.95 * 0.505 = 0.67975; 1.0 + 0.1 * (0.67975 - 1.0).
    learner.update(onehot(1), 0, 0.2, onehot(0), {"task_time_s": 50.0})
    np.testing.assert_allclose(learner.q, [[0.2, 0.505], [0.967975, -0.3]], rtol=0, atol=1e-15)

    # s = s' = 1, a=1, r=0.1: target 0.1 + 0.95 * 0.967975 = 1.01957625;
    # -0.3 + 0.1 * (1.01957625 + 0.3) = -0.168042375.
    learner.update(onehot(1), 1, 0.1, onehot(1), {"task_time_s": 50.0})
    np.testing.assert_allclose(
        learner.q, [[0.2, 0.505], [0.967975, -0.168042375]], rtol=0, atol=1e-15
    )

    # s = s', the updated entry is the row's maximum: the target uses its value before the update.
    # s=0, a=1, r=0.0: target 0.95 * 0.505 = 0.47975; 0.505 + 0.1 * (0.47975 - 0.505) = 0.502475.
    learner.update(onehot(0), 1, 0.0, onehot(0), {"task_time_s": 50.0})
    np.testing.assert_allclose(
        learner.q, [[0.2, 0.502475], [0.967975, -0.168042375]], rtol=0, atol=1e-15
    )
    assert learner.updates.tolist() == [[0, 2], [1, 1]]


def test_q_update_uses_alpha_and_gamma_of_the_params() -> None:
    learner = TavcLearner(
        selection=Softmax(temperature=0.005),
        params=TavcParams(alpha=0.5, gamma=0.5, init="paper", init_range=0.0),
    )
    learner.reset(np.random.default_rng(0), 2)
    learner.q = np.array([[0.0, 0.0], [2.0, 1.0]])
    learner.update(onehot(0), 0, 1.0, onehot(1), {})
    # target 1 + 0.5 * 2 = 2; 0 + 0.5 * 2 = 1.
    assert learner.q[0, 0] == pytest.approx(1.0, abs=1e-15)


def test_updates_count_per_entry_and_choices_count_acts() -> None:
    learner = zero_learner(EpsilonGreedy(epsilon=0.1))
    plan = [(0, 1, 1), (0, 1, 1), (1, 1, 1), (1, 0, 0), (0, 1, 1), (1, 1, 1)]
    for s, a, s_next in plan:
        learner.act(onehot(s), ONES2)
        learner.update(onehot(s), a, 0.04, onehot(s_next), {})
    assert learner.updates.tolist() == [[0, 3], [1, 2]]
    assert learner.updates.dtype.kind == "i"
    assert learner.choices == len(plan)
    # reset starts the counters afresh
    learner.reset(np.random.default_rng(1), 3)
    assert learner.updates.tolist() == [[0] * 3] * 3
    assert learner.choices == learner.non_greedy_choices == 0


def test_q_table_is_a_copy() -> None:
    learner = zero_learner(Softmax(temperature=0.005))
    table = learner.q_table
    table[0, 0] = 99.0
    assert learner.q[0, 0] == 0.0


# -- initialisations ---------------------------------------------------------------------------


@pytest.mark.parametrize("n_actions", [2, 3])
def test_paper_init_draws_uniform_from_the_given_rng(n_actions: int) -> None:
    learner = TavcLearner(selection=Softmax(temperature=0.005), params=TavcParams(init="paper"))
    learner.reset(np.random.default_rng(7), n_actions)
    expected = np.random.default_rng(7).uniform(-0.1, 0.1, size=(n_actions, n_actions))
    assert np.array_equal(learner.q, expected)
    # a different stream gives a different table; the range is the half-width of the params
    other = TavcLearner(
        selection=Softmax(temperature=0.005), params=TavcParams(init="paper", init_range=0.02)
    )
    other.reset(np.random.default_rng(8), n_actions)
    assert not np.array_equal(other.q, learner.q)
    assert np.all(np.abs(other.q) <= 0.02)


def test_paper_init_range_over_many_draws() -> None:
    learner = TavcLearner(selection=Softmax(temperature=0.005), params=TavcParams(init="paper"))
    learner.reset(np.random.default_rng(0), 100)
    assert learner.q.min() >= -0.1 and learner.q.max() < 0.1
    # both halves of the interval are used (not e.g. U(0, 0.1))
    assert learner.q.min() < -0.09 and learner.q.max() > 0.09
    assert abs(learner.q.mean()) < 4 * 0.1 / math.sqrt(3) / 100  # 4 sigma of the mean of 10^4


def test_scaled_init_is_uniform_until_the_first_reward() -> None:
    learner = TavcLearner(selection=Softmax(temperature=0.005), params=TavcParams(init="scaled"))
    learner.reset(np.random.default_rng(3), 2)
    assert np.array_equal(learner.q, np.zeros((2, 2)))
    np.testing.assert_array_equal(learner.selection.probabilities(learner.q[0], ONES2), [0.5, 0.5])
    counts = act_counts(learner, onehot(0), ONES2, 4000)
    assert_binomial(int(counts[0]), 4000, 0.5)
    assert learner.non_greedy_choices == 0  # all entries equal: no choice is non-greedy
    assert learner.choices == 4000


def test_scaled_init_sets_the_scale_at_the_first_update_then_applies_it() -> None:
    optimism, noise, r0 = 0.05, 1e-4, 0.04
    learner = TavcLearner(
        selection=Softmax(temperature=0.005),
        params=TavcParams(alpha=ALPHA, gamma=GAMMA, init="scaled", optimism=optimism, noise=noise),
    )
    rng = np.random.default_rng(11)
    learner.reset(rng, 2)
    a = learner.act(onehot(1), ONES2)
    twin = copy.deepcopy(rng)  # the learner draws its jitter from this very stream next
    learner.update(onehot(1), a, r0, onehot(a), {"task_time_s": 50.0})

    level = r0 / (1 - GAMMA) * (1 + optimism)
    assert level == pytest.approx(0.84)
    expected = level * (1.0 + twin.uniform(-noise, noise, size=(2, 2)))
    expected[1, a] += ALPHA * (r0 + GAMMA * expected[a].max() - expected[1, a])
    np.testing.assert_allclose(learner.q, expected, rtol=1e-14, atol=0)

    untouched = [(s, b) for s in range(2) for b in range(2) if (s, b) != (1, a)]
    for s, b in untouched:
        assert abs(learner.q[s, b] / level - 1) <= noise
    # Optimism: the tried action now looks worse than the untried one in that state, so greedy
    # selection tries the other next (the design's cure for lock-in).
    assert learner.q[1, a] < learner.q[1, 1 - a]
    assert learner.selection.probabilities(learner.q[1], ONES2)[1 - a] > 0.5
    # The second update is a plain Q-update (no re-initialisation).
    before = learner.q.copy()
    learner.update(onehot(a), 0, 0.03, onehot(0), {})
    after = before.copy()
    after[a, 0] += ALPHA * (0.03 + GAMMA * before[0].max() - before[a, 0])
    np.testing.assert_allclose(learner.q, after, rtol=1e-14, atol=0)


def test_scaled_init_is_redone_after_reset() -> None:
    learner = softmax_tavc()
    learner.reset(np.random.default_rng(0), 2)
    learner.update(onehot(0), 0, 0.04, onehot(0), {})
    learner.reset(np.random.default_rng(0), 2)
    assert np.array_equal(learner.q, np.zeros((2, 2)))
    learner.update(onehot(0), 0, 0.02, onehot(0), {})
    assert learner.q[1, 1] == pytest.approx(0.02 / 0.05 * 1.05, rel=1e-4)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("alpha", 0.0),
        ("alpha", 1.5),
        ("alpha", math.nan),
        ("gamma", 1.0),
        ("gamma", -0.1),
        ("init", "zeros"),
        ("init_range", -0.1),
        ("optimism", -0.5),
        ("noise", 0.01),
        ("noise", -1e-5),
    ],
)
def test_bad_params_raise_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=rf"^{field} = .* is invalid; allowed: "):
        TavcParams(**{field: value})


# -- softmax -----------------------------------------------------------------------------------


def closed_form_softmax(q: np.ndarray, t: float) -> np.ndarray:
    e = np.exp(np.asarray(q, float) / t)
    return e / e.sum()


@pytest.mark.parametrize(
    ("q", "t"),
    [
        ([0.3, 0.1, -0.2], 0.2),
        ([0.81, 0.8], 0.005),
        ([0.0, 0.0], 0.005),
        ([1.0, 2.0, 3.0, 4.0], 1.0),
        ([-5.0, 5.0], 3.0),
    ],
)
def test_softmax_matches_closed_form(q: list[float], t: float) -> None:
    p = Softmax(temperature=t).probabilities(np.array(q), np.ones(len(q), np.int8))
    np.testing.assert_allclose(p, closed_form_softmax(np.array(q), t), rtol=1e-12, atol=1e-300)
    assert p.sum() == pytest.approx(1.0, abs=1e-15)


def test_softmax_huge_ratio_does_not_overflow() -> None:
    with np.errstate(all="raise"):  # an overflow or invalid operation is an error here
        p = Softmax(temperature=0.005).probabilities(np.array([1000.0, 999.0]), ONES2)
    assert np.all(np.isfinite(p))
    assert p[0] == 1.0
    assert p[1] == pytest.approx(math.exp(-200.0), rel=1e-9)  # exp((999 - 1000) / 0.005)
    # the same with the greedy action second, and for ratios far beyond float range
    p = Softmax(temperature=1e-6).probabilities(np.array([-3e5, 3e5]), ONES2)
    assert p.tolist() == [0.0, 1.0]


def test_softmax_tiny_ratio_is_nearly_uniform() -> None:
    p = Softmax(temperature=1.0).probabilities(np.array([1e-9, 0.0]), ONES2)
    assert p[0] == pytest.approx(0.5 + 0.25e-9, abs=1e-15)
    assert p[1] == pytest.approx(0.5 - 0.25e-9, abs=1e-15)
    assert p[0] > p[1]


def test_softmax_masked_actions_get_zero() -> None:
    q = np.array([0.3, 50.0, 0.1])  # the masked action would dominate if it were allowed
    p = Softmax(temperature=0.1).probabilities(q, np.array([1, 0, 1], np.int8))
    assert p[1] == 0.0
    np.testing.assert_allclose(p[[0, 2]], closed_form_softmax(q[[0, 2]], 0.1), rtol=1e-12)
    p = Softmax(temperature=0.1).probabilities(q, np.array([0, 0, 1], np.int8))
    assert p.tolist() == [0.0, 0.0, 1.0]


def test_softmax_ties_split_evenly() -> None:
    p = Softmax(temperature=0.005).probabilities(np.array([0.7, 0.7]), ONES2)
    assert p.tolist() == [0.5, 0.5]
    p = Softmax(temperature=1e-6).probabilities(np.array([1.0, 0.0, 1.0]), ONES3)
    np.testing.assert_allclose(p, [0.5, 0.0, 0.5], atol=1e-300)


@pytest.mark.parametrize("temperature", [0, 0.0, -0.005, math.nan, math.inf, -math.inf, "0.1"])
def test_softmax_bad_temperature_raises(temperature: object) -> None:
    with pytest.raises(ValueError, match=r"temperature = .* is invalid"):
        Softmax(temperature=temperature)  # type: ignore[arg-type]


def test_selection_with_no_allowed_action_raises() -> None:
    with pytest.raises(ValueError, match="allows no action"):
        Softmax(temperature=0.1).probabilities(np.array([0.1, 0.2]), np.zeros(2, np.int8))
    with pytest.raises(ValueError, match="allows no action"):
        EpsilonGreedy(epsilon=0.1).probabilities(np.array([0.1, 0.2]), np.zeros(2, np.int8))


# -- epsilon-greedy ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("q", "mask", "eps", "expected"),
    [
        ([0.2, 0.5], [1, 1], 0.1, [0.1, 0.9]),  # two circuits: the other one with probability eps
        ([0.5, 0.2], [1, 1], 0.25, [0.75, 0.25]),
        ([0.1, 0.5, 0.3], [1, 1, 1], 0.1, [0.05, 0.9, 0.05]),  # non-greedy share split evenly
        ([0.5, 0.5, 0.1], [1, 1, 1], 0.1, [0.45, 0.45, 0.1]),  # tied greedy actions
        ([0.3, 0.3], [1, 1], 0.1, [0.5, 0.5]),  # all tied: no non-greedy action
        ([0.3, 0.3, 0.3], [1, 1, 1], 0.4, [1 / 3, 1 / 3, 1 / 3]),
        ([0.9, 0.5, 0.3], [0, 1, 1], 0.1, [0.0, 0.9, 0.1]),  # greedy among the allowed only
        ([0.9, 0.5, 0.3], [0, 0, 1], 0.1, [0.0, 0.0, 1.0]),
        ([0.2, 0.5], [1, 1], 0.0, [0.0, 1.0]),
        ([0.2, 0.5], [1, 1], 1.0, [1.0, 0.0]),
    ],
)
def test_epsilon_greedy_probabilities(
    q: list[float], mask: list[int], eps: float, expected: list[float]
) -> None:
    p = EpsilonGreedy(epsilon=eps).probabilities(np.array(q), np.array(mask, np.int8))
    np.testing.assert_allclose(p, expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize("epsilon", [-0.1, 1.1, math.nan, "0.1"])
def test_epsilon_greedy_bad_epsilon_raises(epsilon: object) -> None:
    with pytest.raises(ValueError, match=r"epsilon = .* is invalid"):
        EpsilonGreedy(epsilon=epsilon)  # type: ignore[arg-type]


def test_epsilon_greedy_act_frequencies_two_actions() -> None:
    learner = zero_learner(EpsilonGreedy(epsilon=0.1), seed=42)
    learner.q[0] = [0.0, 1.0]
    learner.q[1] = [1.0, 0.0]  # state 1 must not be consulted in state 0
    counts = act_counts(learner, onehot(0), ONES2, N_DRAWS)
    assert_binomial(int(counts[0]), N_DRAWS, 0.1)
    # every choice of action 0 was a choice of a non-maximal action, and only those
    assert learner.non_greedy_choices == counts[0]
    assert learner.choices == N_DRAWS


def test_epsilon_greedy_act_frequencies_three_actions_and_mask() -> None:
    learner = zero_learner(EpsilonGreedy(epsilon=0.3), n=3, seed=5)
    learner.q[2] = [0.2, 0.9, 0.1]
    counts = act_counts(learner, onehot(2, 3), ONES3, N_DRAWS)
    for action, p in enumerate([0.15, 0.7, 0.15]):
        assert_binomial(int(counts[action]), N_DRAWS, p)
    assert learner.non_greedy_choices == counts[0] + counts[2]
    # greedy action masked out: action 0 is now greedy among {0, 2}
    counts = act_counts(learner, onehot(2, 3), np.array([1, 0, 1], np.int8), 5000)
    assert counts[1] == 0
    assert_binomial(int(counts[2]), 5000, 0.3)


def test_softmax_act_frequencies() -> None:
    t = 0.1
    learner = zero_learner(Softmax(temperature=t), seed=9)
    learner.q[1] = [t * math.log(7 / 3), 0.0]  # exp ratio 7 : 3
    counts = act_counts(learner, onehot(1), ONES2, N_DRAWS)
    assert_binomial(int(counts[0]), N_DRAWS, 0.7)
    assert learner.non_greedy_choices == counts[1]


def test_non_greedy_choices_counts_non_maximal_choices_only() -> None:
    always_other = zero_learner(EpsilonGreedy(epsilon=1.0))
    always_other.q[0] = [1.0, 0.0]
    assert [always_other.act(onehot(0), ONES2) for _ in range(10)] == [1] * 10
    assert always_other.non_greedy_choices == 10
    # the maximum is taken over the allowed actions: the only allowed action is never non-greedy
    assert always_other.act(onehot(0), np.array([0, 1], np.int8)) == 1
    assert always_other.non_greedy_choices == 10
    assert always_other.choices == 11

    greedy = zero_learner(EpsilonGreedy(epsilon=0.0))
    greedy.q[0] = [1.0, 0.0]
    assert [greedy.act(onehot(0), ONES2) for _ in range(10)] == [0] * 10
    assert greedy.non_greedy_choices == 0

    tied = zero_learner(EpsilonGreedy(epsilon=1.0))
    for _ in range(50):
        tied.act(onehot(0), ONES2)
    assert tied.non_greedy_choices == 0


def test_act_reads_the_row_of_the_observed_state() -> None:
    learner = zero_learner(EpsilonGreedy(epsilon=0.0), n=3)
    learner.q = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    assert [learner.act(onehot(s, 3), ONES3) for s in range(3)] == [0, 2, 1]


# -- sampling ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "probabilities",
    [[0.2, 0.5, 0.0, 0.3], [0.0, 0.25, 0.75], [0.5, 0.0, 0.5], [0.9, 0.1]],
)
def test_sample_frequencies_match_probabilities(probabilities: list[float]) -> None:
    p = np.array(probabilities)
    rng = np.random.default_rng(2024)
    counts = np.bincount([sample(p, rng) for _ in range(N_DRAWS)], minlength=len(p))
    for k, pk in enumerate(p):
        if pk == 0:
            assert counts[k] == 0
        else:
            assert_binomial(int(counts[k]), N_DRAWS, float(pk))


def test_sample_degenerate_and_unnormalised() -> None:
    rng = np.random.default_rng(0)
    assert {sample(np.array([0.0, 1.0, 0.0]), rng) for _ in range(200)} == {1}
    assert {sample(np.array([0.0, 0.0, 1.0]), rng) for _ in range(200)} == {2}
    # weights are normalised by their sum: 2 : 6 behaves like 0.25 : 0.75
    counts = np.bincount([sample(np.array([2.0, 6.0]), rng) for _ in range(N_DRAWS)], minlength=2)
    assert_binomial(int(counts[0]), N_DRAWS, 0.25)


def test_sample_uses_exactly_one_uniform_per_draw() -> None:
    a, b = np.random.default_rng(5), np.random.default_rng(5)
    u = b.random()
    assert sample(np.array([0.3, 0.7]), a) == (0 if u * 1.0 < 0.3 else 1)
    assert a.random() == b.random()  # both streams are at the same position


# -- baselines, protocol, registry -------------------------------------------------------------


def test_random_allocator_is_uniform_over_allowed() -> None:
    policy = RandomAllocator()
    policy.reset(np.random.default_rng(1), 3)
    counts = np.bincount([policy.act(onehot(0, 3), ONES3) for _ in range(N_DRAWS)], minlength=3)
    for c in counts:
        assert_binomial(int(c), N_DRAWS, 1 / 3)
    mask = np.array([0, 1, 1], np.int8)
    picks = {policy.act(onehot(0, 3), mask) for _ in range(200)}
    assert picks == {1, 2}
    assert policy.update(onehot(0, 3), 1, 0.04, onehot(1, 3), {}) is None


def test_random_allocator_follows_its_rng() -> None:
    a, b = RandomAllocator(), RandomAllocator()
    a.reset(np.random.default_rng(3), 2)
    b.reset(np.random.default_rng(3), 2)
    seq_a = [a.act(onehot(0), ONES2) for _ in range(100)]
    assert seq_a == [b.act(onehot(0), ONES2) for _ in range(100)]
    b.reset(np.random.default_rng(4), 2)
    assert seq_a != [b.act(onehot(0), ONES2) for _ in range(100)]


def test_fixed_allocator() -> None:
    policy = FixedAllocator(circuit=1)
    policy.reset(np.random.default_rng(0), 2)
    assert policy.act(onehot(0), ONES2) == 1
    with pytest.raises(ValueError, match="circuit = 2 is invalid"):
        FixedAllocator(circuit=2).reset(np.random.default_rng(0), 2)
    with pytest.raises(ValueError, match="circuit = -1 is invalid"):
        FixedAllocator(circuit=-1)
    with pytest.raises(ValueError, match="masked out"):
        policy.act(onehot(0), np.array([1, 0], np.int8))


def test_stay_allocator_keeps_the_last_circuit() -> None:
    policy = make_policy("stay")
    assert isinstance(policy, StayAllocator)
    policy.reset(np.random.default_rng(0), 3)
    assert [policy.act(onehot(c, 3), np.ones(3, np.int8)) for c in (2, 0, 1)] == [2, 0, 1]
    with pytest.raises(ValueError, match="last circuit 1 is masked out"):
        policy.act(onehot(1, 3), np.array([1, 0, 1], np.int8))


def test_policy_protocol_and_helpers() -> None:
    for policy in (
        softmax_tavc(),
        epsilon_tavc(),
        RandomAllocator(),
        FixedAllocator(circuit=0),
        StayAllocator(),
    ):
        assert isinstance(policy, Policy)
    assert state_of(onehot(1, 3)) == 1
    assert allowed_actions(np.array([0, 1, 1], np.int8)).tolist() == [1, 2]


def test_registry_builds_configured_policies() -> None:
    assert set(allocator_names()) >= {
        "softmax_tavc",
        "epsilon_tavc",
        "random",
        "fixed",
        "stay",
        "static",
        "greedy",
        "auction",
        "response_threshold",
        "network",
    }
    soft = make_policy("softmax_tavc", temperature=0.01, init="paper")
    assert isinstance(soft, TavcLearner)
    assert soft.selection == Softmax(temperature=0.01)
    assert soft.params.init == "paper"
    eps = make_policy("epsilon_tavc", epsilon=0.2)
    assert isinstance(eps, TavcLearner)
    assert eps.selection == EpsilonGreedy(epsilon=0.2)
    assert eps.params == TavcParams()  # the paper's alpha, gamma; scaled init by default
    assert (eps.params.alpha, eps.params.gamma, eps.params.init) == (0.1, 0.95, "scaled")
    assert isinstance(make_policy("random"), RandomAllocator)
    # each call makes a fresh policy (robots must not share a Q-table)
    assert make_policy("softmax_tavc") is not make_policy("softmax_tavc")
    with pytest.raises(ValueError, match=r"'greedy' is not a per-robot policy \(a team"):
        make_policy("greedy")
    with pytest.raises(ValueError, match=r"allocator 'nope' is unknown; allowed: \["):
        make_allocator("nope")


def test_default_constructors_use_the_papers_selection_parameters() -> None:
    assert softmax_tavc().selection == Softmax(temperature=0.005)
    assert epsilon_tavc().selection == EpsilonGreedy(epsilon=0.1)
