"""Baseline allocators: per-robot ones (`baselines`: random, fixed) and team allocators that
coordinate robots through the documented `Team` channel (`teams`: static and greedy on the TAVC
model; `market`: an auction; `threshold`: response thresholds)."""
