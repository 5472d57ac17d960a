"""ABB IRB120 environments."""
