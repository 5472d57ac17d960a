"""The RX200 with a Zed2 stereo camera, observing through it: ``RX200Zed2ReacherSim-v0``,
``RX200Zed2ReacherGoalSim-v0``, ``RX200Zed2PushSim-v0``, ``RX200Zed2PushGoalSim-v0``,
``RX200Zed2PnPSim-v0`` and ``RX200Zed2PnPGoalSim-v0``.

The RX200's tasks (its arm file's, :mod:`rl_environments.arm_envs`), unchanged, with the description's
``use_zed2`` option: a Zed2-like stereo pair
in front of the table, 0.6 m from (0.2, 0, 0.05) of the base, looking back at the robot 35 degrees
down, publishing on Stereolabs' ``zed_wrapper`` topics (``/rx200/zed2/zed_node/rgb/image_rect_color``,
``.../depth/depth_registered`` in metres, ``.../rgb/camera_info``, ``.../right/image_rect_color``).
The observation is the state plus the left camera's RGB and depth images at the Zed2's 640 x 360
(``rgb_plus_depth_plus_normal_obs=True``, ``camera_name="zed2_left"``): the very pixels the topics
carry. Every camera keyword changes it (:mod:`rl_environments.camera_obs`): ``rgb_obs_only=True``,
``rgb_plus_normal_obs=True``, ``image_width``/``image_height`` (rendered at that size; the topics stay
at 640 x 360), or ``normal_obs_only=True`` for the state alone with the camera still publishing.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from rl_environments import arm_envs

#: The Zed2 variants' camera keywords (each one can be given otherwise).
ZED2_CAMERA: dict[str, Any] = {"camera_name": "zed2_left", "rgb_plus_depth_plus_normal_obs": True}


class _Zed2:
    XACRO_ARGS: ClassVar[Mapping[str, str]] = {"robot_name": "rx200", "use_zed2": "true"}
    CAMERA_DEFAULTS: ClassVar[Mapping[str, Any]] = ZED2_CAMERA


class RX200Zed2ReacherEnv(_Zed2, arm_envs.RX200ReacherEnv):  # type: ignore[name-defined,misc]
    """``RX200Zed2ReacherSim-v0``: the RX200 reach observed through the Zed2 (arguments:
    :class:`~rl_environments.arm_reach.ArmReachTask` and the camera keywords)."""



class RX200Zed2ReacherGoalEnv(_Zed2, arm_envs.RX200ReacherGoalEnv):  # type: ignore[name-defined,misc]
    """``RX200Zed2ReacherGoalSim-v0``: the goal-conditioned RX200 reach observed through the Zed2
    (arguments: :class:`~rl_environments.arm_reach.ArmGoalReachTask`)."""



class RX200Zed2PushEnv(_Zed2, arm_envs.RX200PushEnv):  # type: ignore[name-defined,misc]
    """``RX200Zed2PushSim-v0``: the RX200 push observed through the Zed2 (arguments:
    :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""



class RX200Zed2PushGoalEnv(_Zed2, arm_envs.RX200PushGoalEnv):  # type: ignore[name-defined,misc]
    """``RX200Zed2PushGoalSim-v0``: the goal-conditioned RX200 push observed through the Zed2
    (arguments: :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""



class RX200Zed2PnPEnv(_Zed2, arm_envs.RX200PnPEnv):  # type: ignore[name-defined,misc]
    """``RX200Zed2PnPSim-v0``: the RX200 pick-and-place observed through the Zed2 (arguments:
    :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""



class RX200Zed2PnPGoalEnv(_Zed2, arm_envs.RX200PnPGoalEnv):  # type: ignore[name-defined,misc]
    """``RX200Zed2PnPGoalSim-v0``: the goal-conditioned RX200 pick-and-place observed through the Zed2
    (arguments: :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

