"""IRB120 real robot envs (the robot layer)."""
