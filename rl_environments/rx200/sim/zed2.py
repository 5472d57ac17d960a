"""The RX200 observed through its Zed2 stereo camera: an arm file now (``config/arms/rx200_zed2.yaml``,
which extends the RX200's with the description's ``use_zed2`` option and the camera it observes
through), whose IDs are ``RX200Zed2<task>Sim-v0`` and their Real twins.

The names below are the classes' earlier home, kept so that saved runs and code that import them
keep working: each is the arm file's class (:mod:`rl_environments.arm_envs`).
"""

from __future__ import annotations

from typing import Any

from rl_environments import arm_envs

__all__ = ["RX200Zed2PnPEnv", "RX200Zed2PnPGoalEnv", "RX200Zed2PushEnv", "RX200Zed2PushGoalEnv",
           "RX200Zed2ReacherEnv", "RX200Zed2ReacherGoalEnv", "ZED2_CAMERA"]

#: The Zed2 variants' camera keywords (the arm file's ``camera.defaults``; each one can be given otherwise).
ZED2_CAMERA: dict[str, Any] = {"camera_name": "zed2_left", "rgb_plus_depth_plus_normal_obs": True}

RX200Zed2ReacherEnv = arm_envs.RX200Zed2ReacherEnv  # type: ignore[attr-defined]
RX200Zed2ReacherGoalEnv = arm_envs.RX200Zed2ReacherGoalEnv  # type: ignore[attr-defined]
RX200Zed2PushEnv = arm_envs.RX200Zed2PushEnv  # type: ignore[attr-defined]
RX200Zed2PushGoalEnv = arm_envs.RX200Zed2PushGoalEnv  # type: ignore[attr-defined]
RX200Zed2PnPEnv = arm_envs.RX200Zed2PnPEnv  # type: ignore[attr-defined]
RX200Zed2PnPGoalEnv = arm_envs.RX200Zed2PnPGoalEnv  # type: ignore[attr-defined]
