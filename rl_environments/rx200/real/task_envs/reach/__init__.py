"""RX200 reach task envs on a real robot: RX200ReacherReal-v0 and RX200ReacherGoalReal-v0."""
