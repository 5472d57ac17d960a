"""IRB120 real task envs."""
