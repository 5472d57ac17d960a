"""IRB120 reacher task envs: ABBIRB120ReacherEnv-v0 and ABBIRB120ReacherGoalEnv-v0."""
