"""Arm files: one YAML per arm that says everything its tasks need (``format: 1``).

An arm file names the robot's description (a ``package://`` URI found through ``AMENT_PREFIX_PATH``
or the shipped packages, or a path relative to the file) and what the tasks cannot work out from
it: which joints are the arm, where the end effector is, the gripper, a home pose, the workspace,
the task settings and the real driver's names. :mod:`rl_environments.arm_registry` turns a loaded
file into gymnasium IDs; ``uniros arm add`` writes one from a description
(:mod:`rl_environments.arm_inspect`). The shipped arms are arm files too (``config/arms/``).

The layout (``docs/add_your_arm.md`` explains every key)::

    format: 1
    name: UR5e                  # ID prefix: UR5eReacherSim-v0, ...
    robot_name: ur5e            # entity name and ROS namespace in simulation
    description:
      uri: package://ur5e_description/urdf/ur5e.urdf.xacro
      xacro_args: {}
      controllers: package://ur5e_description/config/ur5e_controllers.yaml
    arm:
      joints: [...]             # base to tip
      base_link: base_link
      ee_link: grasp_link
      tcp_offset: [0, 0, 0]     # the grasp point in ee_link's frame, metres (when no link lies between the pads)
      home: [...]
      controller: forward_position_controller
      controllers: [joint_state_broadcaster, forward_position_controller, gripper_position_controller]
      approach_axis: z          # the EE frame's axis out of the gripper
      closing_axis: x           # the EE frame's axis the fingers close along
      ik_seed: [...]            # a top-down pose to start the top-down IK from (default: home)
      top_down_ik: {solver: numeric}   # or planar_wrist with its lengths (the RX200)
    gripper:                    # or null: reach only
      joints: [left_finger_joint, right_finger_joint]
      mimic: -1.0
      closed: 0.0
      open: 0.0425
      controller: gripper_position_controller
      independent: false        # true: both joints driven (no <mimic>), the second commanded at mimic x the first
    camera: {render_camera: render_camera, view: {lookat: [...], distance: .., azimuth: .., elevation: ..}}
    #        (and defaults: {camera_name: .., rgb_plus_depth_plus_normal_obs: true}: camera keywords by default)
    reach: {...}                # rl_environments.task_config.reach_schema's keys (arm_joints left out)
    manipulation: {...}         # task_config.manipulation_schema's keys and the scene's
    scene: {table: URI, object: URI}   # the push / pick-and-place MJCF files (default: made from the scene's sizes)
    real: {namespace: ..., arm_controller: ..., ...}
    training: {ReacherGoal: {...}}     # overrides of the derived training configs, per task

A variant of an arm (another camera, xacro arguments) is a file that says ``extends: <arm file>`` (a path
relative to it) and the keys it changes: mappings merge key by key, anything else is replaced
(``config/arms/rx200_zed2.yaml``: the RX200 observed through its Zed2).

Validation is strict: an unknown key names the nearest valid one, a wrong type names the key and
what it must be, a newer ``format`` says to upgrade. Nothing is registered from a file that fails.
"""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from multiros.excerpt import MAX_MESSAGE_LINE, excerpt
from rl_environments.arm_file_yaml import ArmFileError, read_arm_yaml, resolve_uri

__all__ = ["ARM_FILE_FORMAT", "ArmFile", "ArmFileError", "GripperSpec", "RealSpec", "load_arm_file", "parse_arm_file"]

#: The newest arm file format this uniros reads.
ARM_FILE_FORMAT = 1
_AXES = ("x", "y", "z")
#: The tasks an arm file may override training settings of (keys of ``training:``).
TASK_NAMES = ("Reacher", "ReacherGoal", "Push", "PushGoal", "PnP", "PnPGoal")
_GRIPPER_INTERFACES = ("forward", "trajectory", "gripper_action", "none", "niryo_tool")


@dataclass(frozen=True)
class GripperSpec:
    """A parallel gripper: the commanded finger joint first, the mimicking one second."""

    joints: tuple[str, ...]
    mimic: float
    closed: float
    open: float
    controller: str
    reset_mimic: bool = True
    #: Both finger joints are driven (the description ties them by no ``<mimic>``): the simulation's
    #: gripper controller and the real driver's take both, the second at ``mimic`` times the first.
    independent: bool = False


@dataclass(frozen=True)
class RealSpec:
    """The real robot's driver: names of its namespace, controllers and interfaces, and the safety box."""

    namespace: str
    arm_controller: str
    controllers: tuple[str, ...] = ()
    command_interface: str = "topic"
    check_controllers: bool = True
    joint_states_topic: str | None = None
    gripper_controller: str = "gripper_controller"
    gripper_interface: str = "forward"
    gripper_joint: str | None = None
    gripper_range: tuple[float, float] | None = None
    workspace_min: tuple[float, float, float] = (-1.0, -1.0, 0.0)
    workspace_max: tuple[float, float, float] = (1.0, 1.0, 1.2)
    floor_z: float = 0.02
    max_joint_delta: float = 0.15
    #: rad: how close a reset's move must bring every arm joint to its initial pose.
    reset_tolerance: float = 0.02
    #: rad: a move that stopped short (a servo drooping under load) is accepted once still within this.
    reset_settle_tolerance: float = 0.05


@dataclass(frozen=True)
class ArmDynamics:
    """How the arm's joints follow position commands (``dynamics:``; ``uniros sysid`` writes it from a bag).

    The model, per arm joint: ``time_constant * dy/dt = gain * u(t - latency) + offset - y``, and a joint
    settles ``droop`` short of that target on the side it came from (a stiff servo under load). The
    simulation applies it to the arm's commands (:mod:`rl_environments.randomization` draws around it).
    Lists are in ``arm.joints`` order.
    """

    latency: float = 0.0
    time_constant: tuple[float, ...] = ()
    gain: tuple[float, ...] = ()
    offset: tuple[float, ...] = ()
    droop: tuple[float, ...] = ()
    fit_residual: float | None = None
    source: str = ""

    @property
    def nominal(self) -> bool:
        """The joints follow commands exactly (no section, or one that says so)."""
        return (self.latency == 0 and not any(self.time_constant) and all(g == 1 for g in self.gain)
                and not any(self.offset) and not any(self.droop))


@dataclass(frozen=True)
class ArmFile:
    """A checked arm file (see the module docstring); URIs relative to the file are made absolute."""

    path: Path
    name: str
    robot_name: str
    description_uri: str
    xacro_args: Mapping[str, str]
    controllers_file: str
    joints: tuple[str, ...]
    base_link: str
    ee_link: str
    home: tuple[float, ...]
    arm_controller: str
    sim_controllers: tuple[str, ...]
    approach_axis: str
    closing_axis: str
    ik_seed: tuple[float, ...]
    top_down_ik: Mapping[str, Any]
    gripper: GripperSpec | None
    render_camera: str
    camera_view: tuple[tuple[float, float, float], float, float, float]
    camera_topics: Mapping[str, tuple[str, str]]
    reach: Mapping[str, Any]
    manipulation: Mapping[str, Any] | None
    scene_files: Mapping[str, str]
    real: RealSpec
    training: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    #: The end effector: this point of ``ee_link`` (metres, in its frame); zeros: the link's origin.
    tcp_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Camera keywords the arm's envs take by default (:mod:`rl_environments.camera_obs`: a camera it
    #: observes through, the observation's mode).
    camera_defaults: Mapping[str, Any] = field(default_factory=dict)
    #: How the joints follow commands (``dynamics:``); nominal when the file has none.
    dynamics: ArmDynamics = field(default_factory=ArmDynamics)

    @property
    def has_gripper(self) -> bool:
        return self.gripper is not None

    @property
    def scene(self) -> dict[str, Any]:
        """The push / pick-and-place scene's keys (empty without a gripper)."""
        return dict(self.manipulation or {})


# -- checking --------------------------------------------------------------------------------------
class _Checker:
    """Typed reads of one mapping of the file, with the key's dotted path in every message."""

    def __init__(self, source: Path, data: Any, where: str, keys: Sequence[str]) -> None:
        self.source, self.where = source, where
        if not isinstance(data, dict):
            self.fail(where or "the file", f"must be a mapping of keys, got {type(data).__name__}")
        self.data: dict[str, Any] = data
        unknown = [k for k in data if k not in keys]
        if unknown:
            key = unknown[0]
            close = difflib.get_close_matches(str(key), list(keys), n=1, cutoff=0.6)
            hint = f"did you mean {close[0]!r}?" if close else f"valid keys: {', '.join(keys)}"
            self.fail(self.path(str(key)), f"is not a key of {where or 'an arm file'}; {hint}")

    def path(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def fail(self, key: str, message: str) -> None:
        raise ArmFileError(excerpt(f"{self.source}: key {key!r} {message}", MAX_MESSAGE_LINE))

    def has(self, key: str) -> bool:
        return self.data.get(key) is not None

    def raw(self, key: str, default: Any = ...) -> Any:
        if key not in self.data or self.data[key] is None:
            if default is ...:
                self.fail(self.path(key), "is missing")
            return default
        return self.data[key]

    def string(self, key: str, default: Any = ..., *, empty: bool = False) -> Any:
        value = self.raw(key, default)
        if value is default and default is not ...:
            return value
        if not isinstance(value, str) or (not empty and not value.strip()):
            self.fail(self.path(key), f"must be a {'' if empty else 'non-empty '}string, got {value!r}")
        return value

    def number(self, key: str, default: Any = ...) -> Any:
        value = self.raw(key, default)
        if value is default and default is not ...:
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            self.fail(self.path(key), f"must be a finite number, got {value!r}")
        return float(value)

    def boolean(self, key: str, default: Any = ...) -> Any:
        value = self.raw(key, default)
        if not isinstance(value, bool):
            self.fail(self.path(key), f"must be true or false, got {value!r}")
        return value

    def numbers(self, key: str, length: int | None, default: Any = ...) -> Any:
        value = self.raw(key, default)
        if value is default and default is not ...:
            return value
        ok = isinstance(value, (list, tuple)) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
        if not ok or (length is not None and len(value) != length):
            size = f"{length} " if length is not None else ""
            self.fail(self.path(key), f"must be a list of {size}finite numbers, got {value!r}")
        return tuple(float(v) for v in value)

    def strings(self, key: str, default: Any = ...) -> Any:
        value = self.raw(key, default)
        if value is default and default is not ...:
            return value
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) and v for v in value):
            self.fail(self.path(key), f"must be a list of names, got {value!r}")
        if len(set(value)) != len(value):
            self.fail(self.path(key), f"names a joint or controller twice: {list(value)}")
        return tuple(value)

    def axis(self, key: str) -> str:
        value = self.string(key)
        if value not in _AXES:
            self.fail(self.path(key), f"must be one of x, y, z (an axis of the end-effector frame), got {value!r}")
        return str(value)

    def sub(self, key: str, keys: Sequence[str], default: Any = ...) -> _Checker | None:
        value = self.raw(key, default)
        if value is None:
            return None
        return _Checker(self.source, value, self.path(key), keys)


_TOP = ("format", "name", "robot_name", "description", "arm", "gripper", "camera", "reach", "manipulation", "scene",
        "real", "training", "dynamics")
_DYNAMICS = ("latency", "time_constant", "gain", "offset", "droop", "fit_residual", "source")
#: Bounds of a ``dynamics:`` value a robot can have: seconds of latency and lag, gain, rad of offset.
_DYNAMICS_BOUNDS = {"latency": (0.0, 2.0), "time_constant": (0.0, 5.0), "gain": (0.5, 1.5), "offset": (-0.2, 0.2),
                    "droop": (0.0, 0.2)}
_DESCRIPTION = ("uri", "xacro_args", "controllers")
_ARM = ("joints", "base_link", "ee_link", "tcp_offset", "home", "controller", "controllers", "approach_axis",
        "closing_axis", "ik_seed", "top_down_ik")
_IK = ("solver", "shoulder_height", "upper_arm", "forearm", "tip")
_GRIPPER = ("joints", "mimic", "closed", "open", "controller", "reset_mimic", "independent")
_MAX_JOINT_DELTA = 1.0  # rad: a per-command joint change above this is no safety cap
_MAX_TCP_OFFSET = 0.5  # m: a tool centre point further from its link is a mistake (units, a wrong link)
_CAMERA = ("render_camera", "view", "topics", "defaults")
_VIEW = ("lookat", "distance", "azimuth", "elevation")
_SCENE_FILES = ("table", "object")
_REAL = ("namespace", "arm_controller", "controllers", "command_interface", "check_controllers", "joint_states_topic",
         "gripper_controller", "gripper_interface", "gripper_joint", "gripper_range", "workspace_min",
         "workspace_max", "floor_z", "max_joint_delta", "reset_tolerance", "reset_settle_tolerance")


def _task_section(top: _Checker, key: str, schema: Mapping[str, Any], defaults: Mapping[str, Any]) -> dict[str, Any]:
    """A task section checked against its schema (the task modules' own), the arm's joints filled in."""
    from rl_environments.task_config import TaskConfigError, check_task_config

    data = top.raw(key)
    if not isinstance(data, dict):
        top.fail(key, f"must be a mapping of the task's settings, got {type(data).__name__}")
    extra = [k for k in data if k not in schema and k not in defaults]
    if extra:
        close = difflib.get_close_matches(str(extra[0]), list(schema), n=1, cutoff=0.6)
        hint = f"did you mean {close[0]!r}?" if close else f"valid keys: {', '.join(schema)}"
        top.fail(f"{key}.{extra[0]}", f"is not a setting of the {key} task; {hint}")
    try:
        return check_task_config(data, schema, source=f"{top.source}: {key}", defaults=defaults)
    except TaskConfigError as exc:
        raise ArmFileError(str(exc)) from None


def parse_arm_file(data: Any, source: Path) -> ArmFile:
    """Check an arm file's parsed YAML (``source`` names it in errors and anchors relative paths)."""
    from rl_environments.task_config import SCENE_KEYS, manipulation_schema, reach_schema

    base = source.resolve().parent
    top = _Checker(source, data, "", _TOP)
    fmt = top.raw("format")
    if isinstance(fmt, bool) or not isinstance(fmt, int) or fmt < 1:
        top.fail("format", f"must be a positive integer (this uniros reads format {ARM_FILE_FORMAT}), got {fmt!r}")
    if fmt > ARM_FILE_FORMAT:
        top.fail("format", f"is {fmt}, newer than this uniros reads ({ARM_FILE_FORMAT}): upgrade uniros")
    name = top.string("name")
    if not name.replace("_", "").isalnum() or not name[0].isalpha():
        top.fail("name", f"must be letters and digits starting with a letter (it prefixes the IDs), got {name!r}")
    robot_name = top.string("robot_name", name.lower())
    if not robot_name.replace("_", "").isalnum():
        top.fail("robot_name", f"must be a ROS name (letters, digits, _), got {robot_name!r}")

    desc = top.sub("description", _DESCRIPTION)
    assert desc is not None
    uri = resolve_uri(desc.string("uri"), base)
    xacro_args = desc.raw("xacro_args", {})
    if not isinstance(xacro_args, dict) or not all(isinstance(k, str) for k in xacro_args):
        desc.fail(desc.path("xacro_args"), f"must be a mapping of argument names to values, got {xacro_args!r}")
    xacro = {k: str(v).lower() if isinstance(v, bool) else str(v) for k, v in xacro_args.items()}
    controllers_file = resolve_uri(desc.string("controllers"), base)

    arm = top.sub("arm", _ARM)
    assert arm is not None
    joints = arm.strings("joints")
    if not 4 <= len(joints) <= 7:
        arm.fail("arm.joints", f"names {len(joints)} joints; the tasks serve serial arms of 4 to 7 joints")
    n = len(joints)
    home = arm.numbers("home", n)
    tcp_offset = arm.numbers("tcp_offset", 3, (0.0, 0.0, 0.0))
    if max(abs(v) for v in tcp_offset) > _MAX_TCP_OFFSET:
        arm.fail("arm.tcp_offset", f"is {list(tcp_offset)}: a point more than {_MAX_TCP_OFFSET} m from "
                                   "arm.ee_link along an axis; it is in metres, in ee_link's frame")
    approach, closing = arm.axis("approach_axis"), arm.axis("closing_axis")
    if approach == closing:
        arm.fail("arm.closing_axis", f"must differ from approach_axis ({approach})")
    ik_sec = arm.sub("top_down_ik", _IK, {})
    assert ik_sec is not None
    solver = ik_sec.string("solver", "numeric")
    top_down: dict[str, Any] = {"solver": solver}
    if solver == "planar_wrist":
        if n != 5:
            ik_sec.fail("arm.top_down_ik.solver", f"planar_wrist serves 5 joints, the arm has {n}")
        top_down.update(shoulder_height=ik_sec.number("shoulder_height"), upper_arm=ik_sec.numbers("upper_arm", 2),
                        forearm=ik_sec.number("forearm"), tip=ik_sec.number("tip"))
    elif solver != "numeric":
        ik_sec.fail("arm.top_down_ik.solver", f"must be 'numeric' (any chain) or 'planar_wrist', got {solver!r}")
    sim_controllers = arm.strings("controllers")
    arm_controller = arm.string("controller")
    if arm_controller not in sim_controllers:
        arm.fail("arm.controller", f"{arm_controller!r} is not among arm.controllers {list(sim_controllers)}")

    gsec = top.sub("gripper", _GRIPPER, None)
    gripper = None
    if gsec is not None:
        gjoints = gsec.strings("joints")
        if not 1 <= len(gjoints) <= 2:
            gsec.fail("gripper.joints", f"must name the commanded finger joint and at most one mimicking it, "
                                        f"got {list(gjoints)}")
        overlap = sorted(set(gjoints) & set(joints))
        if overlap:
            gsec.fail("gripper.joints", f"names arm joints {overlap}")
        gripper = GripperSpec(gjoints, gsec.number("mimic", 1.0), gsec.number("closed"), gsec.number("open"),
                              gsec.string("controller"), gsec.boolean("reset_mimic", True),
                              gsec.boolean("independent", False))
        if gripper.independent and len(gjoints) != 2:
            gsec.fail("gripper.independent", f"is true but gripper.joints names {len(gjoints)} joint(s): it takes "
                                             "the two driven finger joints")
        if gripper.controller not in sim_controllers:
            gsec.fail("gripper.controller", f"{gripper.controller!r} is not among arm.controllers "
                                            f"{list(sim_controllers)}")
        if gripper.closed == gripper.open:
            gsec.fail("gripper.open", "must differ from gripper.closed")

    cam = top.sub("camera", _CAMERA, {})
    assert cam is not None
    render_camera = cam.string("render_camera", "", empty=True)
    view_sec = cam.sub("view", _VIEW, {})
    assert view_sec is not None
    camera_view = (view_sec.numbers("lookat", 3, (0.2, 0.0, 0.1)), view_sec.number("distance", 0.9),
                   view_sec.number("azimuth", 140.0), view_sec.number("elevation", -25.0))
    topics = cam.raw("topics", {})
    pairs = topics.values() if isinstance(topics, dict) else ()
    if not isinstance(topics, dict) or not all(
            isinstance(v, (list, tuple)) and len(v) == 2 and all(isinstance(t, str) for t in v) for v in pairs):
        cam.fail("camera.topics", f"must map a camera name to its [rgb, depth] topics, got {topics!r}")
    camera_defaults = cam.raw("defaults", {})
    from rl_environments.camera_obs import CAMERA_KEYWORDS

    if not isinstance(camera_defaults, dict) or not all(
            isinstance(v, (bool, int, str)) or (isinstance(v, float) and math.isfinite(v))
            for v in camera_defaults.values()):
        cam.fail("camera.defaults", f"must map camera keywords to values, got {camera_defaults!r}")
    unknown = [k for k in camera_defaults if k not in CAMERA_KEYWORDS]
    if unknown:
        close = difflib.get_close_matches(str(unknown[0]), CAMERA_KEYWORDS, n=1, cutoff=0.6)
        hint = f"did you mean {close[0]!r}?" if close else f"camera keywords: {', '.join(CAMERA_KEYWORDS)}"
        cam.fail(f"camera.defaults.{unknown[0]}", f"is not a camera keyword; {hint}")

    reach = _task_section(top, "reach", {k: v for k, v in reach_schema(n).items() if k != "arm_joints"}, {})
    reach["arm_joints"] = list(joints)
    manipulation = None
    scene_files: dict[str, str] = {}
    if gripper is not None:
        if not top.has("manipulation"):
            top.fail("manipulation", "is missing: an arm with a gripper needs push and pick-and-place settings "
                                     "(or gripper: null for reach only)")
        schema = {k: v for k, v in manipulation_schema(n).items() if k != "arm_joints"}
        manipulation = _task_section(top, "manipulation", schema, {"table_half_extents": None, "object_mass": None})
        manipulation["arm_joints"] = list(joints)
        files = top.sub("scene", _SCENE_FILES, {})
        assert files is not None
        scene_files = {k: resolve_uri(files.string(k), base) for k in _SCENE_FILES if files.has(k)}
        # The table and the cube are made from the scene's sizes unless the file names their MJCF.
        sizes = _Checker(source, manipulation, "manipulation", list(manipulation))
        if "table" not in scene_files:
            manipulation["table_half_extents"] = sizes.numbers("table_half_extents", 3)
        if "object" not in scene_files:
            manipulation["object_mass"] = sizes.number("object_mass")
        missing = [k for k in SCENE_KEYS if k not in manipulation]
        if missing:
            top.fail(f"manipulation.{missing[0]}", "is missing")
    elif top.has("manipulation"):
        top.fail("manipulation", "is given but the arm has no gripper (gripper: null): remove it or add the gripper")

    real_sec = top.sub("real", _REAL)
    assert real_sec is not None
    interface = real_sec.string("gripper_interface", "forward")
    if interface not in _GRIPPER_INTERFACES:
        real_sec.fail("real.gripper_interface", f"must be one of {list(_GRIPPER_INTERFACES)}, got {interface!r}")
    command = real_sec.string("command_interface", "topic")
    if command not in ("topic", "action"):
        real_sec.fail("real.command_interface", f"must be 'topic' or 'action', got {command!r}")
    grange = real_sec.numbers("gripper_range", 2, None)
    real = RealSpec(
        namespace=real_sec.string("namespace", "", empty=True),
        arm_controller=real_sec.string("arm_controller"),
        controllers=real_sec.strings("controllers", ()),
        command_interface=command,
        check_controllers=real_sec.boolean("check_controllers", True),
        joint_states_topic=real_sec.string("joint_states_topic", None),
        gripper_controller=real_sec.string("gripper_controller", "gripper_controller", empty=True),
        gripper_interface=interface,
        gripper_joint=real_sec.string("gripper_joint", None),
        gripper_range=None if grange is None else (grange[0], grange[1]),
        workspace_min=real_sec.numbers("workspace_min", 3, (-1.0, -1.0, 0.0)),
        workspace_max=real_sec.numbers("workspace_max", 3, (1.0, 1.0, 1.2)),
        floor_z=real_sec.number("floor_z", 0.02),
        max_joint_delta=real_sec.number("max_joint_delta", 0.15),
        reset_tolerance=real_sec.number("reset_tolerance", 0.02),
        reset_settle_tolerance=real_sec.number("reset_settle_tolerance", 0.05),
    )
    if not 0 < real.reset_tolerance <= 0.5:
        real_sec.fail("real.reset_tolerance", f"is {real.reset_tolerance:g} rad: it must be in (0, 0.5]")
    if not 0 <= real.reset_settle_tolerance <= 0.5:
        real_sec.fail("real.reset_settle_tolerance", f"is {real.reset_settle_tolerance:g} rad: it must be in "
                                                     "[0, 0.5] (0: only reset_tolerance)")
    if not 0 < real.max_joint_delta <= _MAX_JOINT_DELTA:  # the robot's per-command safety cap
        real_sec.fail("real.max_joint_delta", f"is {real.max_joint_delta:g} rad: the largest joint change one "
                                              f"command may ask of the robot must be in (0, {_MAX_JOINT_DELTA:g}]")
    inverted = [i for i in range(3) if real.workspace_min[i] > real.workspace_max[i]]
    if inverted:
        real_sec.fail("real.workspace_min", f"is above real.workspace_max at index {inverted[0]}: the safety box "
                                            "is inverted")

    training = top.raw("training", {})
    if not isinstance(training, dict):
        top.fail("training", f"must map a task ({', '.join(TASK_NAMES)}) to training settings, got {training!r}")
    for task, settings in training.items():
        if task not in TASK_NAMES:
            close = difflib.get_close_matches(str(task), TASK_NAMES, n=1, cutoff=0.5)
            hint = f"did you mean {close[0]!r}?" if close else f"tasks: {', '.join(TASK_NAMES)}"
            top.fail(f"training.{task}", f"is not a task; {hint}")
        if not isinstance(settings, dict):
            top.fail(f"training.{task}", f"must be a mapping of training config keys, got {settings!r}")

    dynamics = _dynamics(top, n)

    return ArmFile(
        path=source.resolve(), name=name, robot_name=robot_name, description_uri=uri, xacro_args=xacro,
        controllers_file=controllers_file, joints=joints, base_link=arm.string("base_link"),
        ee_link=arm.string("ee_link"), home=home, arm_controller=arm_controller, sim_controllers=sim_controllers,
        approach_axis=approach, closing_axis=closing, ik_seed=arm.numbers("ik_seed", n, home), top_down_ik=top_down,
        gripper=gripper,
        render_camera=render_camera, camera_view=camera_view,
        camera_topics={k: (v[0], v[1]) for k, v in topics.items()},
        reach=reach, manipulation=manipulation, scene_files=scene_files, real=real,
        training={str(k): dict(v) for k, v in training.items()},
        tcp_offset=(tcp_offset[0], tcp_offset[1], tcp_offset[2]), camera_defaults=dict(camera_defaults),
        dynamics=dynamics,
    )


def _dynamics(top: _Checker, n: int) -> ArmDynamics:
    """The ``dynamics:`` section checked: a number or ``n`` numbers per joint key, within a robot's bounds."""
    sec = top.sub("dynamics", _DYNAMICS, {})
    assert sec is not None
    if not sec.data:
        return ArmDynamics()
    defaults = {"time_constant": 0.0, "gain": 1.0, "offset": 0.0, "droop": 0.0}

    def per_joint(key: str) -> tuple[float, ...]:
        value = sec.raw(key, defaults[key])
        values = sec.numbers(key, n) if isinstance(value, list) else (sec.number(key, defaults[key]),) * n
        lo, hi = _DYNAMICS_BOUNDS[key]
        bad = [v for v in values if not lo <= v <= hi]
        if bad:
            sec.fail(f"dynamics.{key}", f"has {bad[0]:g}, outside [{lo:g}, {hi:g}]")
        return tuple(float(v) for v in values)

    latency = sec.number("latency", 0.0)
    if not _DYNAMICS_BOUNDS["latency"][0] <= latency <= _DYNAMICS_BOUNDS["latency"][1]:
        sec.fail("dynamics.latency", f"is {latency:g} s, outside [0, {_DYNAMICS_BOUNDS['latency'][1]:g}]")
    residual = sec.number("fit_residual", None)
    source = sec.string("source", "", empty=True)
    return ArmDynamics(latency=float(latency), time_constant=per_joint("time_constant"), gain=per_joint("gain"),
                       offset=per_joint("offset"), droop=per_joint("droop"),
                       fit_residual=None if residual is None else float(residual),
                       source=source[:200])


def load_arm_file(path: str | os.PathLike[str]) -> ArmFile:
    """Read and check an arm file.

    Raises:
        ArmFileError: the file is missing, not YAML, or a key is unknown, missing or mistyped.
    """
    source = Path(path).expanduser()
    return parse_arm_file(read_arm_yaml(source), source)
