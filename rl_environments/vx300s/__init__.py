"""Interbotix ViperX 300 6DOF environments: reach, push and pick-and-place, simulated and real
(description: :mod:`rl_environments.robots.vx300s_description`)."""
