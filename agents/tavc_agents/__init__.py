"""Everything that decides and everything that experiments, above the arena (`tavc_env`).

Layers, each importing only from those before it:

- `policy` (the `Policy` and `Team` protocols), `driver` (env outputs to policies) and `model`
  (the TAVC model: task-completion frequencies, slot values, the optimum);
- `learners` (the TAVC Q-learner and its action selection) and `allocators` (random, fixed,
  static, greedy, auction, response threshold);
- `experiments` (one trial, allocators by name, sweeps, the model measured by simulation,
  provenance) and `envs` (one robot as a Gymnasium env);
- `analysis` (statistics, per-trial measures, reports, figures);
- `studies` (one module per question the benchmarks answer);
- `cli` (the `tavc` command).
"""
