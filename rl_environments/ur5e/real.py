"""The Universal Robots UR5e's Real twins: ``UR5eReacherReal-v0``, ``UR5eReacherGoalReal-v0``,
``UR5ePushReal-v0``, ``UR5ePushGoalReal-v0``, ``UR5ePnPReal-v0`` and ``UR5ePnPGoalReal-v0``.

Each is its simulated twin's task, unchanged (same spaces, rewards and success), on the real robot
layer (:mod:`rl_environments.ur5e.robot`: the vendor driver's names by default, every name an
option; joint states from the driver, the end effector by forward kinematics, commands through the
safety rules with the UR5e's limits and workspace, one step per control cycle, 10 Hz by default).
Push and pick-and-place read the object's pose from a tracker's ``geometry_msgs/PoseStamped`` topic
and command the gripper through its driver (:mod:`rl_environments.real_arm_robot`). See
``docs/real_robots.md``.
"""

from __future__ import annotations

from rl_environments.arm_manipulation import ArmGoalManipulationTask, ArmManipulationTask
from rl_environments.arm_reach import ArmGoalReachTask, ArmReachTask
from rl_environments.real_arm_robot import TaskJointLimits
from rl_environments.ur5e.robot import UR5eRobotRealEnv, UR5eRobotRealGoalEnv


class UR5eReacherRealEnv(TaskJointLimits, ArmReachTask, UR5eRobotRealEnv):
    """``UR5eReacherReal-v0``: ``UR5eReacherSim-v0``'s reach on a real UR5e (arguments:
    :class:`~rl_environments.arm_reach.ArmReachTask`; robot and loop knobs:
    :class:`~multiros.envs.real.core.RealEnvCore` and
    :meth:`~rl_environments.real_arm_robot.RealArmRobot.real_robot_kwargs`)."""


class UR5eReacherGoalRealEnv(TaskJointLimits, ArmGoalReachTask, UR5eRobotRealGoalEnv):
    """``UR5eReacherGoalReal-v0``: ``UR5eReacherGoalSim-v0``'s goal-conditioned reach on a real UR5e
    (arguments: :class:`~rl_environments.arm_reach.ArmGoalReachTask`)."""


class UR5ePushRealEnv(TaskJointLimits, ArmManipulationTask, UR5eRobotRealEnv):
    """``UR5ePushReal-v0``: ``UR5ePushSim-v0``'s push on a real UR5e, the object's pose from a tracker
    (arguments: :class:`~rl_environments.arm_manipulation.ArmManipulationTask` and
    :meth:`~rl_environments.real_arm_robot.RealArmRobot.real_robot_kwargs`)."""

    TASK = "push"


class UR5ePushGoalRealEnv(TaskJointLimits, ArmGoalManipulationTask, UR5eRobotRealGoalEnv):
    """``UR5ePushGoalReal-v0``: ``UR5ePushGoalSim-v0``'s goal-conditioned push on a real UR5e
    (arguments: :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "push"


class UR5ePnPRealEnv(TaskJointLimits, ArmManipulationTask, UR5eRobotRealEnv):
    """``UR5ePnPReal-v0``: ``UR5ePnPSim-v0``'s pick-and-place on a real UR5e, the object's pose from a
    tracker (arguments: :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "pnp"


class UR5ePnPGoalRealEnv(TaskJointLimits, ArmGoalManipulationTask, UR5eRobotRealGoalEnv):
    """``UR5ePnPGoalReal-v0``: ``UR5ePnPGoalSim-v0``'s goal-conditioned pick-and-place on a real UR5e
    (arguments: :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "pnp"
