"""The simulated side of the env core: its constructor knobs, a :class:`~multiros.envs.sim_connection.SimConnection`
built from them, and what only a simulated robot offers (frames, teleports, rendering, pickling).

:class:`MujocoBaseEnv <multiros.envs.base_env.MujocoBaseEnv>` and ``MujocoGoalEnv`` are this plus
their step template. The environment never touches MuJoCo: everything goes through the simulation
node, composed in this process (called directly) or over ROS 2.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from multiros.envs.config import SpawnPose, StepConfig, parse_reset_mode, parse_step_mode
from multiros.envs.core import EnvCore
from multiros.envs.errors import EnvError
from multiros.envs.knobs import SIM_KNOBS, sort_knobs
from multiros.envs.sim_connection import RobotModel, SimConnection
from multiros.sim.client import SimulationClient
from multiros.sim.launch import SimulationConnection

__all__ = ["MujocoEnvCore"]

_logger = logging.getLogger(__name__)


class MujocoEnvCore(EnvCore):
    """The env core on a simulation node (shared by :class:`MujocoBaseEnv` and :class:`MujocoGoalEnv`).

    Args:
        spawn_robot: spawn the robot described below when the env starts.
        robot_name: entity name of the robot in the simulation (MultiROS: ``robot_model_name``).
        robot_model_xml: a URDF, xacro or MJCF file path / ``package://`` URI, or the text itself.
        urdf_pkg_name, urdf_file_name, urdf_folder: MultiROS-style location of the description
            (``package://<pkg><folder>/<file>``), used when ``robot_model_xml`` is not given.
        urdf_xacro_args: xacro arguments, as a ``{"name": "value"}`` dict or ``["name:=value"]`` list.
        namespace: the robot's ROS namespace (controllers, ``joint_states``); default ``/<robot_name>``.
        robot_pos_x, robot_pos_y, robot_pos_z: spawn position in the world.
        robot_ori_w, robot_ori_x, robot_ori_y, robot_ori_z: spawn orientation; identity by default.
        controllers_file: a ros2_control controllers YAML (path or ``package://``) overriding the one
            the description names.
        controllers_list: controllers to activate (default: what the YAML configures).
        initial_joint_positions: ``{joint: position}`` the robot is spawned at, and put back at by a
            world reset (default: the description's ros2_control ``initial_value``, else zeros clamped
            into the limits): an arm whose zero pose reaches below its base spawns at its home.
        reset_controllers: restart the controllers on every reset.
        reset_mode: ``"world"`` (state only; sim time keeps running) or ``"simulation"`` (state and time).
        step_mode: ``"lockstep"`` (default), ``"pause_unpause"`` or ``"realtime"``; MultiROS' 1/2 accepted.
        num_sim_steps: physics steps per env step in lockstep mode (MultiROS: ``num_gazebo_steps``).
        action_cycle_time: seconds between acting and observing in the other step modes.
        sim_timestep: physics time step in seconds (``None`` keeps the node's).
        real_time_factor: real-time factor of the ``realtime`` mode (1.0 = wall clock, <= 0 = as fast
            as possible).
        floor_color: the floor's tiles in rendered images of a node this env starts, ``"light"``
            (default) or ``"dark"`` (a pale arm stands out on it in camera observations); no physics.
            ValueError with ``sim_mode="existing"`` (that node's floor is its own; ``uniros-sim
            --floor-color``). In a batched vector env the batch starts the nodes with it.
        frames: robot links or sites whose world poses each step returns (e.g. the end effector).
        sim_mode: ``"composed"`` (node in this process, the fast default), ``"process"`` (a child
            process over Zenoh) or ``"existing"`` (connect to a running node named ``sim_node_name``).
        sim_node_name: the simulation node's name.
        transport: ``"inproc"`` or ``"zenoh"`` (default: inproc when composed, zenoh otherwise).
        gui: open the MuJoCo viewer (composed or child-process node, when a display exists).
        seed: seed for the first reset only; later resets continue the same random stream.
        timeout_sec: bound on every call to the node.
        max_reset_attempts: how often a reset may retry reaching the initial pose.
        render_mode: ``None``, ``"rgb_array"``, ``"depth_array"`` or ``"human"``.
        render_camera: camera for rendering (a camera name in the world; empty = the default view).
        render_width, render_height: rendered image size.
        sim_connection: a :class:`~multiros.sim.launch.SimulationConnection` shared with other envs
            (a vector env's batch, see :mod:`multiros.envs.batch`): the env spawns its robot there,
            does not close the connection, and its reset puts back only its own robot and the
            objects spawned into its namespace, never the world.
        world_slot: offset ``(x, y, z)`` in metres of this env's slot in a shared world: the robot spawns
            at its spawn position plus the offset and frame positions are reported minus it, so the
            task sees the same numbers as alone in its own world.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array", "depth_array", "human"], "render_fps": 25}
    connection: SimConnection
    _ctor_args: tuple[tuple[Any, ...], dict[str, Any]]

    # -- pickling: an env is re-created from its constructor arguments, as Gymnasium's MuJoCo envs
    # (EzPickle) are; the copy has its own simulation node and starts from a fresh reset.
    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        self = super().__new__(cls)
        self._ctor_args = (args, dict(kwargs))
        return self

    def __getstate__(self) -> dict[str, Any]:
        args, kwargs = getattr(self, "_ctor_args", ((), {}))
        kwargs = dict(kwargs)
        if kwargs.get("sim_mode") == "existing" or kwargs.get("sim_connection") is not None:
            raise TypeError(
                f"{type(self).__name__} with sim_mode='existing' cannot be pickled or copied: a copy would spawn "
                "a second robot into the same running simulation node; create another env instead"
            )
        return {"_ctor_args": (args, kwargs)}

    def __setstate__(self, state: dict[str, Any]) -> None:
        # Built in place: what the env's parts hold of it (a task's env, a callback) is this object, not a
        # temporary one whose attributes were copied over.
        args, kwargs = state["_ctor_args"]
        self._ctor_args = (args, dict(kwargs))
        type(self).__init__(self, *args, **kwargs)

    def _init_core(
        self,
        *,
        spawn_robot: bool = True,
        robot_name: str = "robot",
        robot_model_xml: str | None = None,
        urdf_pkg_name: str | None = None,
        urdf_file_name: str | None = None,
        urdf_folder: str = "/urdf",
        urdf_xacro_args: Mapping[str, Any] | Sequence[str] | None = None,
        namespace: str | None = None,
        robot_pos_x: float = 0.0,
        robot_pos_y: float = 0.0,
        robot_pos_z: float = 0.0,
        robot_ori_w: float = 1.0,
        robot_ori_x: float = 0.0,
        robot_ori_y: float = 0.0,
        robot_ori_z: float = 0.0,
        controllers_file: str | None = None,
        controllers_list: Sequence[str] | None = None,
        initial_joint_positions: Mapping[str, float] | None = None,
        reset_controllers: bool = False,
        reset_mode: Any = "world",
        step_mode: Any = "lockstep",
        num_sim_steps: int = 20,
        action_cycle_time: float = 0.0,
        sim_timestep: float | None = None,
        real_time_factor: float | None = None,
        floor_color: str | None = None,
        frames: Sequence[str] = (),
        sim_mode: str = "composed",
        sim_node_name: str = "mujoco_sim",
        transport: str | None = None,
        gui: bool = False,
        seed: int | None = None,
        timeout_sec: float = 10.0,
        max_reset_attempts: int = 3,
        render_mode: str | None = None,
        render_camera: str = "",
        render_width: int = 480,
        render_height: int = 480,
        sim_connection: SimulationConnection | None = None,
        world_slot: Sequence[float] = (0.0, 0.0, 0.0),
        **legacy: Any,
    ) -> None:
        given = {k: v for k, v in locals().items() if k not in ("self", "legacy", "__class__")}
        k = sort_knobs(SIM_KNOBS, type(self).__name__, given, legacy)
        self.info = {}
        self._pending_seed = k["seed"]
        if k["render_mode"] is not None and k["render_mode"] not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {k['render_mode']!r} is not one of {self.metadata['render_modes']}")
        self.render_mode = k["render_mode"]
        self._render_options = (k["render_camera"], int(k["render_width"]), int(k["render_height"]))
        self.robot_name: str = k["robot_name"]
        ns = k["namespace"]
        namespace = ("/" + self.robot_name) if ns in (None, "", "/") else "/" + ns.strip("/")
        self.spawn_pose = SpawnPose(
            (k["robot_pos_x"], k["robot_pos_y"], k["robot_pos_z"]),
            (k["robot_ori_w"], k["robot_ori_x"], k["robot_ori_y"], k["robot_ori_z"]),
        )
        self.step_config = StepConfig(parse_step_mode(k["step_mode"]), int(k["num_sim_steps"]),
                                      float(k["action_cycle_time"]))
        self.reset_mode = parse_reset_mode(k["reset_mode"])
        model = RobotModel(k["robot_model_xml"], k["urdf_pkg_name"], k["urdf_file_name"], k["urdf_folder"],
                           k["urdf_xacro_args"], k["controllers_file"],
                           k["initial_joint_positions"]) if k["spawn_robot"] else None
        self.connection = SimConnection(
            robot_name=self.robot_name, namespace=namespace, model=model, spawn_pose=self.spawn_pose,
            step_config=self.step_config, reset_mode=self.reset_mode, controllers_list=k["controllers_list"] or [],
            reset_controllers=k["reset_controllers"], frames=k["frames"], sim_mode=k["sim_mode"],
            sim_node_name=k["sim_node_name"], transport=k["transport"], gui=k["gui"],
            sim_timestep=k["sim_timestep"], real_time_factor=k["real_time_factor"], timeout_sec=k["timeout_sec"],
            max_reset_attempts=k["max_reset_attempts"], shared=k["sim_connection"], world_slot=k["world_slot"],
            floor_color=k["floor_color"])
        self.robot_name = self.connection.robot_name  # the node may have renamed it

    # -- what the robot's connection holds, by its documented names ---------------------------
    @property
    def sim(self) -> SimulationClient:
        """The simulation node's client (every ``simulation_interfaces`` service and more)."""
        return self.connection.sim

    @property
    def node(self) -> Any:
        """This env's ROS node (goal markers, extra topics)."""
        return self.connection.node

    @property
    def sim_connection(self) -> SimulationConnection:
        """The link to the simulation node: its context, the composed node or the child process (``pid``)."""
        return self.connection.link

    @property
    def namespace(self) -> str:
        return self.connection.namespace

    @property
    def frames(self) -> tuple[str, ...]:
        """The frames whose poses each step returns."""
        return self.connection.frames

    @property
    def controllers_list(self) -> list[str]:
        return self.connection.controllers_list

    @property
    def reset_controllers(self) -> bool:
        return self.connection.reset_controllers

    @property
    def timeout_sec(self) -> float:
        return self.connection.timeout_sec

    @property
    def max_reset_attempts(self) -> int:
        return self.connection.max_reset_attempts

    @property
    def world_slot(self) -> np.ndarray:
        """This env's offset in a shared world (zeros alone in its world)."""
        return self.connection.world_slot

    @property
    def shared_world(self) -> bool:
        """Whether the env's robot shares its simulation node with other envs' (a vector env's batch)."""
        return self.connection.shared

    def frame_position(self, frame: str) -> np.ndarray:
        """World position of a frame listed in ``frames``."""
        return self.connection.state.frame_positions[self.connection.frame_index(frame)].copy()

    def frame_orientation(self, frame: str) -> np.ndarray:
        """World orientation ``(w, x, y, z)`` of a frame listed in ``frames``."""
        return self.connection.state.frame_orientations[self.connection.frame_index(frame)].copy()

    @property
    def sim_time(self) -> float:
        """Simulation time in seconds after the last step."""
        return self.connection.state.sim_time

    def set_joint_positions(self, names: Sequence[str], positions: npt.ArrayLike, hold: bool = True) -> None:
        """Teleport joints (e.g. to the episode's initial pose); ``hold`` keeps them there."""
        self.connection.set_joint_positions(names, positions, hold)

    def _refresh_state(self, steps: int = 0) -> None:
        """One round trip for this robot: its queued commands, ``steps`` physics steps, a fresh state."""
        self.note_step_status(self.connection.refresh(steps))

    # -- rendering ------------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        """An image of the scene (``rgb_array``: HxWx3 uint8; ``depth_array``: HxW float32 metres)."""
        if self.render_mode is None:
            return None
        camera, width, height = self._render_options
        if self.render_mode == "human":
            from multiros.sim.render import display_available

            if not display_available():
                raise EnvError('render_mode="human" opens the MuJoCo viewer and needs a display (DISPLAY or '
                               'WAYLAND_DISPLAY is not set); use render_mode="rgb_array" for images without one')
            self.connection.show_viewer()
            return None
        return self.connection.render(camera, width, height, depth=self.render_mode == "depth_array")
