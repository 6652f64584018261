"""A 2-hour random-choice run of `dahl2004` through the PettingZoo env, to profile.

    pip install pyinstrument
    pyinstrument -i 0.0002 benchmarks/profile_env.py

What the profiles taught (before / after issue 5, in `results/profile/`): the physics step was a
small part of a tick; reading each body's position and setting each body's velocity through
pymunk's Python attributes cost more than the step itself, followed by the controller call's
argument conversions. Batched I/O over numpy buffers and one fused post-step check removed most
of that. The one-off cost left is numba's start-up (about 1 s per process, cached code included).
"""

import numpy as np

import tavc_env

env = tavc_env.parallel_env(preset="dahl2004", max_sim_time_s=7200, max_cycles=10**9)
obs, infos = env.reset(seed=0)
rng = np.random.default_rng(0)
while env.agents:
    actions = {a: int(rng.integers(2)) for a in env.agents if infos[a]["action_required"]}
    obs, rewards, terminations, truncations, infos = env.step(actions)
