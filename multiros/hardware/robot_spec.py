"""What a fake robot needs to know about its robot: joints, limits, initial positions, controllers.

Read from a robot description (URDF or xacro, a file or a ``package://`` URI) and a ros2_control
controllers YAML, as a real ros2_control robot reads them at start-up. The joints are those of the
description's ``<ros2_control>`` block (all movable joints when there is none), plus a joint that
``<mimic>`` joints follow when the block leaves it out (a gripper's drive); joints with a
``<mimic>`` follow their leader. Presets name the robots shipped with uniros, with the ROS namespace
and controller names of their vendors' ROS 2 drivers.

The description is the user's own input (a command-line argument), so xacro runs on it as it would
in ``ros2 launch``; nothing here arrives over the wire.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl

from multiros.bounded_yaml import YamlBoundsError, read_yaml_bounded
from multiros.sim.errors import DescriptionError
from multiros.sim.packages import PackageIndex, default_index
from multiros.sim.urdf_model import parse_urdf
from multiros.sim.xacro_runner import xacro_to_urdf

__all__ = ["JointSpec", "MimicSpec", "RobotSpec", "Preset", "PRESETS", "load_robot_spec", "rename_controllers"]


@dataclass(frozen=True)
class JointSpec:
    """One commandable joint: position limits (+-inf when unlimited), velocity limit (0 = none)."""

    name: str
    lower: float
    upper: float
    velocity: float
    initial: float


@dataclass(frozen=True)
class MimicSpec:
    """A joint that follows ``leader``: ``multiplier * leader + offset``, clamped to its limits."""

    name: str
    leader: str
    multiplier: float
    offset: float
    lower: float
    upper: float


@dataclass
class RobotSpec:
    """A robot as the fake driver runs it."""

    name: str
    namespace: str
    joints: list[JointSpec]
    mimics: list[MimicSpec] = field(default_factory=list)
    #: Parsed ros2_control YAML (controller names already renamed).
    controllers: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    #: The commanded arm joints, in the arm's order (empty: see :attr:`arm`).
    arm_joints: list[str] = field(default_factory=list)

    @property
    def published_joints(self) -> list[str]:
        """Names in ``joint_states`` order: commandable joints, then mimic joints."""
        return [j.name for j in self.joints] + [m.name for m in self.mimics]

    @property
    def arm(self) -> list[str]:
        """The commanded arm joints: :attr:`arm_joints` when set, else the joints of the controllers YAML's
        first JointTrajectoryController (file order), else every commandable joint."""
        if self.arm_joints:
            return list(self.arm_joints)
        cm = (self.controllers.get("controller_manager") or {}).get("ros__parameters") or {}
        for name, entry in cm.items():
            if isinstance(entry, Mapping) and str(entry.get("type", "")).endswith("/JointTrajectoryController"):
                joints = ((self.controllers.get(name) or {}).get("ros__parameters") or {}).get("joints")
                if isinstance(joints, list) and joints:
                    return [str(j) for j in joints]
        return [j.name for j in self.joints]


@dataclass(frozen=True)
class Preset:
    """A shipped robot with its vendor driver's ROS names."""

    description: str
    namespace: str
    controllers_file: str
    renames: Mapping[str, str] = field(default_factory=dict)


#: ``--robot`` presets. RX200: Interbotix' ROS 2 driver runs in the robot's namespace with
#: ``arm_controller`` and ``gripper_controller``. IRB120: ABB's ros2_control driver (abb_ros2) runs
#: un-namespaced with ``joint_trajectory_controller``; our YAML calls it ``arm120_controller``.
PRESETS: dict[str, Preset] = {
    "rx200": Preset(
        description="package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200",
        namespace="/rx200",
        controllers_file="package://rx200_description/config/rx200_controllers.yaml",
    ),
    "irb120": Preset(
        description="package://abb_irb120_description/urdf/irb120.urdf.xacro",
        namespace="",
        controllers_file="package://abb_irb120_description/config/irb120_controllers.yaml",
        renames={"arm120_controller": "joint_trajectory_controller"},
    ),
}


def _split_uri(location: str) -> tuple[str, dict[str, str]]:
    """``path?arg=value&...`` -> (path, xacro args)."""
    path, _, query = location.partition("?")
    return path, dict(parse_qsl(query, keep_blank_values=True))


def _resolve(location: str, index: PackageIndex) -> Path:
    if location.startswith("file://"):
        location = location[len("file://"):]
    if location.startswith("package://"):
        return index.resolve_uri(location)
    return Path(os.path.expanduser(location))


def _description_text(location: str, xacro_args: Mapping[str, str], index: PackageIndex) -> tuple[str, Path]:
    path_part, query_args = _split_uri(location)
    path = _resolve(path_part, index)
    if not path.is_file():
        raise DescriptionError(f"robot description '{location}' not found (resolved to '{path}'); give a URDF or "
                               "xacro file or a package:// URI of an installed description package")
    args = {**query_args, **{str(k): str(v) for k, v in xacro_args.items()}}
    text = path.read_text()
    if path.suffix == ".xacro" or args or "http://www.ros.org/wiki/xacro" in text:
        text = xacro_to_urdf(path, args, index=index)
    return text, path


def _controllers_file_in(root: ET.Element) -> str | None:
    """The controllers YAML a description names (ros2_control hardware param or gz plugin)."""
    for param in root.iter("param"):
        if param.get("name") == "controllers_file" and (param.text or "").strip():
            return param.text.strip()
    for plugin in root.iter("plugin"):
        params = plugin.find("parameters")
        if params is not None and (params.text or "").strip().endswith((".yaml", ".yml")):
            return params.text.strip()
    return None


def _ros2_control_joints(root: ET.Element) -> list[tuple[str, bool, float | None]]:
    """``(name, commandable, initial position)`` per joint of the ``<ros2_control>`` blocks."""
    out = []
    for block in root.iter("ros2_control"):
        for joint in block.findall("joint"):
            initial = None
            for si in joint.findall("state_interface"):
                for param in si.findall("param") if si.get("name") == "position" else ():
                    if param.get("name") == "initial_value" and (param.text or "").strip():
                        try:
                            initial = float(param.text.strip())
                        except ValueError as exc:
                            raise DescriptionError(f"ros2_control joint '{joint.get('name')}': initial_value "
                                                   f"{param.text.strip()!r} is not a number") from exc
            out.append((joint.get("name", ""), bool(joint.findall("command_interface")), initial))
    return out


def rename_controllers(config: Mapping[str, Any], renames: Mapping[str, str]) -> dict[str, Any]:
    """A ros2_control YAML mapping with controllers renamed (``{old: new}``).

    Raises:
        ValueError: a name to rename is not a controller of the YAML, or a new name is taken.
    """
    config = dict(config)
    cm = dict((config.get("controller_manager") or {}).get("ros__parameters") or {})
    for old, new in renames.items():
        if old == new:
            continue
        if not isinstance(cm.get(old), Mapping) or "type" not in cm[old]:
            known = sorted(k for k, v in cm.items() if isinstance(v, Mapping) and "type" in v)
            raise ValueError(f"cannot rename controller '{old}': the controllers YAML defines {known}")
        if new in cm or new in config:
            raise ValueError(f"cannot rename controller '{old}' to '{new}': that name is taken")
        cm = {(new if k == old else k): v for k, v in cm.items()}
        if old in config:
            config = {(new if k == old else k): v for k, v in config.items()}
    config["controller_manager"] = {"ros__parameters": cm}
    return config


def _finite_or(value: float | None, default: float) -> float:
    return float(value) if value is not None and math.isfinite(value) else default


def load_robot_spec(
    robot: str | None = None,
    *,
    description: str | None = None,
    xacro_args: Mapping[str, str] | None = None,
    controllers_file: str | None = None,
    namespace: str | None = None,
    renames: Mapping[str, str] | None = None,
    initial_positions: Mapping[str, float] | None = None,
    index: PackageIndex | None = None,
) -> RobotSpec:
    """Build a :class:`RobotSpec` from a preset name or a description.

    Args:
        robot: a key of :data:`PRESETS` (``"rx200"``, ``"irb120"``); its values are the defaults of
            the other arguments.
        description: URDF/xacro file or ``package://`` URI (``?name=value`` adds xacro arguments).
        xacro_args: more xacro arguments.
        controllers_file: ros2_control YAML (file or ``package://``); default: the one the
            description names, else none (no controllers).
        namespace: ROS namespace of the driver ("" = none).
        renames: ``{yaml name: served name}`` for controllers.
        initial_positions: start positions overriding the description's ``initial_value``.

    Raises:
        ValueError: unknown preset, no description, unknown joint in ``initial_positions``.
        DescriptionError: the description cannot be read.
    """
    index = index or default_index()
    preset = None
    if robot is not None:
        preset = PRESETS.get(robot)
        if preset is None:
            raise ValueError(f"unknown robot preset '{robot}'; known: {sorted(PRESETS)} "
                             "(or give --description and --controllers-file)")
    description = description or (preset.description if preset else None)
    if not description:
        raise ValueError("no robot description: give a preset (--robot rx200) or a description (--description URI)")
    text, path = _description_text(description, xacro_args or {}, index)
    root = ET.fromstring(text)
    urdf = parse_urdf(root, source=str(path))
    by_name = {j.name: j for j in urdf.joints}
    if controllers_file is None:
        controllers_file = preset.controllers_file if preset else _controllers_file_in(root)
    config: dict[str, Any] = {}
    if controllers_file:
        yaml_path = _resolve(controllers_file, index)
        try:
            config = read_yaml_bounded(yaml_path) or {}
        except (OSError, YamlBoundsError) as exc:
            raise ValueError(f"controllers file '{controllers_file}' cannot be read: {exc}") from exc
        if not isinstance(config, Mapping):
            raise ValueError(f"controllers file '{controllers_file}' is not a ros2_control YAML mapping")
    all_renames = dict(preset.renames) if preset else {}
    all_renames.update(renames or {})
    if config and all_renames:
        config = rename_controllers(config, all_renames)

    declared = _ros2_control_joints(root) or [
        (j.name, j.mimic is None, None) for j in urdf.joints if j.type not in ("fixed", "floating", "planar")
    ]
    listed = {name for name, _, _ in declared}
    declared += [(name, True, None) for name in urdf.mimic_leaders() if name not in listed]  # a gripper's drive
    initial_positions = dict(initial_positions or {})
    joints: list[JointSpec] = []
    mimics: list[MimicSpec] = []
    for name, _commandable, initial in declared:  # state-only non-mimic joints hold their position
        joint = by_name.get(name)
        if joint is None:
            raise DescriptionError(f"ros2_control joint '{name}' is not a joint of the description '{description}'")
        limit = joint.limit
        unlimited = joint.type == "continuous" or limit is None
        lower = -math.inf if unlimited else _finite_or(limit.lower, -math.inf)
        upper = math.inf if unlimited else _finite_or(limit.upper, math.inf)
        if joint.mimic is not None:
            mimics.append(MimicSpec(name, joint.mimic.joint, float(joint.mimic.multiplier),
                                    float(joint.mimic.offset), lower, upper))
            continue
        start = initial_positions.pop(name, initial if initial is not None else 0.0)
        velocity = _finite_or(limit.velocity if limit is not None else None, 0.0)
        joints.append(JointSpec(name, lower, upper, max(velocity, 0.0),
                                float(min(max(start, lower), upper))))
    if initial_positions:
        raise ValueError(f"initial positions for unknown joints {sorted(initial_positions)}; "
                         f"the robot's joints are {[j.name for j in joints]}")
    leaders = {j.name for j in joints}
    for m in mimics:
        if m.leader not in leaders:
            raise DescriptionError(f"mimic joint '{m.name}' follows '{m.leader}', which is not a hardware joint")
    if namespace is None:
        namespace = preset.namespace if preset else ""
    namespace = "/" + namespace.strip("/") if namespace.strip("/") else ""
    return RobotSpec(name=robot or urdf.name, namespace=namespace, joints=joints, mimics=mimics,
                     controllers=config, description=text)


_XACRO_ARG_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]*\Z")


def parse_xacro_args(items: Sequence[str], what: str = "--xacro-arg") -> dict[str, str]:
    """``["prefix:=left_", "hand=true"]`` -> ``{"prefix": "left_", "hand": "true"}``: xacro's and
    ``ros2 launch``'s ``NAME:=VALUE``, or ``NAME=VALUE``; raises ValueError naming a malformed item
    (a name that is not an XML name, e.g. ``prefix:`` from a ``:`` too many)."""
    out = {}
    for item in items:
        colon, equals = item.find(":="), item.find("=")
        key, found, value = item.partition(":=" if 0 <= colon < equals else "=")
        key = key.strip()
        if not found or not _XACRO_ARG_NAME.match(key):
            raise ValueError(f"{what} {item!r} must look like NAME:=VALUE (or NAME=VALUE), NAME a xacro "
                             "argument's name")
        out[key] = value.strip()
    return out


def parse_assignments(items: Sequence[str], what: str, sep: str = "=") -> dict[str, str]:
    """``["a=b", ...]`` -> ``{"a": "b"}``; raises ValueError naming a malformed item."""
    out = {}
    for item in items:
        key, found, value = item.partition(sep)
        if not found or not key:
            raise ValueError(f"{what} {item!r} must look like NAME{sep}VALUE")
        out[key.strip()] = value.strip()
    return out
