"""MyRobotEnv: the robot layer of a MultiROS-style environment (template).

The robot layer says which robot to spawn and how to talk to it; a task env (``MyTaskEnv.py``)
inherits it and adds spaces, actions, observations and rewards. Create a copy with your names
filled in with ``uniros new MyArm`` (or copy this file by hand).

Fill in the block between ``# BLANK(robot)`` and ``# END BLANK``. Every base-env knob
(``multiros.envs.sim_env.MujocoEnvCore``) can also be overridden at construction:
``uniros.make("MyTaskEnv-v0", num_sim_steps=10, sim_mode="process")``.

Robot-layer hooks: ``_check_connection_and_readiness()`` (called on each reset before the episode
hooks) and ``_set_episode_init_params()`` (robot-side reset, e.g. the home pose). Termination
belongs to the task layer here: a ``_check_if_done`` defined in this class would hide a task
env's ``_compute_terminated`` (the canonical name wins).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from multiros.envs import EnvError
from multiros.envs.GazeboBaseEnv import GazeboBaseEnv
from multiros.utils.ros_markers import goal_marker


class MyRobotEnv(GazeboBaseEnv):
    """Robot layer of my_robot. Keyword arguments override the base-env knobs set below."""

    def __init__(self, **kwargs: Any) -> None:
        # BLANK(robot) -------------------------------------------------------------------------
        # The robot: its description, controllers and the frames each step should return.
        # Example, the Interbotix RX200 shipped with uniros:
        #   robot_model_xml = "package://rx200_description/urdf/rx200.urdf.xacro"
        #   urdf_xacro_args = {"robot_name": "my_robot"}
        #   controllers_list = ["joint_state_broadcaster", "arm_position_controller"]
        #   self.arm_joints = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]
        #   self.arm_controller = "arm_position_controller"
        #   self.ee_frame = "my_robot/ee_gripper_link"
        #   self.home_position = [0.0, 0.0, 0.0, 0.0, 0.0]
        robot_model_xml = None  # URDF / xacro / MJCF: a path, a package:// URI or the XML text
        urdf_xacro_args: dict[str, str] = {}
        controllers_list: list[str] = []
        self.arm_joints: list[str] = []
        self.arm_controller = ""
        self.ee_frame = ""
        self.home_position: list[float] = []
        # END BLANK ------------------------------------------------------------------------------
        if robot_model_xml is None:
            raise NotImplementedError(f"{type(self).__name__}: fill in the BLANK(robot) block of its robot env")
        knobs: dict[str, Any] = {
            "spawn_robot": True,
            "robot_name": "my_robot",
            "robot_model_xml": robot_model_xml,
            "urdf_xacro_args": urdf_xacro_args,
            "robot_pos_x": 0.0, "robot_pos_y": 0.0, "robot_pos_z": 0.0,
            "robot_ori_w": 1.0, "robot_ori_x": 0.0, "robot_ori_y": 0.0, "robot_ori_z": 0.0,  # identity
            "controllers_list": controllers_list,
            "reset_controllers": False,
            "reset_mode": "world",        # or "simulation" (also rewinds sim time)
            "step_mode": "lockstep",      # or "pause_unpause" / "realtime" with action_cycle_time > 0
            "num_sim_steps": 20,          # physics steps per env step in lockstep mode
            "frames": [self.ee_frame] if self.ee_frame else [],
        }
        knobs.update(kwargs)
        super().__init__(**knobs)

    # -- robot-layer hooks ----------------------------------------------------------------------
    def _check_connection_and_readiness(self) -> bool:
        """Check the robot reports the joints the task will command."""
        missing = [j for j in self.arm_joints if j not in self.joint_names]
        if missing:
            raise EnvError(f"robot {self.robot_name!r} has no joints {missing}; it has {self.joint_names}")
        return True

    def _set_episode_init_params(self) -> None:
        """Robot-side reset: teleport the arm to its home pose (raises ResetError if unreachable)."""
        if self.home_position:
            self.move_to_initial_pose(self.arm_joints, self.home_position)

    # -- helpers for the task layer -------------------------------------------------------------
    def get_joint_positions(self) -> np.ndarray:
        """Arm joint positions after the last step, in ``arm_joints`` order."""
        return self.joint_positions(self.arm_joints)

    def get_ee_position(self) -> np.ndarray:
        """World position of ``ee_frame`` after the last step."""
        return self.frame_position(self.ee_frame)

    def set_joint_targets(self, targets: np.ndarray) -> None:
        """Command the arm controller; the command travels with the next physics step."""
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
