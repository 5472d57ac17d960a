"""RX200 push and pick-and-place task envs: RX200PushSim-v0, RX200PushGoalSim-v0, RX200PnPSim-v0, RX200PnPGoalSim-v0."""
