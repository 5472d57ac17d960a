"""The robot layer of an arm, one class for simulation and a robot: an arm of ``ARM_JOINTS`` under a
position controller, an end-effector frame, a kinematic chain for EE actions and goals, and for push
and pick-and-place its gripper, its top-down IK and its scene (a table and a cube).

:class:`ArmRobot` reads states and sends commands only through the robot connection
(:class:`~multiros.envs.connection.RobotConnection`), and asks it for whatever a side does its own way:
where the base is, the scene (spawned and teleported in simulation; a tracker's object and fixed
fixtures on a robot), the arm's command (with the next step; through a robot's safety rules), the
gripper (a controller in simulation; its driver's interface on a robot) and the clock of the states.
Only the constructor arguments differ: :meth:`ArmRobot.robot_kwargs` for the simulation node's env core,
:meth:`ArmRobot.real_robot_kwargs` (:mod:`rl_environments.real_arm_kwargs`) for a robot's. An arm's
constants come from its arm file (:mod:`rl_environments.arm_envs`); the env cores below are mixed in by
:mod:`rl_environments.arm_robot_envs`.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from importlib import import_module
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from multiros.envs import EnvError
from multiros.envs.connection import SceneEntity
from multiros.robot_state import RobotStates
from multiros.utils.kinematics import KinematicChain
from multiros.utils.rotations import matrix_from_quat
from rl_environments.arm_ik import TopDownIK
from rl_environments.arm_interface import ArmInterface

_ARM_INDEX: dict[tuple[type, tuple[str, ...]], np.ndarray | slice] = {}


@functools.lru_cache(maxsize=8)
def _chain(package: str, xacro_file: str, args: tuple[tuple[str, str], ...], base: str, tip: str) -> KinematicChain:
    # A chain is immutable once built, so envs may share it; xacro processing costs ~0.1 s.
    where = import_module(package).__file__
    if where is None:
        raise EnvError(f"description package module {package!r} has no files on disk")
    root = Path(where).parent
    return KinematicChain.from_urdf(root / "urdf" / xacro_file, base, tip, xacro_args=dict(args))


class ArmRobot(ArmInterface):
    """Robot-layer behaviour of a fixed-base arm. A robot sets the class attributes below.

    Attributes:
        ROBOT_NAME: entity name and default namespace.
        DESCRIPTION_PACKAGE: the ROS package name (``package://`` URI host).
        DESCRIPTION_MODULE: the Python package shipping it (for local kinematics).
        XACRO_FILE: the xacro file in ``urdf/``.
        XACRO_ARGS: xacro arguments.
        CONTROLLERS_FILE: the ros2_control controllers YAML in the package's ``config/``.
        ARM_JOINTS: the arm's joint names, in command order.
        BASE_LINK, EE_LINK: the kinematic chain's ends (URDF link names).
        TCP_OFFSET: the end effector as a point of ``EE_LINK`` (metres, in its frame; zeros: its origin),
            for a description with no link between the fingers (an arm file's ``arm.tcp_offset``).
        ARM_CONTROLLER: the group position controller commanding ``ARM_JOINTS``.
        CONTROLLERS: controllers to activate at spawn.
        SIM_TIMESTEP: physics time step in seconds.
        NUM_SIM_STEPS: physics steps per env step (lockstep). The control period is
            ``SIM_TIMESTEP * NUM_SIM_STEPS`` (40 ms, Fetch's, by default).
        RENDER_CAMERA: the description's camera ``render()`` uses unless ``render_camera`` is
            given (in the world: ``"<robot_name>/<camera>"``); empty = the node's default view.
        GRIPPER_CONTROLLER: push and pick-and-place: the controller commanding the first of
            ``FINGER_JOINTS`` (a position).
        FINGER_JOINTS: the commanded finger joint and the one mimicking it.
        FINGER_MIMIC: the second finger's position per unit of the first (its URDF ``<mimic>``).
        FINGERS_INDEPENDENT: both finger joints are driven (no ``<mimic>`` ties them): the gripper
            controller takes both, the second at ``FINGER_MIMIC`` times the first.
        RESET_MIMIC: whether a reset also teleports the second finger to its mimic position (the
            RX200's episodes have only ever set the commanded one; its mimic then follows).
        SCENE: the push / pick-and-place scene, positions relative to the robot base (the description
            package's ``SCENE``: ``robot_height``, ``table_center``, ``table_top``,
            ``object_half_size``, ``init_ee_position``, the object, goal and end-effector boxes,
            ``target_height_max``, ``max_object_distance``); the package's ``mjcf/table.xml`` and
            ``mjcf/cube.xml`` match it. :meth:`top_down_ik` gives the arm's IK with the gripper
            pointing down.
        CAMERA_VIEW: camera observations (:mod:`rl_environments.camera_obs`): the default camera,
            ``((x, y, z) lookat, distance, azimuth, elevation)`` relative to the robot base (metres,
            degrees), by default the view of the description's ``render_camera``.
        CAMERA_TOPICS: a described camera's ``(rgb, depth)`` topics, relative to the robot's
            namespace, when not ``<camera>/image_raw`` and ``<camera>/depth/image_raw``.

    The Real twin's (its arm file's ``real`` section; :meth:`real_robot_kwargs`):

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
            takes commands (:data:`~multiros.envs.real.gripper.GRIPPER_INTERFACES`).
        REAL_GRIPPER_JOINT: the joint a gripper trajectory commands (default the first finger joint).
        REAL_GRIPPER_RANGE: the driver's values at the task's (closed, open) fingers (default: the same).
        OBJECT_POSE_TOPIC: the object tracker's ``PoseStamped`` topic.
    """

    ROBOT_NAME: ClassVar[str]
    DESCRIPTION_PACKAGE: ClassVar[str]
    DESCRIPTION_MODULE: ClassVar[str]
    XACRO_FILE: ClassVar[str]
    XACRO_ARGS: ClassVar[Mapping[str, str]] = {}
    CONTROLLERS_FILE: ClassVar[str]
    ARM_JOINTS: ClassVar[tuple[str, ...]]
    BASE_LINK: ClassVar[str]
    EE_LINK: ClassVar[str]
    TCP_OFFSET: ClassVar[tuple[float, ...]] = (0.0, 0.0, 0.0)
    ARM_CONTROLLER: ClassVar[str]
    CONTROLLERS: ClassVar[tuple[str, ...]]
    # 4 ms steps: the position servos of both arms are far inside their explicit-stiffness stability
    # bound there (dt < 2 sqrt(I / kp) ~ 20 ms with implicit damping), and it halves the physics
    # cost of a 40 ms control period compared with MuJoCo's 2 ms default.
    SIM_TIMESTEP: ClassVar[float] = 0.004
    NUM_SIM_STEPS: ClassVar[int] = 10
    RENDER_CAMERA: ClassVar[str] = "render_camera"
    GRIPPER_CONTROLLER: ClassVar[str] = ""
    FINGER_JOINTS: ClassVar[tuple[str, ...]] = ()
    #: The arm's joint positions it is spawned at (an arm file's ``arm.home``); empty: the description's.
    HOME: ClassVar[tuple[float, ...]] = ()
    FINGER_MIMIC: ClassVar[float] = -1.0
    RESET_MIMIC: ClassVar[bool] = True
    FINGERS_INDEPENDENT: ClassVar[bool] = False
    SCENE: ClassVar[Mapping[str, Any]] = {}
    CAMERA_VIEW: ClassVar[tuple[tuple[float, float, float], float, float, float]] = ((0.2, 0.0, 0.1), 0.9, 140.0,
                                                                                      -25.0)
    CAMERA_TOPICS: ClassVar[Mapping[str, tuple[str, str]]] = {}
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
    # The scene of push and pick-and-place (set by the manipulation task: place_object uses them).
    table_entity: str
    table_frame: str
    table_pose: np.ndarray
    object_entity: str

    @classmethod
    def top_down_ik(cls, lower: Sequence[float], upper: Sequence[float]) -> TopDownIK:
        """The arm's top-down IK within joint limits ``lower``/``upper`` (push and pick-and-place)."""
        raise EnvError(f"{cls.__name__} has no top-down IK: push and pick-and-place need one (top_down_ik)")

    @classmethod
    def scene_uri(cls, item: str) -> str:
        """``package://`` URI of the scene's ``"table"`` or ``"cube"`` MJCF in the description package."""
        return f"package://{cls.DESCRIPTION_PACKAGE}/mjcf/{item}.xml"

    @classmethod
    def scene_mjcf(cls, item: str) -> str:
        """The ``"table"`` or ``"cube"`` as MJCF text when the scene is made from sizes (else ``""``: the
        :meth:`scene_uri` file)."""
        return ""

    @classmethod
    def robot_kwargs(cls, overrides: Mapping[str, Any]) -> dict[str, Any]:
        """Base-env constructor arguments for this robot; ``overrides`` (user kwargs) win."""
        model, xacro_args, controllers = cls.description_files()
        kwargs: dict[str, Any] = {
            "robot_name": cls.ROBOT_NAME,
            "robot_model_xml": model,
            "urdf_xacro_args": xacro_args,
            "controllers_file": controllers,
            "controllers_list": list(cls.CONTROLLERS),
            "frames": [cls.EE_LINK],
            "num_sim_steps": cls.NUM_SIM_STEPS,
            "sim_timestep": cls.SIM_TIMESTEP,
        }
        if cls.HOME:  # spawned at home: an arm whose zero pose reaches below its base stays clear of the table
            kwargs["initial_joint_positions"] = dict(zip(cls.ARM_JOINTS, cls.HOME))
        kwargs.update(overrides)
        if cls.RENDER_CAMERA and "render_camera" not in overrides and kwargs.get("spawn_robot", True):
            kwargs["render_camera"] = f"{kwargs['robot_name']}/{cls.RENDER_CAMERA}"
        return kwargs

    @classmethod
    def real_robot_kwargs(cls, overrides: Mapping[str, Any]) -> dict[str, Any]:
        """:class:`~multiros.envs.RealBaseEnv` arguments for this arm on a robot; ``overrides`` (user kwargs)
        win (:func:`rl_environments.real_arm_kwargs.real_robot_kwargs` says which it takes)."""
        from rl_environments.real_arm_kwargs import real_robot_kwargs

        return real_robot_kwargs(cls, overrides)

    @classmethod
    def description_files(cls) -> tuple[str, dict[str, str], str]:
        """The description URI, its xacro arguments and the controllers file the robot is spawned from."""
        return (f"package://{cls.DESCRIPTION_PACKAGE}/urdf/{cls.XACRO_FILE}", dict(cls.XACRO_ARGS),
                f"package://{cls.DESCRIPTION_PACKAGE}/config/{cls.CONTROLLERS_FILE}")

    @classmethod
    def kinematic_chain(cls) -> KinematicChain:
        """The arm's chain from ``BASE_LINK`` to ``EE_LINK`` (built once per process)."""
        return _chain(cls.DESCRIPTION_MODULE, cls.XACRO_FILE, tuple(sorted(cls.XACRO_ARGS.items())),
                      cls.BASE_LINK, cls.EE_LINK)

    # -- the robot layer, batch-first (see rl_environments.arm_interface) -----------------------------
    @classmethod
    def arm_index(cls, names: tuple[str, ...]) -> np.ndarray | slice:
        """Where ``ARM_JOINTS`` sit in joint arrays ordered as ``names`` (cached per class and order):
        a slice when they are consecutive (a view, not a gather), else an index array."""
        key = (cls, names)
        idx = _ARM_INDEX.get(key)
        if idx is None:
            where = {name: i for i, name in enumerate(names)}
            missing = [j for j in cls.ARM_JOINTS if j not in where]
            if missing:
                raise EnvError(f"{cls.__name__}: the robot reports no joints {missing}; joints: {names}")
            found = [where[j] for j in cls.ARM_JOINTS]
            consecutive = found == list(range(found[0], found[0] + len(found)))
            idx = _ARM_INDEX[key] = (slice(found[0], found[0] + len(found)) if consecutive
                                     else np.array(found, dtype=np.intp))
        return idx

    @classmethod
    def arm_positions_of(cls, states: RobotStates) -> np.ndarray:
        """The arm joints' positions (a view of ``states`` when the arm's joints are consecutive: read only)."""
        return states.position[:, cls.arm_index(states.names)]

    @classmethod
    def arm_velocities_of(cls, states: RobotStates) -> np.ndarray:
        """The arm joints' velocities (read only, as :meth:`arm_positions_of`)."""
        return states.velocity[:, cls.arm_index(states.names)]

    @classmethod
    def ee_positions_of(cls, envs: Sequence[Any], states: RobotStates) -> np.ndarray:
        """The end effector of each state, in each env's world: the ``EE_LINK`` frame (returned with the step
        in simulation, forward kinematics of the observed joints on a robot: the connection's), moved by
        ``TCP_OFFSET`` in its frame."""
        if not any(cls.TCP_OFFSET):
            return envs[0].connection.frame_positions(states, cls.EE_LINK)
        where, quat = envs[0].connection.frame_poses(states, cls.EE_LINK)
        return where + np.einsum("nij,j->ni", matrix_from_quat(quat), np.asarray(cls.TCP_OFFSET, dtype=np.float64))

    @classmethod
    def set_arm_targets_of(cls, envs: Sequence[Any], targets: np.ndarray) -> None:
        """Each env's arm command: with the next physics step in simulation; on a robot through its safety
        rules (``info["safety"]`` says what they did)."""
        controller = cls.ARM_CONTROLLER
        for env, row in zip(envs, targets):
            env.connection.command_arm(controller, row, env.info)

    # -- the same for one env (scripted policies, user code) -------------------------------------------
    def arm_positions(self) -> np.ndarray:
        """Arm joint positions after the last step, in ``ARM_JOINTS`` order (a fresh array)."""
        return self.arm_positions_of(self.connection.states)[0].copy()

    def arm_velocities(self) -> np.ndarray:
        """Arm joint velocities after the last step (a fresh array)."""
        return self.arm_velocities_of(self.connection.states)[0].copy()

    def ee_position(self) -> np.ndarray:
        """World position of the end effector after the last step."""
        return self.ee_positions_of([self], self.connection.states)[0].copy()

    def set_arm_targets(self, targets: np.ndarray) -> None:
        """Command the arm's position controller (sent with the next physics step)."""
        self.set_arm_targets_of([self], np.asarray(targets, dtype=np.float64)[None])

    @classmethod
    def object_poses_of(cls, envs: Sequence[Any], states: RobotStates) -> tuple[np.ndarray, np.ndarray]:
        """``(N, 3)`` positions and ``(N, 4)`` orientations ``(w, x, y, z)`` of the envs' objects (frames
        returned with the step in simulation, a tracker's poses on a robot: the connection's)."""
        return envs[0].connection.frame_poses(states, envs[0].object_frame)

    @classmethod
    def observation_time(cls, envs: Sequence[Any], states: RobotStates) -> float:
        """The clock of the states (finite-difference velocities): simulation time, or the local time a
        robot's state arrived (the connection's)."""
        return envs[0].connection.observation_time(states)

    @classmethod
    def command_grippers(cls, envs: Sequence[Any], targets: Sequence[float]) -> None:
        """Each env's finger target: the gripper controller's command (with the next step in simulation; on
        a robot, routed by the connection to the gripper driver's interface)."""
        for env, target in zip(envs, targets):
            values = [float(target), cls.FINGER_MIMIC * float(target)] if cls.FINGERS_INDEPENDENT else [float(target)]
            env.connection.command(cls.GRIPPER_CONTROLLER, np.array(values))

    # -- where the arm stands, its scene and its gripper (the connection's, whichever side) --------------
    @property
    def base_position(self) -> np.ndarray:
        """World position of the robot base: its spawn position in simulation, ``base_position`` on a robot."""
        return self.connection.base_position

    def spawn_scene(self, table: str, table_position: np.ndarray, obj: str, object_position: np.ndarray) -> None:
        """The push / pick-and-place scene and the gripper: the connection reaches the gripper, then
        spawns the table and the cube into the robot's namespace (a shared world's reset puts them back
        with the robot) or, on a robot, serves the tracker's object and the standing table."""
        if self.GRIPPER_CONTROLLER:
            self.connection.use_gripper(self.GRIPPER_CONTROLLER, tuple(self.gripper_range))  # type: ignore[attr-defined]
        self.connection.add_scene((
            SceneEntity(table, self.scene_uri("table"), _point(table_position), f"{table}/table", movable=False,
                        mjcf=self.scene_mjcf("table")),
            SceneEntity(obj, self.scene_uri("cube"), _point(object_position), f"{obj}/object", movable=True,
                        mjcf=self.scene_mjcf("cube"))))

    def place_object(self, position: np.ndarray, quat: np.ndarray) -> None:
        """Teleport the object (at rest) to its episode start; put the table back when knocked. On a robot
        nothing moves (put it back by hand; ``reset_env_prompt=True`` asks before each reset)."""
        table = self.connection.frame_positions(self.connection.states, self.table_frame)[0]
        if np.linalg.norm(table - self.table_pose) > 1e-3:
            self.connection.place_entity(self.table_entity, self.table_pose, np.array([1.0, 0, 0, 0]))
        self.connection.place_entity(self.object_entity, position, quat)

    def open_fingers_at_reset(self, opening: float) -> None:
        """Put the fingers at ``opening`` for the episode start: in simulation a teleport, held (the second
        finger at its mimic position, or left to follow through the mimic when ``RESET_MIMIC`` is false);
        on a robot a command to the gripper's driver."""
        if not self.RESET_MIMIC or len(self.FINGER_JOINTS) < 2:
            joints, positions = self.FINGER_JOINTS[:1], [opening]
        else:
            joints, positions = self.FINGER_JOINTS, [opening, self.FINGER_MIMIC * opening]
        self.connection.reset_gripper(self.GRIPPER_CONTROLLER, joints, positions)

    def _check_connection_and_readiness(self) -> bool:
        names = self.robot_state.names
        missing = [j for j in self.ARM_JOINTS if j not in names]
        if missing:
            raise EnvError(f"robot {self.robot_name!r} reports no joints {missing}; joints: {names}")
        return True


def _point(position: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in np.asarray(position, dtype=np.float64).reshape(3))
    return x, y, z
