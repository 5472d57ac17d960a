"""The real twin's driver names for a drafted arm file (``uniros arm add``).

The names come from the controllers files (``config`` folders) of the packages the description names,
else the ``<ros2_control>`` tag's hardware plugin where we know its vendor's convention, else ROS 2
control's conventional names, each marked ``inferred`` or ``guessed`` in the file's ``real`` section.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from rl_environments.arm_description_tree import Inspection
from rl_environments.arm_draft import ArmDraft, _rl
from rl_environments.arm_gripper import _Gripper

#: Vendors' ros2_control hardware plugins -> (arm controller, gripper controller, gripper interface)
#: of their drivers' launch files; an unknown plugin gets ROS 2 control's conventional names.
_DRIVERS = {
    "ur_robot_driver/": ("scaled_joint_trajectory_controller", "gripper_controller", "gripper_action"),
    "franka_hardware/": ("fr3_arm_controller", "franka_gripper", "gripper_action"),
    "dynamixel_hardware": ("arm_controller", "gripper_controller", "gripper_action"),
    "open_manipulator": ("arm_controller", "gripper_controller", "gripper_action"),
    "interbotix": ("arm_controller", "gripper_controller", "forward"),
    "kinova": ("joint_trajectory_controller", "robotiq_gripper_controller", "gripper_action"),
}
#: A vendor package's controllers files read for the driver's names: at most this many, this large.
_MAX_CONTROLLER_FILES, _MAX_CONTROLLER_FILE_BYTES = 64, 256 * 1024
#: ros2_control controller types -> the Real twin's gripper interface.
_GRIPPER_TYPES = {"joint_trajectory_controller/JointTrajectoryController": "trajectory",
                  "position_controllers/GripperActionController": "gripper_action",
                  "parallel_gripper_action_controller/GripperActionController": "gripper_action",
                  "forward_command_controller/ForwardCommandController": "forward",
                  "position_controllers/JointGroupPositionController": "forward"}


@dataclass
class _Driver:
    """The names a vendor's own controllers file gives its driver (``None``: not found there)."""

    source: str
    namespace: str
    arm_controller: str
    gripper_controller: str | None = None
    gripper_interface: str | None = None


def _source_packages(ins: Inspection) -> list[str]:
    """The packages the description's xacro files name (``$(find pkg)``, ``package://pkg``), its own first."""
    from multiros.sim.packages import default_index

    names: list[str] = []
    for parent in Path(ins.source).resolve().parents:  # the package the description is in comes first
        manifest = parent / "package.xml"
        if manifest.is_file():
            own = re.search(r"<name>\s*([A-Za-z0-9_]+)\s*</name>", manifest.read_text(errors="replace")[:100_000])
            if own:
                names.append(own.group(1))
            break
    index = default_index()
    seen: set[Path] = set()
    queue = [Path(ins.source)]
    while queue and len(seen) < 64:  # the description's files, following $(find ...) includes
        path = queue.pop(0)
        if path in seen or not path.is_file():
            continue
        seen.add(path)
        try:
            text = path.read_text(errors="replace")[:2_000_000]
        except OSError:
            continue
        for pkg, rest in re.findall(r"(?:\$\(find |package://)([A-Za-z0-9_]+)\)?(/[^\s\"'<>]*)?", text):
            if pkg not in names:
                names.append(pkg)
            if rest and rest.endswith(".xacro"):
                try:
                    queue.append(index.find_package_share(pkg) / rest.lstrip("/"))
                except Exception:  # noqa: BLE001 - a package we cannot find names no file
                    pass
    return names


def _config_files(share: Path) -> list[Path]:
    """The YAML files in ``config`` folders of a package (``config/``, or deeper as Kinova's
    ``arms/gen3_lite/6dof/config/``), at most ``_MAX_CONTROLLER_FILES``, 4 folders deep."""
    found: list[Path] = []
    for depth in range(4):
        pattern = "/".join(["*"] * depth + ["config", "**", "*.yaml"])
        found += sorted(p for p in share.glob(pattern) if p.is_file() and p not in found)
        if len(found) >= _MAX_CONTROLLER_FILES:
            break
    return found[:_MAX_CONTROLLER_FILES]


def _vendor_driver(ins: Inspection, joints: Sequence[str], gripper: _Gripper | None) -> _Driver | None:
    """The arm's trajectory controller (and the gripper's) from the controllers files of the packages
    the description names (``config/**/*.yaml``): the controller whose joints are the arm's, its
    controller manager's namespace (``/lbr/controller_manager:`` -> ``/lbr``)."""
    from multiros.bounded_yaml import YamlBoundsError, load_yaml_bounded
    from multiros.sim.packages import default_index

    index = default_index()
    files: list[Path] = []
    for pkg in _source_packages(ins):
        try:
            share = index.find_package_share(pkg)
        except Exception:  # noqa: BLE001 - not installed here: nothing to read
            continue
        files += _config_files(share)
    found: _Driver | None = None
    grip: tuple[str, str] | None = None
    for path in files[:_MAX_CONTROLLER_FILES]:
        try:
            if path.stat().st_size > _MAX_CONTROLLER_FILE_BYTES:
                continue
            doc = load_yaml_bounded(path.read_text(errors="replace"), max_bytes=_MAX_CONTROLLER_FILE_BYTES)
        except (OSError, YamlBoundsError):  # unreadable, or a file no driver config is (aliases exploding, ...)
            continue
        if not isinstance(doc, dict):
            continue
        types: dict[str, str] = {}
        namespace = ""
        for key, value in doc.items():
            if str(key).rstrip("/").endswith("controller_manager") and isinstance(value, dict):
                prefix = str(key).rsplit("controller_manager", 1)[0].strip("/*")  # "/lbr/", "/**/", ""
                namespace = f"/{prefix}" if prefix else ""
                params = value.get("ros__parameters") or {}
                types.update({k: v["type"] for k, v in params.items() if isinstance(v, dict) and "type" in v})
        for key, value in doc.items():
            name = str(key).strip("/").rsplit("/", 1)[-1]
            params = value.get("ros__parameters") if isinstance(value, dict) else None
            if name not in types or not isinstance(params, dict):
                continue
            joints_of = params.get("joints", [params["joint"]] if isinstance(params.get("joint"), str) else None)
            if not isinstance(joints_of, list):  # a GripperActionController names its one joint as `joint`
                continue
            listed = [str(j) for j in joints_of]
            if found is None and types[name].endswith("JointTrajectoryController") and set(listed) == set(joints):
                found = _Driver(path.name, namespace, name)
            elif gripper is not None and listed in ([gripper.joint], [gripper.joint, gripper.follower]) \
                    and types[name] in _GRIPPER_TYPES:
                grip = (name, _GRIPPER_TYPES[types[name]])
    if found is not None and grip is not None:
        found.gripper_controller, found.gripper_interface = grip
    return found


def _real(draft: ArmDraft, ins: Inspection, joints: Sequence[str], gripper: _Gripper | None,
          ee_min: Sequence[float], ee_max: Sequence[float]) -> None:
    """The real twin's driver names: the vendor's controllers file's where the description's packages
    have one, else a known vendor plugin's, else ROS 2 control's conventional ones."""
    import xml.etree.ElementTree as ET

    plugins = [p.text.strip() for p in ET.fromstring(ins.description.text).iter("plugin")
               if p.text and p.text.strip() and p.find("*") is None]
    known = next(((prefix, names) for p in plugins for prefix, names in _DRIVERS.items() if prefix in p), None)
    rc = {j.name for j in ins.description.ros2_control}
    if known is not None:
        arm_ctrl, grip_ctrl, grip_iface = known[1]
        why = f"guessed: the names {known[0].rstrip('/')}'s driver launches (ros2_control plugin {plugins[0]!r})"
    else:
        arm_ctrl, grip_ctrl, grip_iface = "joint_trajectory_controller", "gripper_controller", "gripper_action"
        why = "guessed: ROS 2 control's conventional names" + (
            " (the ros2_control tag names no plugin we know)" if rc else " (the description has no ros2_control tag)")
    real = {"namespace": "", "arm_controller": arm_ctrl, "controllers": [], "command_interface": "topic",
            "check_controllers": True, "joint_states_topic": "/joint_states",
            "gripper_controller": grip_ctrl if gripper is not None else "",
            "gripper_interface": grip_iface if gripper is not None else "none",
            "workspace_min": _rl(ee_min, 3), "workspace_max": _rl(ee_max, 3), "floor_z": 0.02,
            "max_joint_delta": 0.15}
    if gripper is not None:
        real["gripper_joint"] = gripper.joint
    missing = [j for j in joints if rc and j not in rc]
    vendor = _vendor_driver(ins, joints, gripper)
    grip_why = "guessed: as real.arm_controller" if gripper else "no gripper"
    if vendor is not None:
        real["arm_controller"] = vendor.arm_controller
        real["namespace"] = vendor.namespace
        why = f"inferred: the JointTrajectoryController of the arm's joints in the package's {vendor.source}"
        if vendor.namespace:
            draft.note("real.namespace", f"inferred: its controller manager's namespace in {vendor.source}")
            real["joint_states_topic"] = f"{vendor.namespace}/joint_states"
        if gripper is not None and vendor.gripper_controller:
            real["gripper_controller"] = vendor.gripper_controller
            real["gripper_interface"] = vendor.gripper_interface
            grip_why = f"inferred: the controller of {gripper.joint!r} in the package's controllers files"
    draft.sections["real"] = real
    draft.note("real.arm_controller", why + "; a JointTrajectoryController")
    draft.note("real.joint_states_topic", "guessed: the joint_state_broadcaster's default topic" +
               (f"; the ros2_control tag lacks {missing}" if missing else ""))
    draft.note("real.gripper_controller", grip_why)
    draft.note("real.workspace_min", "inferred: the reach's EE box (the safety box the Real env clips to)")
