"""Environments built from the arena and policies: one robot of a team as a Gymnasium env
(`single_robot`), for single-agent RL libraries."""
