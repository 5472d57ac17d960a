"""An arm as a value: what an arm file says, and what an env needs of it, on either side.

:class:`Arm` is made from a checked arm file (:mod:`rl_environments.arm_file`) and never changes. It
gives the tasks the arm's joints, end effector, kinematic chain, top-down IK, gripper and scene, reads
them out of N robots' states at once (``(N, ...)`` arrays, batch-first), and commands them through a
robot connection (:class:`~multiros.envs.connection.RobotConnection`), which does whatever a side does
its own way: the simulation node's frames and controllers, or a robot's forward kinematics, safety
rules, gripper driver and object tracker. The only other difference between the sides is the env
core's constructor arguments: :meth:`Arm.sim_kwargs` for the simulation node's, :meth:`Arm.real_kwargs`
(with its :class:`RealArmSetup`) for a robot driver's.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from multiros.envs import EnvError
from multiros.envs.connection import RobotConnection, SceneEntity
from multiros.envs.real.gripper import GRIPPER_INTERFACES
from multiros.envs.real.safety import SafetyRules
from multiros.envs.real.scene import RealSceneOptions
from multiros.robot_state import RobotStates
from multiros.utils.kinematics import KinematicChain
from multiros.utils.rotations import matrix_from_quat
from rl_environments.arm_file import ArmFile, ArmFileError
from rl_environments.arm_ik import ChainTopDownIK, PlanarWristTopDownIK, TopDownIK

__all__ = ["Arm", "RealArmSetup", "chain_of", "top_down_ik_of"]


def chain_of(spec: ArmFile) -> KinematicChain:
    """The arm's chain from ``arm.base_link`` to its end effector (``arm.ee_link``, moved by ``arm.tcp_offset``)
    of its description (built once per process)."""
    chain = _chain(spec.description_uri, tuple(sorted(spec.xacro_args.items())), spec.base_link, spec.ee_link)
    return chain.with_tip_offset(spec.tcp_offset) if any(spec.tcp_offset) else chain


def top_down_ik_of(spec: ArmFile, lower: Sequence[float] | None = None,
                   upper: Sequence[float] | None = None) -> TopDownIK:
    """The arm's top-down IK (its file's ``arm.top_down_ik`` solver, axes, seed and home) within joint
    limits (default the chain's)."""
    ik = spec.top_down_ik
    if ik.get("solver") == "planar_wrist":
        chain = chain_of(spec)
        return PlanarWristTopDownIK(ik["shoulder_height"], ik["upper_arm"], ik["forearm"], ik["tip"], spec.joints,
                                    chain.lower if lower is None else lower, chain.upper if upper is None else upper)
    return ChainTopDownIK(chain_of(spec), spec.approach_axis, spec.closing_axis, spec.ik_seed, home=spec.home,
                          lower=lower, upper=upper)


@functools.lru_cache(maxsize=32)
def _urdf_text(uri: str, args: tuple[tuple[str, str], ...]) -> str:
    # xacro costs ~0.1 s; the text is immutable, so envs share it.
    from multiros.sim.description import xacro_to_urdf
    from multiros.sim.packages import default_index

    index = default_index()
    path = index.resolve_uri(uri)
    if not path.is_file():
        raise ArmFileError(f"description {uri!r}: file {str(path)!r} not found")
    return xacro_to_urdf(path, dict(args), index=index) if path.name.endswith(".xacro") else path.read_text()


@functools.lru_cache(maxsize=32)
def _chain(uri: str, args: tuple[tuple[str, str], ...], base: str, tip: str) -> KinematicChain:
    return KinematicChain.from_urdf(_urdf_text(uri, args), base, tip)


@dataclass(frozen=True)
class RealArmSetup:
    """What a robot's connection is told once it is up: where the base stands, the end-effector frame
    (forward kinematics of ``chain``) and, for a task with a scene, how the scene is reached."""

    base_position: np.ndarray
    ee_link: str
    chain: KinematicChain
    scene: RealSceneOptions | None

    def apply(self, connection: Any) -> None:
        connection.set_base_position(self.base_position)
        connection.add_kinematic_frame(self.ee_link, self.chain)
        if self.scene is not None:
            connection.set_scene_options(self.scene)


@dataclass(frozen=True, eq=False)
class Arm:
    """A registered arm (see the module docstring). ``Arm(file)``; compare arms by ``name``."""

    file: ArmFile

    # -- what the file says ---------------------------------------------------------------------------
    @property
    def name(self) -> str:
        """The ID prefix (``RX200``)."""
        return self.file.name

    @property
    def robot_name(self) -> str:
        """Entity name and default ROS namespace."""
        return self.file.robot_name

    @property
    def joints(self) -> tuple[str, ...]:
        """The arm joints, in command order."""
        return self.file.joints

    @property
    def ee_link(self) -> str:
        return self.file.ee_link

    @property
    def base_link(self) -> str:
        return self.file.base_link

    @property
    def tcp_offset(self) -> tuple[float, float, float]:
        """The end effector as a point of ``ee_link`` (metres, in its frame)."""
        return self.file.tcp_offset

    @property
    def arm_controller(self) -> str:
        return self.file.arm_controller

    @property
    def finger_joints(self) -> tuple[str, ...]:
        """The commanded finger joint and the one that follows it (empty without a gripper)."""
        return self.file.gripper.joints if self.file.gripper else ()

    @property
    def finger_mimic(self) -> float:
        """The second finger's position per unit of the first (its URDF ``<mimic>``)."""
        return self.file.gripper.mimic if self.file.gripper else 1.0

    @property
    def gripper_controller(self) -> str:
        return self.file.gripper.controller if self.file.gripper else ""

    @property
    def camera_view(self) -> tuple[tuple[float, float, float], float, float, float]:
        return self.file.camera_view

    @property
    def camera_topics(self) -> Mapping[str, tuple[str, str]]:
        return self.file.camera_topics

    @property
    def camera_defaults(self) -> Mapping[str, Any]:
        return self.file.camera_defaults

    def task_config(self, section: str) -> dict[str, Any]:
        """The file's ``reach`` or ``manipulation`` settings (checked when the file was loaded)."""
        values = self.file.reach if section == "reach" else self.file.manipulation
        if values is None:
            raise EnvError(f"{self.file.path}: the arm has no gripper, so no {section} task")
        return dict(values)

    # -- kinematics --------------------------------------------------------------------------------
    @functools.cached_property
    def chain(self) -> KinematicChain:
        """The chain from the base link to the end effector (``tcp_offset`` included)."""
        return chain_of(self.file)

    def top_down_ik(self, lower: Sequence[float], upper: Sequence[float]) -> TopDownIK:
        """The IK with the gripper pointing down, within joint limits ``lower``/``upper``."""
        return top_down_ik_of(self.file, lower, upper)

    # -- N robots' states, batch-first --------------------------------------------------------------
    @functools.lru_cache(maxsize=16)  # noqa: B019  # a few joint orders per arm; arms live as long as the process
    def arm_index(self, names: tuple[str, ...]) -> np.ndarray | slice:
        """Where the arm joints sit in joint arrays ordered as ``names``: a slice when they are consecutive
        (a view, not a gather), else an index array."""
        where = {name: i for i, name in enumerate(names)}
        missing = [j for j in self.joints if j not in where]
        if missing:
            raise EnvError(f"{self.name}: the robot reports no joints {missing}; joints: {names}")
        found = [where[j] for j in self.joints]
        if found == list(range(found[0], found[0] + len(found))):
            return slice(found[0], found[0] + len(found))
        return np.array(found, dtype=np.intp)

    def positions_of(self, states: RobotStates) -> np.ndarray:
        """``(N, arm joints)`` positions (a view of ``states`` when the joints are consecutive: read only)."""
        return states.position[:, self.arm_index(states.names)]

    def velocities_of(self, states: RobotStates) -> np.ndarray:
        """``(N, arm joints)`` velocities (read only, as :meth:`positions_of`)."""
        return states.velocity[:, self.arm_index(states.names)]

    def ee_positions_of(self, connection: RobotConnection, states: RobotStates) -> np.ndarray:
        """``(N, 3)`` end effectors: the ``ee_link`` frame (with the step in simulation, forward kinematics on
        a robot: the connection's), moved by ``tcp_offset`` in its frame."""
        if not any(self.tcp_offset):
            return connection.frame_positions(states, self.ee_link)
        where, quat = connection.frame_poses(states, self.ee_link)
        return where + np.einsum("nij,j->ni", matrix_from_quat(quat), np.asarray(self.tcp_offset, dtype=np.float64))

    def finger_states(self, states: RobotStates) -> tuple[np.ndarray, np.ndarray]:
        """Both fingers' positions and velocities (N x 2 each), in ``finger_joints`` order.

        A driver may publish only the commanded finger (a ros2_control mimic joint has no hardware
        behind it); the other is then the commanded one times ``finger_mimic``, as its URDF says.
        """
        where = {name: i for i, name in enumerate(states.names)}
        lead = self.finger_joints[0]
        if lead not in where:
            raise KeyError(f"the robot's joint states have no {lead!r}, the gripper's commanded finger "
                           f"(gripper.joints[0]); joints: {list(states.names)}")
        pos, vel = states.position[:, where[lead]], states.velocity[:, where[lead]]
        other = self.finger_joints[1] if len(self.finger_joints) > 1 else None
        if other is not None and other in where:
            return (np.stack([pos, states.position[:, where[other]]], axis=1),
                    np.stack([vel, states.velocity[:, where[other]]], axis=1))
        mimic = self.finger_mimic
        return np.stack([pos, mimic * pos], axis=1), np.stack([vel, mimic * vel], axis=1)

    # -- commands -------------------------------------------------------------------------------------
    def command_arm(self, connection: RobotConnection, targets: np.ndarray, info: dict[str, Any]) -> None:
        """Joint targets: with the next physics step in simulation; through a robot's safety rules."""
        connection.command_arm(self.arm_controller, targets, info)

    def command_gripper(self, connection: RobotConnection, target: float) -> None:
        """The commanded finger's target (both fingers' when they are driven independently)."""
        gripper = self.file.gripper
        assert gripper is not None
        values = [float(target), gripper.mimic * float(target)] if gripper.independent else [float(target)]
        connection.command(gripper.controller, np.array(values))

    def open_gripper_at_reset(self, connection: RobotConnection, opening: float) -> None:
        """The fingers at ``opening`` for an episode's start: a teleport, held, in simulation (the second
        finger at its mimic position unless the file's ``reset_mimic`` is false); a command on a robot."""
        gripper = self.file.gripper
        assert gripper is not None
        if not gripper.reset_mimic or len(gripper.joints) < 2:
            joints, positions = gripper.joints[:1], [opening]
        else:
            joints, positions = gripper.joints, [opening, gripper.mimic * opening]
        connection.reset_gripper(gripper.controller, joints, positions)

    # -- the scene of tasks with objects ------------------------------------------------------------
    def scene_entity(self, item: str, entity: str, position: np.ndarray, *, movable: bool) -> SceneEntity:
        """The ``"table"`` or ``"object"`` of push and pick-and-place as a spawnable entity: the file's
        ``scene:`` MJCF when it names one, else made from its ``manipulation`` sizes."""
        from rl_environments.arm_scene import scene_mjcf

        uri = self.file.scene_files.get(item, "")
        sizes = self.file.manipulation
        mjcf = "" if uri or sizes is None else scene_mjcf(self.robot_name, sizes, item)
        x, y, z = (float(v) for v in np.asarray(position, dtype=np.float64).reshape(3))
        return SceneEntity(entity, uri, (x, y, z), f"{entity}/{item}", movable=movable, mjcf=mjcf)

    # -- the env core's constructor arguments, per side ----------------------------------------------
    def sim_kwargs(self, overrides: Mapping[str, Any]) -> dict[str, Any]:
        """The simulation node's env-core arguments for this arm; ``overrides`` (the user's) win."""
        spec = self.file
        kwargs: dict[str, Any] = {
            "robot_name": spec.robot_name, "robot_model_xml": spec.description_uri,
            "urdf_xacro_args": dict(spec.xacro_args), "controllers_file": spec.controllers_file,
            "controllers_list": list(spec.sim_controllers), "frames": [spec.ee_link],
            "num_sim_steps": 10, "sim_timestep": 0.004,  # 40 ms control periods (Fetch's) of 4 ms physics steps
        }
        if spec.home:  # spawned at home: an arm whose zero pose reaches below its base stays clear of the table
            kwargs["initial_joint_positions"] = dict(zip(spec.joints, spec.home))
        kwargs.update(overrides)
        if spec.render_camera and "render_camera" not in overrides and kwargs.get("spawn_robot", True):
            kwargs["render_camera"] = f"{kwargs['robot_name']}/{spec.render_camera}"
        return kwargs

    def real_kwargs(self, overrides: Mapping[str, Any], *, scene: tuple[Any, Any] | None = None,
                    ) -> tuple[dict[str, Any], RealArmSetup]:
        """A robot driver's env-core arguments for this arm (``overrides``, the user's, win) and what its
        connection is told once up. ``scene``: a task with a table and an object gives its end-effector box
        ``(low, high)`` (base frame).

        Arm options (taken here): ``base_position`` (default ``robot_pos_x/y/z``, the simulated twin's spawn
        position), ``workspace_min``/``workspace_max``/``floor_z`` (``None`` disables that check),
        ``max_joint_delta``, ``workspace_mode``; with a scene also ``object_pose_topic``,
        ``object_pose_frame``, ``object_pose_timeout``, ``gripper_interface``, ``gripper_controller``,
        ``gripper_joint``, ``gripper_range``, ``gripper_max_effort`` (docs/real.md).
        """
        spec, real = self.file, self.file.real
        opts = dict(overrides)
        if real.joint_states_topic:
            opts.setdefault("joint_states_topic", real.joint_states_topic)
        spawn = [opts.pop(k, 0.0) for k in ("robot_pos_x", "robot_pos_y", "robot_pos_z")]
        base = np.asarray(opts.pop("base_position", spawn), dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(base)):
            raise ValueError(f"base_position must be 3 finite numbers, got {base.tolist()}")
        ws_default: tuple[Any, Any, Any] = (real.workspace_min, real.workspace_max, real.floor_z)
        scene_options = None
        if scene is not None:  # the end effector kept inside the task's box, 5 cm around it, 5 mm above its lowest
            ee_lo, ee_hi = (np.asarray(v, dtype=np.float64) + base for v in scene)
            ws_default = (tuple(ee_lo - 0.05), tuple(ee_hi + 0.05), float(ee_lo[2] - 0.005))
            scene_options = self._real_scene_options(opts)
        ws_min = opts.pop("workspace_min", ws_default[0])
        ws_max = opts.pop("workspace_max", ws_default[1])
        floor = opts.pop("floor_z", ws_default[2])
        chain = self.chain
        limits = np.asarray(chain.velocity_limits, dtype=np.float64)
        safety = SafetyRules(
            spec.joints, lower=chain.lower, upper=chain.upper,
            max_joint_delta=opts.pop("max_joint_delta", real.max_joint_delta),
            max_velocity=limits if np.all(np.isfinite(limits)) and np.all(limits > 0) else None,
            chain=chain, base_position=base, workspace_min=ws_min, workspace_max=ws_max, floor_z=floor,
            workspace_mode=opts.pop("workspace_mode", "project"))
        kwargs: dict[str, Any] = {
            "namespace": real.namespace, "robot_name": spec.robot_name, "arm_joints": spec.joints,
            "arm_controller": real.arm_controller, "controllers_list": list(real.controllers),
            "command_interface": real.command_interface, "check_controllers": real.check_controllers,
            "safety": safety, "reset_tolerance": real.reset_tolerance,
            "reset_settle_tolerance": real.reset_settle_tolerance,
        }
        kwargs.update(opts)
        # The frame is served as a simulation serves it: the link's pose (ee_positions_of adds tcp_offset).
        return kwargs, RealArmSetup(base, spec.ee_link, chain.with_tip_offset(None), scene_options)

    def _real_scene_options(self, opts: dict[str, Any]) -> RealSceneOptions:
        real, gripper = self.file.real, self.file.gripper
        interface = opts.pop("gripper_interface", real.gripper_interface if gripper is not None else "none")
        if interface == "niryo_tool":
            raise ValueError(
                f"{self.name}: the Ned2's gripper is Niryo's tool commander (/niryo_robot_tools_commander/"
                "action_server, niryo_ned_ros2_interfaces/action/Tool), whose interface definitions uniros does "
                "not ship: pass gripper_interface='none' (your own node drives the gripper) or 'trajectory', "
                "'forward' or 'gripper_action' with gripper_controller= (a bridge to the tool commander)")
        if interface not in GRIPPER_INTERFACES:
            raise ValueError(f"{self.name}: gripper_interface {interface!r} is not one of {list(GRIPPER_INTERFACES)}")
        timeout = opts.pop("object_pose_timeout", 0.5)
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not 0 < timeout <= 60:
            raise ValueError(f"{self.name}: object_pose_timeout must be a number of seconds in (0, 60], "
                             f"got {timeout!r}")
        topic = opts.pop("object_pose_topic", "/object_pose")
        if not isinstance(topic, str) or not topic.strip("/"):
            raise ValueError(f"{self.name}: object_pose_topic must be a topic name, got {topic!r}")
        real_range = opts.pop("gripper_range", real.gripper_range)
        # Two independently driven fingers: a trajectory or forward command drives both (a GripperCommand
        # action's driver moves its fingers itself).
        followers = ((gripper.joints[1], float(gripper.mimic)),) if (
            gripper is not None and gripper.independent and interface in ("trajectory", "forward")) else ()
        return RealSceneOptions(
            gripper_interface=interface,
            gripper_controller=opts.pop("gripper_controller", real.gripper_controller),
            gripper_joint=opts.pop("gripper_joint", real.gripper_joint) or (gripper.joints[0] if gripper else ""),
            gripper_range=None if real_range is None else (float(real_range[0]), float(real_range[1])),
            gripper_max_effort=float(opts.pop("gripper_max_effort", 0.0)),
            gripper_followers=followers, object_pose_topic=topic,
            object_pose_frame=opts.pop("object_pose_frame", self.base_link),
            object_pose_timeout=float(timeout))
