"""RX200 robot envs (the robot layer)."""
