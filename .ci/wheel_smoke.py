"""Smoke tests of an installed wheel, run by .ci/run from a folder outside the source tree: the
package imports from the wheel (not the checkout), its env passes PettingZoo's checker, a trial
runs, and the experiments ship inside the package (`tavc reproduce --quick` is run by .ci/run)."""

from __future__ import annotations

import copy
import sys
from pathlib import Path

from pettingzoo.test import parallel_api_test

import tavc_agents
import tavc_env
from tavc_agents.experiments.runner import run_trial
from tavc_agents.learners.tavc import softmax_tavc
from tavc_agents.studies import STUDIES, load

source = Path(__file__).resolve().parents[1]
for module in (tavc_env, tavc_agents):
    where = Path(module.__file__ or "").resolve()
    if source in where.parents:
        sys.exit(f"{module.__name__} was imported from the source tree ({where}), not the wheel")

env = tavc_env.parallel_env(max_sim_time_s=1800.0)
parallel_api_test(env, num_cycles=50)
env.reset(seed=1)
env.step(dict.fromkeys(env.agents, 0))
assert copy.deepcopy(env).sim_time_s == env.sim_time_s

result = run_trial(lambda agent: softmax_tavc(), seed=0, convergence_s=1800.0, measured_s=600.0)
assert result.delivery_time_s, "no delivery in a 40-minute trial"
for name in STUDIES:
    load(name)  # every study imports from the installed package
print(f"wheel smoke: tavc_env {tavc_env.__version__} from {Path(tavc_env.__file__).parent}: ok")
