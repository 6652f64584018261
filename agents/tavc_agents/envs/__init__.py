"""Environments built from the arena and policies: one robot of a team as a Gymnasium env
(`single_robot`), for single-agent RL libraries. Its Gymnasium ids (`registration.SINGLE_ROBOT_IDS`,
e.g. `tavc/dahl2004-v0`, for `gymnasium.make` and `gymnasium.make_vec`) are registered by
`import tavc_env`; importing this package registers them again, which does nothing."""

from tavc_agents.envs.registration import SINGLE_ROBOT_IDS, register_single_robot_envs

register_single_robot_envs(SINGLE_ROBOT_IDS)
