"""The deep leaderboard's table of every run, from saved results (no training, no TorchRL): runs
in scenario, learner and seed order, the curve's untrained, best and last points normalised, and
a final policy called `stay` only when every robot goes back to the circuit it just served."""

from __future__ import annotations

from typing import Any

import deep_leaderboard as study

REFS = {"dahl2004": {"random": 100.0, "optimum": 200.0}}


def _run(algorithm: str, seed: int) -> study.Run:
    return study.Run(algorithm, "dahl2004", seed, 100, 50, 1, 50, 60.0, (0,))


def _result(curve: list[float], choices: list[list[int]], score: float) -> dict[str, Any]:
    points = [{"decisions": 50 * k, "value_per_h": v} for k, v in enumerate(curve)]
    return {"curve": points, "choices": choices, "eval_values_per_h": [score, score]}


def test_every_run_is_a_row_in_order_with_its_curve_and_its_final_policy() -> None:
    settings = study.Settings(algorithms=("mappo", "ippo"), scenarios=("dahl2004",), seeds=2)
    runs = [_run("ippo", 0), _run("mappo", 1), _run("mappo", 0)]
    results = {
        study.run_key(runs[0]): _result([150.0, 190.0, 120.0], [[1, 1], [0, 1]], 120.0),
        study.run_key(runs[2]): _result([100.0, 180.0, 180.0], [[0, 1], [0, 1]], 180.0),
    }  # mappo seed 1 is not saved yet
    rows = study.runs_table(settings, runs, results, REFS).splitlines()[2:]
    assert rows == [
        "| dahl2004 | mappo | 0 | 0.00 | 0.80 at 50 | 0.80 | 0.800 | stay |",
        "| dahl2004 | ippo | 0 | 0.50 | 0.90 at 50 | 0.20 | 0.200 | moves |",
    ]


def test_no_saved_run_says_so() -> None:
    settings = study.Settings(algorithms=("mappo",), scenarios=("dahl2004",), seeds=1)
    assert study.runs_table(settings, [_run("mappo", 0)], {}, REFS) == "(no run saved yet)"
