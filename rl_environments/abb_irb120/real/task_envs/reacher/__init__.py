"""IRB120 reacher task envs on a real robot: ABBIRB120ReacherRealEnv-v0 and ABBIRB120ReacherGoalRealEnv-v0."""
