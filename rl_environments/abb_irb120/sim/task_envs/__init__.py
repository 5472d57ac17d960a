"""IRB120 task envs."""
