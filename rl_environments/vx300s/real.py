"""The ViperX 300 6DOF's Real twins: ``VX300SReacherReal-v0``, ``VX300SReacherGoalReal-v0``,
``VX300SPushReal-v0``, ``VX300SPushGoalReal-v0``, ``VX300SPnPReal-v0`` and ``VX300SPnPGoalReal-v0``.

Each is its simulated twin's task, unchanged (same spaces, rewards and success), on the real robot
layer (:mod:`rl_environments.vx300s.robot`: the vendor driver's names by default, every name an
option; joint states from the driver, the end effector by forward kinematics, commands through the
safety rules with the VX300S's limits and workspace, one step per control cycle, 10 Hz by default).
Push and pick-and-place read the object's pose from a tracker's ``geometry_msgs/PoseStamped`` topic
and command the gripper through its driver (:mod:`rl_environments.real_arm_robot`). See
``docs/real_robots.md``.
"""

from __future__ import annotations

from rl_environments.arm_manipulation import ArmGoalManipulationTask, ArmManipulationTask
from rl_environments.arm_reach import ArmGoalReachTask, ArmReachTask
from rl_environments.real_arm_robot import TaskJointLimits
from rl_environments.vx300s.robot import VX300SRobotRealEnv, VX300SRobotRealGoalEnv


class VX300SReacherRealEnv(TaskJointLimits, ArmReachTask, VX300SRobotRealEnv):
    """``VX300SReacherReal-v0``: ``VX300SReacherSim-v0``'s reach on a real VX300S (arguments:
    :class:`~rl_environments.arm_reach.ArmReachTask`; robot and loop knobs:
    :class:`~multiros.envs.real.core.RealEnvCore` and
    :meth:`~rl_environments.real_arm_robot.RealArmRobot.real_robot_kwargs`)."""


class VX300SReacherGoalRealEnv(TaskJointLimits, ArmGoalReachTask, VX300SRobotRealGoalEnv):
    """``VX300SReacherGoalReal-v0``: ``VX300SReacherGoalSim-v0``'s goal-conditioned reach on a real VX300S
    (arguments: :class:`~rl_environments.arm_reach.ArmGoalReachTask`)."""


class VX300SPushRealEnv(TaskJointLimits, ArmManipulationTask, VX300SRobotRealEnv):
    """``VX300SPushReal-v0``: ``VX300SPushSim-v0``'s push on a real VX300S, the object's pose from a tracker
    (arguments: :class:`~rl_environments.arm_manipulation.ArmManipulationTask` and
    :meth:`~rl_environments.real_arm_robot.RealArmRobot.real_robot_kwargs`)."""

    TASK = "push"


class VX300SPushGoalRealEnv(TaskJointLimits, ArmGoalManipulationTask, VX300SRobotRealGoalEnv):
    """``VX300SPushGoalReal-v0``: ``VX300SPushGoalSim-v0``'s goal-conditioned push on a real VX300S
    (arguments: :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "push"


class VX300SPnPRealEnv(TaskJointLimits, ArmManipulationTask, VX300SRobotRealEnv):
    """``VX300SPnPReal-v0``: ``VX300SPnPSim-v0``'s pick-and-place on a real VX300S, the object's pose from a
    tracker (arguments: :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "pnp"


class VX300SPnPGoalRealEnv(TaskJointLimits, ArmGoalManipulationTask, VX300SRobotRealGoalEnv):
    """``VX300SPnPGoalReal-v0``: ``VX300SPnPGoalSim-v0``'s goal-conditioned pick-and-place on a real VX300S
    (arguments: :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "pnp"
