"""Test-session set-up: pick MuJoCo's headless GL backend before anything imports mujoco."""

import multiros  # noqa: F401  (sets MUJOCO_GL=egl when there is no display and none was chosen)
