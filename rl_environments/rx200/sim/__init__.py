"""RX200 environments on the MuJoCo simulation node."""
