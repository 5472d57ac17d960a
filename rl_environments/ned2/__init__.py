"""Niryo Ned2 environments: reach, push and pick-and-place, simulated and real
(description: :mod:`rl_environments.robots.ned2_description`)."""
