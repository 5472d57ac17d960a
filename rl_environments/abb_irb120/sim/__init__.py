"""IRB120 environments on the MuJoCo simulation node."""
