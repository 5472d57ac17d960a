"""An arm's constructor arguments on a real robot: what :class:`~rl_environments.arm_robot.ArmRobot` hands
a :class:`~multiros.envs.RealBaseEnv`, where the simulated twin's are :meth:`ArmRobot.robot_kwargs
<rl_environments.arm_robot.ArmRobot.robot_kwargs>`. The robot layer itself is the same class on both
sides; what a robot does its own way is its connection's (:class:`~multiros.envs.real.connection.RealConnection`).

The end-effector position is forward kinematics of ``joint_states`` through the description package's
URDF (a real robot offers no end-effector service); arm targets go through the env's
:class:`~multiros.envs.real.safety.SafetyRules` to the JointTrajectoryController.

Push and pick-and-place on a real robot (the scene a simulation spawns is on the table already;
:mod:`multiros.envs.real.scene`):

* the object's pose comes from a tracker (a motion-capture system, a fiducial or a vision node
  of yours) as ``geometry_msgs/PoseStamped`` on ``object_pose_topic`` (default ``/object_pose``), in
  the robot's base frame (``object_pose_frame``, default the description's base link; ``None``
  accepts any frame). A pose older than ``object_pose_timeout`` (0.5 s) is stale: the env stops
  and raises, as for stale joint states; malformed poses (NaN, not a unit quaternion, another
  frame) are dropped and named in that error. The env waits up to ``startup_timeout`` for the first;
* an episode starts with the object where it lies (a robot cannot teleport it: put it back by
  hand, ``reset_env_prompt=True`` asks before each reset); the goal is sampled as in simulation;
* the gripper takes the finger target through its driver's interface
  (:mod:`multiros.envs.real.gripper`: ``gripper_interface``, ``gripper_controller``,
  ``gripper_joint``, ``gripper_range`` = the driver's values at the task's (closed, open)).

Positions are in the world frame of the task, as in simulation: the base at ``base_position``
(default: the simulated twin's spawn position, ``robot_pos_x/y/z``: for push and pick-and-place the
table height), so observations, goals and spaces are the simulated twin's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from multiros.envs.real.gripper import GRIPPER_INTERFACES
from multiros.envs.real.safety import SafetyRules
from multiros.envs.real.scene import RealSceneOptions

if TYPE_CHECKING:
    from multiros.envs.real.connection import RealConnection
    from multiros.utils.kinematics import KinematicChain

__all__ = ["RealArmSetup", "TaskJointLimits", "real_robot_kwargs"]

#: The key of :func:`real_robot_kwargs`' result that the arm's Real env pops before its env core sees the rest.
SETUP_KEY = "_real_arm_setup"


@dataclass(frozen=True)
class RealArmSetup:
    """What the arm's robot connection is told once it is up: where the base stands, the end-effector
    frame (forward kinematics of ``chain``) and, for push and pick-and-place, how the scene is reached."""

    base_position: np.ndarray
    ee_link: str
    chain: KinematicChain
    scene: RealSceneOptions | None

    def apply(self, connection: RealConnection) -> None:
        connection.set_base_position(self.base_position)
        connection.add_kinematic_frame(self.ee_link, self.chain)
        if self.scene is not None:
            connection.set_scene_options(self.scene)


def _velocity_limits(chain: Any) -> np.ndarray | None:
    """The chain's joint velocity limits (rad/s) when the description gives them all."""
    limits = np.asarray(chain.velocity_limits, dtype=np.float64)
    return limits if np.all(np.isfinite(limits)) and np.all(limits > 0) else None


def real_robot_kwargs(cls: Any, overrides: Mapping[str, Any]) -> dict[str, Any]:
    """:class:`~multiros.envs.RealBaseEnv` arguments for the arm ``cls`` (its constants: :class:`ArmRobot
    <rl_environments.arm_robot.ArmRobot>`'s ``REAL_*``, ``WORKSPACE_*``, ...); ``overrides`` (user kwargs) win.

    Robot-layer options (popped here): ``base_position`` (world position of the base, default
    ``robot_pos_x/y/z``, the simulated twin's spawn position, else the origin),
    ``workspace_min``/``workspace_max``/``floor_z`` (``None`` disables that check),
    ``max_joint_delta``, ``workspace_mode`` (``"project"`` or ``"refuse"``). Push and
    pick-and-place also take the scene's (see the module docstring): ``object_pose_topic``,
    ``object_pose_frame``, ``object_pose_timeout``, ``gripper_interface``, ``gripper_controller``,
    ``gripper_joint``, ``gripper_range``, ``gripper_max_effort``.
    """
    opts = dict(overrides)
    topic = getattr(cls, "REAL_JOINT_STATES_TOPIC", None)
    if topic:
        opts.setdefault("joint_states_topic", topic)
    spawn = [opts.pop(k, 0.0) for k in ("robot_pos_x", "robot_pos_y", "robot_pos_z")]
    base = np.asarray(opts.pop("base_position", spawn), dtype=np.float64).reshape(3)
    if not np.all(np.isfinite(base)):
        raise ValueError(f"base_position must be 3 finite numbers, got {base.tolist()}")
    scene_task = bool(getattr(cls, "SCENE_TASK", False))
    ws_default: tuple[Any, Any, Any] = (cls.WORKSPACE_MIN, cls.WORKSPACE_MAX, cls.FLOOR_Z)
    scene: RealSceneOptions | None = None
    if scene_task:
        ee_lo, ee_hi = (np.asarray(cls.SCENE[k], dtype=np.float64) + base
                        for k in ("position_ee_min", "position_ee_max"))
        ws_default = (tuple(ee_lo - 0.05), tuple(ee_hi + 0.05), float(ee_lo[2] - 0.005))
        scene = _scene_options_from(cls, opts)
    ws_min = opts.pop("workspace_min", ws_default[0])
    ws_max = opts.pop("workspace_max", ws_default[1])
    floor = opts.pop("floor_z", ws_default[2])
    chain = cls.kinematic_chain()
    if tuple(chain.joint_names) != tuple(cls.ARM_JOINTS):
        raise ValueError(f"{cls.__name__}: chain joints {chain.joint_names} differ from ARM_JOINTS "
                         f"{cls.ARM_JOINTS}")
    safety = SafetyRules(
        cls.ARM_JOINTS, lower=chain.lower, upper=chain.upper,
        max_joint_delta=opts.pop("max_joint_delta", cls.MAX_JOINT_DELTA), max_velocity=_velocity_limits(chain),
        chain=chain, base_position=base,
        workspace_min=ws_min, workspace_max=ws_max, floor_z=floor,
        workspace_mode=opts.pop("workspace_mode", "project"),
    )
    kwargs: dict[str, Any] = {
        "namespace": cls.REAL_NAMESPACE,
        "robot_name": cls.ROBOT_NAME,
        "arm_joints": cls.ARM_JOINTS,
        "arm_controller": cls.REAL_ARM_CONTROLLER,
        "controllers_list": list(cls.REAL_CONTROLLERS),
        "command_interface": cls.REAL_COMMAND_INTERFACE,
        "check_controllers": cls.REAL_CHECK_CONTROLLERS,
        "safety": safety,
    }
    kwargs.update(opts)
    # The frame served as a simulation serves it: the link's pose (the robot layer adds TCP_OFFSET).
    kwargs[SETUP_KEY] = RealArmSetup(base, cls.EE_LINK, chain.with_tip_offset(None), scene)
    return kwargs


def _scene_options_from(cls: Any, opts: dict[str, Any]) -> RealSceneOptions:
    """Pop and check the push / pick-and-place options of a real robot (module docstring)."""
    interface = opts.pop("gripper_interface", cls.REAL_GRIPPER_INTERFACE)
    if interface == "niryo_tool":
        raise ValueError(
            f"{cls.__name__}: the Ned2's gripper is Niryo's tool commander (/niryo_robot_tools_commander/"
            "action_server, niryo_ned_ros2_interfaces/action/Tool), whose interface definitions uniros does "
            "not ship: pass gripper_interface='none' (your own node drives the gripper) or 'trajectory', "
            "'forward' or 'gripper_action' with gripper_controller= (a bridge to the tool commander)")
    if interface not in GRIPPER_INTERFACES:
        raise ValueError(f"{cls.__name__}: gripper_interface {interface!r} is not one of "
                         f"{list(GRIPPER_INTERFACES)}")
    timeout = opts.pop("object_pose_timeout", 0.5)
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0 < timeout <= 60:
        raise ValueError(f"{cls.__name__}: object_pose_timeout must be a number of seconds in (0, 60], "
                         f"got {timeout!r}")
    topic = opts.pop("object_pose_topic", cls.OBJECT_POSE_TOPIC)
    if not isinstance(topic, str) or not topic.strip("/"):
        raise ValueError(f"{cls.__name__}: object_pose_topic must be a topic name, got {topic!r}")
    real_range = opts.pop("gripper_range", cls.REAL_GRIPPER_RANGE)
    # Two independently driven fingers: a trajectory or forward command drives both (a GripperCommand
    # action's driver moves its fingers itself).
    followers = ((cls.FINGER_JOINTS[1], float(cls.FINGER_MIMIC)),) if (
        cls.FINGERS_INDEPENDENT and interface in ("trajectory", "forward")) else ()
    return RealSceneOptions(
        gripper_interface=interface,
        gripper_controller=opts.pop("gripper_controller", cls.REAL_GRIPPER_CONTROLLER),
        gripper_joint=opts.pop("gripper_joint", cls.REAL_GRIPPER_JOINT) or cls.FINGER_JOINTS[0],
        gripper_range=None if real_range is None else (float(real_range[0]), float(real_range[1])),
        gripper_max_effort=float(opts.pop("gripper_max_effort", 0.0)),
        gripper_followers=followers,
        object_pose_topic=topic,
        object_pose_frame=opts.pop("object_pose_frame", cls.BASE_LINK),
        object_pose_timeout=float(timeout),
    )


class TaskJointLimits:
    """Mixed in before a Real twin's task: the task config's joint range tightens the safety rules' (the
    tighter bound wins; :meth:`~multiros.envs.connection.RobotConnection.limit_joints`)."""

    if TYPE_CHECKING:
        min_joint_pos: np.ndarray
        max_joint_pos: np.ndarray
        connection: Any

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.connection.limit_joints(self.min_joint_pos, self.max_joint_pos)
