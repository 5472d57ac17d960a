"""IRB120 robot envs (the robot layer)."""
