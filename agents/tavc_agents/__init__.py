"""Everything that decides and everything that experiments, above the arena (`tavc_env`).

Layers, each importing only from those before it:

- `policy` (the `Policy` and `Team` protocols), `driver` (env outputs to policies) and `model`
  (the TAVC model: task-completion frequencies, slot values, the optimum);
- `learners` (the TAVC Q-learner and its action selection) and `allocators` (random, fixed,
  static, greedy, auction, response threshold);
- `experiments` (one trial, allocators by name, sweeps, the model measured by simulation,
  provenance) and `envs` (one robot as a Gymnasium env);
- `analysis` (statistics, per-trial measures, reports, figures);
- `evaluation` (the suite's protocol: `evaluate(agent, scenario)` scores any agent on it);
- `cli` (the `tavc` command).

The research studies are programs of the source repository (`benchmarks/`), not part of the
package. `tavc_agents.evaluate` is `tavc_agents.evaluation.evaluate`, imported when first used (so
that the `tavc` command starts fast).
"""

from __future__ import annotations

from typing import Any

__all__ = ["evaluate"]


def __getattr__(name: str) -> Any:
    if name == "evaluate":
        from tavc_agents.evaluation import evaluate

        return evaluate
    raise AttributeError(f"module 'tavc_agents' has no attribute {name!r}")
