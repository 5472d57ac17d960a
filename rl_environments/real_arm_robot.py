"""The robot layer of a real arm: :class:`~rl_environments.arm_robot.ArmRobot` (the arm's constants and
everything both sides share) over a robot's ROS 2 driver, where the simulated arm has
:class:`~rl_environments.arm_robot.SimArmRobot`. Its connection is a
:class:`~multiros.envs.real.connection.RealConnection`.

The end-effector position is forward kinematics of ``joint_states`` through the description
package's URDF (a real robot offers no end-effector service); arm targets go through the env's
:class:`~multiros.envs.real.safety.SafetyRules` to the JointTrajectoryController.

Push and pick-and-place on a real robot (the scene a simulation spawns is on the table already):

* the object's pose comes from a tracker (a motion-capture system, a fiducial or a vision node
  of yours) as ``geometry_msgs/PoseStamped`` on ``object_pose_topic`` (default ``/object_pose``), in
  the robot's base frame (``object_pose_frame``, default the description's base link; ``None``
  accepts any frame). A pose older than ``object_pose_timeout`` (0.5 s) is stale: the env stops
  and raises, as for stale joint states; malformed poses (NaN, not a unit quaternion, another
  frame) are dropped and named in that error. The env waits up to ``startup_timeout`` for the first;
* an episode starts with the object where it lies (a robot cannot teleport it: put it back by
  hand, ``reset_env_prompt=True`` asks before each reset); the goal is sampled as in simulation;
* the gripper takes the finger target through its driver's interface
  (:mod:`rl_environments.real_gripper`: ``gripper_interface``, ``gripper_controller``,
  ``gripper_joint``, ``gripper_range`` = the driver's values at the task's (closed, open)).

Positions are in the world frame of the task, as in simulation: the base at ``base_position``
(default: the simulated twin's spawn position, ``robot_pos_x/y/z``: for push and pick-and-place the
table height), so observations, goals and spaces are the simulated twin's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import numpy.typing as npt

from multiros.envs.real.errors import RobotConnectionError, StaleStateError
from multiros.envs.real.safety import SafetyRules
from multiros.robot_state import RobotStates
from rl_environments.arm_robot import ArmRobot
from rl_environments.real_gripper import GRIPPER_INTERFACES, RealGripper

if TYPE_CHECKING:
    from multiros.envs.real.connection import RealConnection


def _velocity_limits(chain: Any) -> np.ndarray | None:
    """The chain's joint velocity limits (rad/s) when the description gives them all."""
    limits = np.asarray(chain.velocity_limits, dtype=np.float64)
    return limits if np.all(np.isfinite(limits)) and np.all(limits > 0) else None


class RealArmRobot(ArmRobot):
    """Robot-layer behaviour of a fixed-base arm driven through ros2_control; a real robot sets the
    class attributes below besides :class:`~rl_environments.arm_robot.ArmRobot`'s.

    Attributes:
        REAL_NAMESPACE: the driver's namespace.
        REAL_ARM_CONTROLLER: the JointTrajectoryController over ``ARM_JOINTS``.
        REAL_CONTROLLERS: other controllers that must be active.
        WORKSPACE_MIN, WORKSPACE_MAX: the box (world frame) the end effector must stay in (reach;
            push and pick-and-place keep it inside their scene's end-effector box, 5 cm around it).
        FLOOR_Z: lowest allowed end-effector height (world frame; push and pick-and-place: 5 mm below
            the scene's lowest end-effector target, above the table).
        MAX_JOINT_DELTA: largest joint change per command (rad).
        REAL_COMMAND_INTERFACE: ``"topic"`` or ``"action"`` (the driver offers only the action).
        REAL_CHECK_CONTROLLERS: whether the driver has a ros2_control controller manager to ask.
        REAL_GRIPPER_CONTROLLER, REAL_GRIPPER_INTERFACE: the driver's gripper controller and how it
            takes commands (:data:`~rl_environments.real_gripper.GRIPPER_INTERFACES`).
        REAL_GRIPPER_JOINT: the joint a gripper trajectory commands (default the first finger joint).
        REAL_GRIPPER_RANGE: the driver's values at the task's (closed, open) fingers (default: the same).
    """

    REAL_NAMESPACE: ClassVar[str]
    REAL_ARM_CONTROLLER: ClassVar[str]
    REAL_CONTROLLERS: ClassVar[tuple[str, ...]] = ()
    WORKSPACE_MIN: ClassVar[tuple[float, float, float]]
    WORKSPACE_MAX: ClassVar[tuple[float, float, float]]
    FLOOR_Z: ClassVar[float] = 0.02
    MAX_JOINT_DELTA: ClassVar[float] = 0.15
    REAL_COMMAND_INTERFACE: ClassVar[str] = "topic"
    REAL_CHECK_CONTROLLERS: ClassVar[bool] = True
    REAL_GRIPPER_CONTROLLER: ClassVar[str] = "gripper_controller"
    REAL_GRIPPER_INTERFACE: ClassVar[str] = "forward"
    REAL_GRIPPER_JOINT: ClassVar[str | None] = None
    REAL_GRIPPER_RANGE: ClassVar[tuple[float, float] | None] = None
    OBJECT_POSE_TOPIC: ClassVar[str] = "/object_pose"
    _scene_options: dict[str, Any]
    _object_pose: Any = None
    _gripper: RealGripper | None = None

    if TYPE_CHECKING:  # the real env core's, below this layer
        connection: RealConnection
        safety: SafetyRules | None
        link: Any
        loop: Any

        def send_joint_targets(self, targets: Sequence[float] | np.ndarray) -> Any: ...

    @classmethod
    def real_robot_kwargs(cls, overrides: Mapping[str, Any]) -> dict[str, Any]:
        """:class:`~multiros.envs.RealBaseEnv` arguments for this robot; ``overrides`` (user kwargs) win.

        Robot-layer options (popped here): ``base_position`` (world position of the base, default
        ``robot_pos_x/y/z``, the simulated twin's spawn position, else the origin),
        ``workspace_min``/``workspace_max``/``floor_z`` (``None`` disables that check),
        ``max_joint_delta``, ``workspace_mode`` (``"project"`` or ``"refuse"``). Push and
        pick-and-place also take the scene's (see the module docstring): ``object_pose_topic``,
        ``object_pose_frame``, ``object_pose_timeout``, ``gripper_interface``, ``gripper_controller``,
        ``gripper_joint``, ``gripper_range``, ``gripper_max_effort``.
        """
        opts = dict(overrides)
        spawn = [opts.pop(k, 0.0) for k in ("robot_pos_x", "robot_pos_y", "robot_pos_z")]
        base = np.asarray(opts.pop("base_position", spawn), dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(base)):
            raise ValueError(f"base_position must be 3 finite numbers, got {base.tolist()}")
        scene_task = bool(getattr(cls, "SCENE_TASK", False))
        ws_default: tuple[Any, Any, Any] = (cls.WORKSPACE_MIN, cls.WORKSPACE_MAX, cls.FLOOR_Z)
        scene: dict[str, Any] = {}
        if scene_task:
            ee_lo, ee_hi = (np.asarray(cls.SCENE[k], dtype=np.float64) + base
                            for k in ("position_ee_min", "position_ee_max"))
            ws_default = (tuple(ee_lo - 0.05), tuple(ee_hi + 0.05), float(ee_lo[2] - 0.005))
            scene = cls._scene_options_from(opts)
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
        kwargs["_base_position"] = base
        kwargs["_scene_options"] = scene
        return kwargs

    @classmethod
    def _scene_options_from(cls, opts: dict[str, Any]) -> dict[str, Any]:
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
        return {
            "gripper_interface": interface,
            "gripper_controller": opts.pop("gripper_controller", cls.REAL_GRIPPER_CONTROLLER),
            "gripper_joint": opts.pop("gripper_joint", cls.REAL_GRIPPER_JOINT) or cls.FINGER_JOINTS[0],
            "gripper_range": None if real_range is None else tuple(float(v) for v in real_range),
            "gripper_max_effort": float(opts.pop("gripper_max_effort", 0.0)),
            "object_pose_topic": topic,
            "object_pose_frame": opts.pop("object_pose_frame", cls.BASE_LINK),
            "object_pose_timeout": float(timeout),
        }

    def _take_base(self, kwargs: dict[str, Any]) -> dict[str, Any]:
        self._base_position = kwargs.pop("_base_position")
        self._scene_options = kwargs.pop("_scene_options")
        return kwargs

    def serve_frames(self) -> None:
        """Give the connection the end-effector frame a simulation returns with each step: forward
        kinematics of the observed arm joints through the description's chain (a real robot offers no
        end-effector pose; the sim's frame is the same link of the same description), in the task's world."""
        chain, base = self.kinematic_chain(), self._base_position
        arm_positions_of = self.arm_positions_of
        self.connection.add_frame_source(self.EE_LINK,
                                         lambda states: (chain.fk_position(arm_positions_of(states)) + base, None))

    def apply_task_joint_limits(self, lower: npt.ArrayLike, upper: npt.ArrayLike) -> None:
        """Tighten the safety rules' joint limits to the task config's (the tighter bound wins)."""
        rules = self.safety
        assert rules is not None, "a real arm's env has safety rules"
        self.safety = SafetyRules(
            rules.joint_names, lower=lower, upper=upper, description_lower=rules.lower, description_upper=rules.upper,
            max_joint_delta=rules.max_joint_delta, max_velocity=rules.max_velocity, chain=rules.chain,
            base_position=rules.base_position,
            workspace_min=rules.workspace_min, workspace_max=rules.workspace_max, floor_z=rules.floor_z,
            workspace_mode=rules.workspace_mode, path_samples=rules.path_samples,
        )

    # -- the robot layer, batch-first (see rl_environments.arm_interface) -----------------------------
    @classmethod
    def set_arm_targets_of(cls, envs: Sequence[Any], targets: np.ndarray) -> None:
        """Command each env's arm through its safety rules (``info["safety"]`` says what they did)."""
        for env, row in zip(envs, targets):
            env.send_joint_targets(row)

    # -- the same for one env ------------------------------------------------------------------------
    @property
    def base_position(self) -> np.ndarray:
        """World position of the robot base (``base_position`` option; the origin by default)."""
        return self._base_position.copy()

    # -- push and pick-and-place on a robot: the tracker's object, the driver's gripper -----------------
    def spawn_scene(self, table: str, table_position: np.ndarray, obj: str, object_position: np.ndarray) -> None:
        """Nothing to spawn: subscribe to the tracker's object pose and reach the gripper's driver;
        wait for the first pose and the gripper's interface (``startup_timeout``)."""
        from multiros.envs.real.sensor_link import PoseTopic

        opts = self._scene_options
        wait = self.connection.startup_timeout
        self._gripper = RealGripper(self, opts["gripper_interface"], opts["gripper_controller"], opts["gripper_joint"],
                                    self.gripper_range, opts["gripper_range"], opts["gripper_max_effort"])  # type: ignore[attr-defined]
        if not self._gripper.wait_ready(wait):
            raise RobotConnectionError(
                f"nobody serves the gripper's {opts['gripper_interface']} interface of controller "
                f"{opts['gripper_controller']!r} within {wait:g} s: is the gripper driver running? "
                "(gripper_interface=, gripper_controller= name it)")
        self._object_pose = PoseTopic(self.node, self.link.resolve(opts["object_pose_topic"]),
                                      opts["object_pose_frame"])
        self._object_pose_timeout = opts["object_pose_timeout"]
        self._object_pose.wait_first(wait)
        # What a simulation returns with each step, from the robot's side: the object's frame from the
        # tracker, the gripper controller's commands to the gripper's driver.
        self.connection.add_frame_source(f"{obj}/object", lambda _states: self._object_pose_latest())
        gripper = self._gripper
        self.connection.route_controller(self.GRIPPER_CONTROLLER, lambda values: gripper.command(float(values[0])))

    def _object_pose_latest(self) -> tuple[np.ndarray, np.ndarray]:
        """The tracker's newest object pose in the task's world, ``(1, 3)`` and ``(1, 4)``; a stale one stops
        the env (:class:`~multiros.envs.real.sensor_link.StaleSensorError`)."""
        try:
            position, quat = self._object_pose.latest(self._object_pose_timeout)
        except StaleStateError as exc:
            self.connection.fault = exc
            raise
        return (np.asarray(position, dtype=np.float64) + self._base_position)[None], np.asarray(quat, np.float64)[None]

    @classmethod
    def observation_time(cls, envs: Sequence[Any], states: RobotStates) -> float:
        """The local time the robot's state arrived (seconds, monotonic)."""
        received = envs[0].robot_state.received
        return float(received) if received is not None else 0.0

    def place_object(self, position: np.ndarray, quat: np.ndarray) -> None:
        """Nothing: a robot cannot put the object anywhere (it starts where it lies; put it back by
        hand, ``reset_env_prompt=True`` asks before each reset)."""

    def open_fingers_at_reset(self, opening: float) -> None:
        """Open the gripper (a command to its driver)."""
        assert self._gripper is not None
        self._gripper.command(opening)

    def close(self) -> None:
        """Release the object pose subscription and the gripper's client, then the robot."""
        for part in (self._object_pose, self._gripper):
            if part is not None:
                part.close()
        super().close()  # type: ignore[misc]


class TaskJointLimits:
    """Mixed in before a Real twin's task: the task config's joint range tightens the safety rules'
    (the tighter bound wins)."""

    if TYPE_CHECKING:
        min_joint_pos: np.ndarray
        max_joint_pos: np.ndarray

        def apply_task_joint_limits(self, lower: npt.ArrayLike, upper: npt.ArrayLike) -> None: ...

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.apply_task_joint_limits(self.min_joint_pos, self.max_joint_pos)
