"""Environments built from the arena and policies: one robot of a team as a Gymnasium env
(`single_robot`), for single-agent RL libraries. Its Gymnasium ids
(`tavc_env.registration.SINGLE_ROBOT_IDS`, e.g. `tavc/dahl2004-v0`, for `gymnasium.make` and
`gymnasium.make_vec`) are registered by `import tavc_env`, which importing this package does."""

import tavc_env  # noqa: F401  (registers the single-robot view's Gymnasium ids)
