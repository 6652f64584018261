"""A market allocator: robots bid their own estimated value rates for the circuits' places.

Follows the auction-based MRTA of MURDOCH (Gerkey & Mataric, IEEE T-RA 2002: robots bid a fitness
for an announced task, the best bid wins) and TraderBots (Dias, CMU 2004: robots re-trade tasks
whenever a trade raises the team's profit). Here the goods are places on the circuits and a robot's
bid for circuit i is its own estimate of the value it would earn there per second, `w_i / t_i`,
from its own task times (no knowledge of its speed). The places are re-auctioned among all working
robots whenever a robot must decide; the deciding robot takes the circuit it won, the others move
when they next decide. The auction is Bertsekas' (1988) forward auction with epsilon scaling, which
ends in an assignment within n * epsilon of the one maximising the sum of bids.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tavc_agents.allocators.teams import TeamAllocator
from tavc_agents.model import CompletionModel, as_model
from tavc_env.env import completed_task_s
from tavc_env.validation import is_integer, is_number, require


def auction(bids: np.ndarray, places: Sequence[int], epsilon: float) -> list[int]:
    """Bertsekas' forward auction: robot r (row of `bids`, one column per circuit) is assigned one
    of the places, `places[c]` identical places on circuit c, so that the sum of the winners' bids
    is within `len(bids) * epsilon` of the best. Returns each robot's circuit.

    Epsilon scaling (start at the bid spread, divide by 8 down to `epsilon`), keeping prices
    between rounds, bounds the number of bidding rounds. Ties are broken toward lower indices, so
    the result is deterministic.
    """
    bids = np.asarray(bids, dtype=float)
    require(
        bids.ndim == 2 and bids.shape[1] == len(places),
        "bids.shape",
        bids.shape,
        f"(robots, {len(places)}): one bid per robot and circuit",
    )
    require(bool(np.all(np.isfinite(bids))), "bids", bids.tolist(), "finite numbers")
    n_robots = bids.shape[0]
    owner_circuit = [c for c, k in enumerate(places) for _ in range(k)]
    require(
        len(owner_circuit) >= n_robots,
        "places",
        list(places),
        f"at least one place per robot ({n_robots})",
    )
    require(is_number(epsilon) and epsilon > 0, "epsilon", epsilon, "a number > 0")
    if n_robots == 0:
        return []
    # Places nobody fills keep the prices raised in earlier rounds and would repel bidders, so
    # every place gets a bidder: dummies bidding nothing take the ones left over.
    value = np.zeros((len(owner_circuit), len(owner_circuit)))
    value[:n_robots] = bids[:, owner_circuit]  # bidders x places
    price = np.zeros(len(owner_circuit))
    step = max(float(np.ptp(value)), epsilon)
    while True:
        step = max(step / 8.0, epsilon)
        assigned = [-1] * len(owner_circuit)
        owner = [-1] * len(owner_circuit)
        queue = list(range(len(owner_circuit)))
        while queue:
            r = queue.pop(0)
            net = value[r] - price
            best = int(np.argmax(net))
            second = float(np.max(np.delete(net, best))) if net.size > 1 else float(net[best])
            price[best] += net[best] - second + step
            if owner[best] >= 0:
                assigned[owner[best]] = -1
                queue.append(owner[best])
            owner[best] = r
            assigned[r] = best
        if step <= epsilon:
            return [owner_circuit[p] for p in assigned[:n_robots]]


class AuctionAllocator(TeamAllocator):
    """Market allocation: places on each circuit go to the robots bidding most for them.

    Decision rule: when robot r must decide, every working robot bids `b_{j,i} = w_i / t_{j,i}` for
    each circuit i, where `t_{j,i}` is robot j's running mean (exponential, weight `rate`) of its
    own task times on circuit i, counting only tasks that did not start with a switch; a circuit a
    robot has not yet timed is bid at its mean time on the others (before any task, all times are
    equal, so bids rank circuits by value alone). A bid for a circuit other than the robot's
    current one is lowered by `switch_penalty` (relative) for the travel a switch costs. The places
    (`places[i]` on circuit i, by default the group sizes of the TAVC model's optimum) are
    auctioned; robot r serves the circuit it wins.

    Knows: its own task times, the circuits' current values, how many places each circuit has (the
    task specification, as an operator posts tasks to MURDOCH) and who is working. Not speeds.
    When robots break down there are more places than bidders, and the least valuable stay empty.
    """

    def __init__(
        self,
        places: Sequence[int] | None = None,
        model: CompletionModel | Mapping[str, Any] | None = None,
        rate: float = 0.2,
        switch_penalty: float = 0.05,
    ) -> None:
        super().__init__()
        require(
            (places is None) != (model is None),
            "auction places",
            {"places": places, "model": model is not None},
            "exactly one of places= or model=",
        )
        if places is not None:
            require(
                all(is_integer(k) and k >= 0 for k in places),
                "places",
                places,
                "a count >= 0 of places per circuit",
            )
        require(is_number(rate) and 0 < rate <= 1, "rate", rate, "a weight in (0, 1]")
        require(
            is_number(switch_penalty) and 0 <= switch_penalty < 1,
            "switch_penalty",
            switch_penalty,
            "a relative penalty in [0, 1)",
        )
        self.places = None if places is None else [int(k) for k in places]
        self.model = None if model is None else as_model(model)
        self.rate = float(rate)
        self.switch_penalty = float(switch_penalty)
        self.times = np.zeros((0, 0))

    def setup(self) -> None:
        n, m = len(self.agents), self.n_actions
        if self.model is not None:
            self.model.check_team(self.classes)
            self.places = [sum(g) for g in self.model.optimum()]
        assert self.places is not None
        require(
            len(self.places) == m and sum(self.places) >= n,
            "places",
            self.places,
            f"{m} counts adding up to at least the {n} robots",
        )
        self.times = np.full((n, m), np.nan)  # running mean task time per robot and circuit

    def learn(
        self, robot: int, previous: int, action: int, reward: float, info: Mapping[str, Any]
    ) -> None:
        t = completed_task_s(info)
        if t is None or previous != action:
            return
        old = self.times[robot, action]
        self.times[robot, action] = t if np.isnan(old) else old + self.rate * (t - old)

    def bids(self) -> np.ndarray:
        """Every robot's bid for every circuit (value per second)."""
        times = self.times.copy()
        for j in range(times.shape[0]):
            row = times[j]
            known = row[~np.isnan(row)]
            row[np.isnan(row)] = known.mean() if known.size else 1.0
        bids = np.asarray(self.values) / times
        for j, c in enumerate(self.current):
            if c >= 0:
                bids[j] *= 1.0 - self.switch_penalty
                bids[j, c] /= 1.0 - self.switch_penalty
        return bids

    def choose(self, robot: int, allowed: np.ndarray) -> int:
        assert self.places is not None
        working = [j for j in range(len(self.agents)) if not self.broken[j]]
        if robot not in working:  # asked while flagged broken: it is back
            working.append(robot)
            working.sort()
        bids = self.bids()[working]
        scale = float(np.abs(bids).max())
        won = auction(bids, self.places, epsilon=1e-4 * scale)
        return won[working.index(robot)]
