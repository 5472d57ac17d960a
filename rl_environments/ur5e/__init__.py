"""Universal Robots UR5e environments: reach, push and pick-and-place, simulated and real
(description: :mod:`rl_environments.robots.ur5e_description`)."""
