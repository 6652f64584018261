"""Own or team credit: does training each robot on its own deliveries pull the deep learners to
`stay`? The deep leaderboard (`tavc_agents.studies.deep_leaderboard`) trains every robot on its
own deliveries; outside `passing` 23 of its 30 runs end on exactly the `stay` policy, and in
`bad_start` 9 of 10 do, below random allocation. Independent learners that each maximise their own
return play a game whose equilibria need not maximise the team's (docs/semi_mdp.md section 4).

This study is the deep leaderboard with one change: every robot is trained on the team's reward
(the mean over robots of each step's reward, `Settings.credit = "team"`), MAPPO on `bad_start`,
seeds 0-4, the same budget, batches, evaluation and report. Its prediction was committed before
its first run (docs/results/scenarios.md, "Own or team credit"). The script is
`benchmarks/deep_credit.py`; it needs the `marl` extra.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from tavc_agents.studies import deep_leaderboard

run = deep_leaderboard.run


@dataclass(frozen=True, kw_only=True)
class Settings(deep_leaderboard.Settings):
    """The deep leaderboard's settings, trained on the team's reward, MAPPO on `bad_start`."""

    reference: ClassVar = "deep_credit"

    algorithms: tuple[str, ...] = ("mappo",)
    """the learners: mappo (centralised critic), ippo (decentralised critic); both share one actor"""
    scenarios: tuple[str, ...] = ("bad_start",)
    """the scenarios (names in tavc_env.scenarios.SCENARIOS)"""
    credit: str = "team"
    """own: each robot is trained on its own deliveries; team: on the team's (the mean reward of
    the step, every robot alike)"""
