"""RX200 reach task envs: RX200ReacherSim-v0 and RX200ReacherGoalSim-v0."""
