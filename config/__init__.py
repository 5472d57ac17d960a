"""Task configuration files (YAML) of the library's environments, installed as ``rl_environments.config``."""
