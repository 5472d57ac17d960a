"""Task configuration files (installed as ``rl_environments.config``)."""
