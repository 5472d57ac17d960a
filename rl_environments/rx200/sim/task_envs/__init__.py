"""RX200 task envs."""
