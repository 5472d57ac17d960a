"""CustomRobotEnv: the robot layer of a FRobs_RL-style environment (template).

FRobs_RL's ``RobotBasicEnv`` becomes ``MujocoBaseEnv``; its knob names (``pkg_name``,
``urdf_file``, ``controller_list``, ``model_pos_x`` ...) and hook names (``_send_action``,
``_get_observation``, ``_check_if_done``, ``_check_subs_and_pubs_connection``,
``_set_episode_init_params``) work unchanged. There is no Gazebo or ROS master to launch: the
simulation node is composed into the env's process (``sim_mode="process"`` runs it in a child).

Fill in the block between ``# BLANK(robot)`` and ``# END BLANK``; the task env
(``CustomTaskEnv.py``) inherits this class.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from multiros.envs import MujocoBaseEnv
from multiros.utils.ros_markers import goal_marker


class CustomRobotEnv(MujocoBaseEnv):
    """Robot layer. Keyword arguments override the knobs set below."""

    def __init__(self, **kwargs: Any) -> None:
        # BLANK(robot) -------------------------------------------------------------------------
        # Example, the Interbotix RX200 shipped with uniros:
        #   pkg_name = "rx200_description"
        #   urdf_file = "rx200.urdf.xacro"
        #   urdf_xacro_args = ["robot_name:=my_robot"]
        #   controller_list = ["joint_state_broadcaster", "arm_position_controller"]
        #   self.joint_names_arm = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]
        #   self.arm_controller = "arm_position_controller"
        #   self.ee_frame = "my_robot/ee_gripper_link"
        pkg_name = None  # the ROS package holding urdf/<urdf_file>
        urdf_file = None
        urdf_xacro_args: list[str] = []
        controller_list: list[str] = []
        self.joint_names_arm: list[str] = []
        self.arm_controller = ""
        self.ee_frame = ""
        # END BLANK ------------------------------------------------------------------------------
        if pkg_name is None or urdf_file is None:
            raise NotImplementedError(f"{type(self).__name__}: fill in the BLANK(robot) block of its robot env")
        knobs: dict[str, Any] = {
            "spawn_robot": True,
            "model_name_in_gazebo": "my_robot",
            "pkg_name": pkg_name,
            "urdf_file": urdf_file,
            "urdf_xacro_args": urdf_xacro_args,
            "controller_list": controller_list,
            "model_pos_x": 0.0, "model_pos_y": 0.0, "model_pos_z": 0.0,  # orientation: identity
            "reset_controllers": False,
            "reset_mode": 1,           # 1 = reset world (keep time), 2 = reset simulation
            "step_mode": 2,            # 2 = N physics steps per env step (lockstep), the fast default
            "num_gazebo_steps": 20,
            "frames": [self.ee_frame] if self.ee_frame else [],
        }
        knobs.update(kwargs)
        super().__init__(**knobs)

    def _check_subs_and_pubs_connection(self) -> bool:
        """Check the robot reports the joints the task commands (FRobs_RL: topics connected)."""
        missing = [j for j in self.joint_names_arm if j not in self.joint_names]
        if missing:
            raise RuntimeError(f"robot {self.robot_name!r} has no joints {missing}; it has {self.joint_names}")
        return True

    # -- helpers for the task env ---------------------------------------------------------------
    def get_joint_angles(self) -> np.ndarray:
        return self.joint_positions(self.joint_names_arm)

    def get_ee_pos(self) -> np.ndarray:
        return self.frame_position(self.ee_frame)

    def set_joint_targets(self, targets: np.ndarray) -> None:
        self.send_command(self.arm_controller, targets)

    def show_goal(self, position: Any, diameter: float = 0.04) -> None:
        """Draw the goal as a green sphere (rendered images and videos, the viewer, RViz).

        Publishes a ``visualization_msgs/Marker`` that the simulation node draws; call it once per
        episode from a reset hook, never from the reward (HER calls that on batches).
        """
        marker = getattr(self, "_goal_marker", None)
        if marker is None:
            self._goal_marker = goal_marker(self.node, np.asarray(position, dtype=float), diameter=diameter)
        else:
            marker.update(position=np.asarray(position, dtype=float))
