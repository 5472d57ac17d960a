"""RX200 real robot envs (the robot layer)."""
