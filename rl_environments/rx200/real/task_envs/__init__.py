"""RX200 real task envs."""
