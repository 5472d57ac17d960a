"""The Niryo Ned2's Real twins: ``NED2ReacherReal-v0``, ``NED2ReacherGoalReal-v0``,
``NED2PushReal-v0``, ``NED2PushGoalReal-v0``, ``NED2PnPReal-v0`` and ``NED2PnPGoalReal-v0``.

Each is its simulated twin's task, unchanged (same spaces, rewards and success), on the real robot
layer (:mod:`rl_environments.ned2.robot`: the vendor driver's names by default, every name an
option; joint states from the driver, the end effector by forward kinematics, commands through the
safety rules with the NED2's limits and workspace, one step per control cycle, 10 Hz by default).
Push and pick-and-place read the object's pose from a tracker's ``geometry_msgs/PoseStamped`` topic
and command the gripper through its driver (:mod:`rl_environments.real_arm_robot`). See
``docs/real_robots.md``.
"""

from __future__ import annotations

from rl_environments.arm_manipulation import ArmGoalManipulationTask, ArmManipulationTask
from rl_environments.arm_reach import ArmGoalReachTask, ArmReachTask
from rl_environments.ned2.robot import NED2RobotRealEnv, NED2RobotRealGoalEnv
from rl_environments.real_arm_robot import TaskJointLimits


class NED2ReacherRealEnv(TaskJointLimits, ArmReachTask, NED2RobotRealEnv):
    """``NED2ReacherReal-v0``: ``NED2ReacherSim-v0``'s reach on a real NED2 (arguments:
    :class:`~rl_environments.arm_reach.ArmReachTask`; robot and loop knobs:
    :class:`~multiros.envs.real.core.RealEnvCore` and
    :meth:`~rl_environments.real_arm_robot.RealArmRobot.real_robot_kwargs`)."""


class NED2ReacherGoalRealEnv(TaskJointLimits, ArmGoalReachTask, NED2RobotRealGoalEnv):
    """``NED2ReacherGoalReal-v0``: ``NED2ReacherGoalSim-v0``'s goal-conditioned reach on a real NED2
    (arguments: :class:`~rl_environments.arm_reach.ArmGoalReachTask`)."""


class NED2PushRealEnv(TaskJointLimits, ArmManipulationTask, NED2RobotRealEnv):
    """``NED2PushReal-v0``: ``NED2PushSim-v0``'s push on a real NED2, the object's pose from a tracker
    (arguments: :class:`~rl_environments.arm_manipulation.ArmManipulationTask` and
    :meth:`~rl_environments.real_arm_robot.RealArmRobot.real_robot_kwargs`)."""

    TASK = "push"


class NED2PushGoalRealEnv(TaskJointLimits, ArmGoalManipulationTask, NED2RobotRealGoalEnv):
    """``NED2PushGoalReal-v0``: ``NED2PushGoalSim-v0``'s goal-conditioned push on a real NED2
    (arguments: :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "push"


class NED2PnPRealEnv(TaskJointLimits, ArmManipulationTask, NED2RobotRealEnv):
    """``NED2PnPReal-v0``: ``NED2PnPSim-v0``'s pick-and-place on a real NED2, the object's pose from a
    tracker (arguments: :class:`~rl_environments.arm_manipulation.ArmManipulationTask`)."""

    TASK = "pnp"


class NED2PnPGoalRealEnv(TaskJointLimits, ArmGoalManipulationTask, NED2RobotRealGoalEnv):
    """``NED2PnPGoalReal-v0``: ``NED2PnPGoalSim-v0``'s goal-conditioned pick-and-place on a real NED2
    (arguments: :class:`~rl_environments.arm_manipulation.ArmGoalManipulationTask`)."""

    TASK = "pnp"
