"""The physics stand-in of an arm file: ``uniros-fake-robot --arm FILE --physics TASK``.

The plain fake robot has joints and no object, so the push, pick-and-place and slide Real twins cannot
be tried on it. In physics mode the driver's names (the arm file's ``real:`` section, as without
``--physics``) serve a robot in a MuJoCo world of its own (:class:`~multiros.hardware.physics_hardware.PhysicsHardware`)
holding the Sim twin's scene: the robot where the Sim twin spawns it, the table and the object made as
the Sim twin makes them (the arm file's ``scene:`` MJCF, else its ``manipulation`` sizes; slide's long
table and puck). The object's pose goes out on the tracker topic the Real twins read
(:class:`~multiros.hardware.tracker.PoseTracker`: ``/object_pose`` by default, in the arm's base link
frame) with a tracker's noise and latency.

Perturbations (:func:`parse_perturbation`): scales of the spawned physical values, by the keys the
simulation's ``randomization:`` uses for them (``object_mass``, ``object_friction``, ``table_friction``,
``object_size``, ``link_mass``, ``joint_damping``, ``joint_friction``, ``joint_armature``,
``actuator_gain``); a value is one scale or a ``[low, high]`` range drawn once at start from
``--physics-seed``; shipped profiles :data:`PERTURB_PROFILES`. They are set through the world's
``set_entity_properties``, as the simulation node sets a randomised episode's.

Between episodes (:class:`LabHelper`): a Real twin's reset moves the arm to the task's start pose and
starts the episode with the object where it lies (a person puts it back). The stand-in does what that
person does: whenever the arm comes back to the start pose after having left it, the object is put down,
at rest, at a new start pose in the task's start box (``--physics-reset random``, the default, seeded),
at the box's centre (``spawn``) or not at all (``none``). A ``PoseStamped`` on
``<namespace>/physics/place_object`` (base frame) puts it anywhere, at any time.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import numpy as np

from multiros.bounded_yaml import YamlBoundsError, read_yaml_bounded
from multiros.hardware.physics_hardware import PhysicsEntity, PhysicsHardware, PropertyRow

if TYPE_CHECKING:
    from multiros.hardware.gap import GapProfile
    from multiros.hardware.robot_spec import RobotSpec
    from rl_environments.arm_file import ArmFile

__all__ = ["PERTURB_KEYS", "PERTURB_PROFILES", "RESET_MODES", "TASKS", "LabHelper", "PhysicsOptionError",
           "PhysicsScene", "draw_scales", "parse_perturbation", "perturbation_rows", "physics_hardware",
           "physics_scene"]

_logger = logging.getLogger(__name__)

#: ``--physics`` tasks: push and pick-and-place share a scene; slide has its own.
TASKS = ("push", "pnp", "slide")
#: Where the helper puts the object between episodes.
RESET_MODES = ("random", "spawn", "none")
#: Perturbation key -> (whose: robot, object or table; target; property) of ``set_entity_properties``.
PERTURB_KEYS: dict[str, tuple[str, str, str]] = {
    "object_mass": ("object", "body", "mass"),
    "object_friction": ("object", "geom", "friction"),
    "object_size": ("object", "geom", "size"),
    "table_friction": ("table", "geom", "friction"),
    "link_mass": ("robot", "body", "mass"),
    "joint_damping": ("robot", "joint", "damping"),
    "joint_friction": ("robot", "joint", "frictionloss"),
    "joint_armature": ("robot", "joint", "armature"),
    "actuator_gain": ("robot", "actuator", "gain"),
}
#: Shipped perturbations (``[low, high]`` scales, drawn once at start). MuJoCo takes the larger friction
#: of two touching geoms: lowering the object's friction needs the table's lowered too.
PERTURB_PROFILES: dict[str, dict[str, tuple[float, float]]] = {
    "none": {},
    "mild": {"object_mass": (0.8, 1.25), "object_friction": (0.8, 1.25), "table_friction": (0.8, 1.25),
             "link_mass": (0.9, 1.1), "joint_damping": (0.8, 1.25)},
    "hard": {"object_mass": (0.5, 2.0), "object_friction": (0.5, 1.5), "table_friction": (0.5, 1.5),
             "link_mass": (0.8, 1.25), "joint_damping": (0.5, 2.0), "actuator_gain": (0.7, 1.3)},
}
_SCALE_BOUNDS = (0.01, 100.0)  # the world's bounds of a scale
#: rad: the arm has left its start pose (farther than this on some joint), and is back (within this).
_LEFT, _BACK = 0.15, 0.05


class PhysicsOptionError(ValueError):
    """A physics option the stand-in cannot use (one line naming it)."""


# ------------------------------------------------------------------------------ perturbations
def _scale(key: str, raw: Any, where: str) -> tuple[float, float]:
    if key not in PERTURB_KEYS:
        import difflib

        close = difflib.get_close_matches(key, PERTURB_KEYS, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else f"; keys: {', '.join(PERTURB_KEYS)}"
        raise PhysicsOptionError(f"{where}: {key!r} is not a perturbation key{hint}")
    if isinstance(raw, str) and ":" in raw:
        raw = raw.split(":", 1)
    values = list(raw) if isinstance(raw, (list, tuple)) else [raw, raw]
    try:
        if len(values) != 2 or any(isinstance(v, bool) for v in values):
            raise ValueError
        lo, hi = (float(v) for v in values)
    except (TypeError, ValueError):
        raise PhysicsOptionError(f"{where}: {key} must be a scale or a range LOW:HIGH ([low, high] in YAML), "
                                 f"got {str(raw)[:60]!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and _SCALE_BOUNDS[0] <= lo <= hi <= _SCALE_BOUNDS[1]):
        raise PhysicsOptionError(f"{where}: {key} scales must satisfy {_SCALE_BOUNDS[0]:g} <= low <= high <= "
                                 f"{_SCALE_BOUNDS[1]:g}, got [{lo:g}, {hi:g}]")
    return lo, hi


def parse_perturbation(items: Sequence[str]) -> dict[str, tuple[float, float]]:
    """The ranges of ``--physics-perturb`` items, later ones winning: a shipped profile's name
    (:data:`PERTURB_PROFILES`), a YAML file (a mapping of keys to a scale or ``[low, high]``), or
    ``KEY=SCALE`` / ``KEY=LOW:HIGH``. Raises :class:`PhysicsOptionError` (one line)."""
    ranges: dict[str, tuple[float, float]] = {}
    for item in items:
        if "=" in item:
            key, _, value = item.partition("=")
            ranges[key.strip()] = _scale(key.strip(), value.strip(), f"--physics-perturb {item[:80]!r}")
        elif item in PERTURB_PROFILES:
            ranges.update(PERTURB_PROFILES[item])
        else:
            try:
                data = read_yaml_bounded(Path(item))
            except FileNotFoundError:
                raise PhysicsOptionError(f"--physics-perturb {item[:80]!r}: not KEY=SCALE, a profile "
                                         f"({', '.join(PERTURB_PROFILES)}) or a YAML file") from None
            except (OSError, YamlBoundsError) as exc:
                raise PhysicsOptionError(f"--physics-perturb {item[:80]}: cannot be read: "
                                         f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
            if data is None:
                continue
            if not isinstance(data, Mapping):
                raise PhysicsOptionError(f"--physics-perturb {item[:80]}: a mapping of perturbation keys, got "
                                         f"{type(data).__name__}")
            for key, value in data.items():
                ranges[str(key)] = _scale(str(key), value, f"--physics-perturb {item[:80]}")
    return ranges


def draw_scales(ranges: Mapping[str, tuple[float, float]], rng: np.random.Generator) -> dict[str, float]:
    """One scale per key (uniform in its range; in key order, so a seed gives the same draws)."""
    return {key: float(rng.uniform(lo, hi)) if hi > lo else float(lo) for key, (lo, hi) in sorted(ranges.items())}


def perturbation_rows(scales: Mapping[str, float]) -> dict[str, list[PropertyRow]]:
    """The scales as ``set_entity_properties`` rows per entity role (``robot``, ``object``, ``table``)."""
    rows: dict[str, list[PropertyRow]] = {}
    for key, value in scales.items():
        role, target, prop = PERTURB_KEYS[key]
        rows.setdefault(role, []).append((target, "", prop, float(value)))
    return rows


# ------------------------------------------------------------------------------ the scene
@dataclass(frozen=True)
class PhysicsScene:
    """The Sim twin's scene of a task, and what the helper needs (world frame unless said).

    Attributes:
        task: ``push``, ``pnp`` or ``slide``.
        base: where the robot's base stands.
        table, object: the entities.
        start_pose: the arm joints' start pose of the task (its reset's target).
        object_xy_min, object_xy_max: the object's start box (base frame).
        rest_z: the object's centre height at rest (base frame).
        yaw_range: the object's start yaw within +- this (rad).
        frame_id: the frame the tracker's poses are in (the arm's base link).
    """

    task: str
    base: tuple[float, float, float]
    table: PhysicsEntity
    object: PhysicsEntity
    start_pose: tuple[float, ...]
    object_xy_min: tuple[float, float]
    object_xy_max: tuple[float, float]
    rest_z: float
    yaw_range: float
    frame_id: str


def _yaw_quat(yaw: float) -> tuple[float, float, float, float]:
    return (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))


def physics_scene(arm_file: ArmFile, task: str) -> PhysicsScene:
    """The scene ``task``'s Sim twin spawns for ``arm_file`` (see the module docstring).

    Raises:
        PhysicsOptionError: an unknown task, or an arm without the task (no gripper, no ``manipulation``).
    """
    from rl_environments.arm import Arm
    from rl_environments.arm_scene import scene_mjcf

    if task not in TASKS:
        raise PhysicsOptionError(f"--physics {task!r}: the task is one of {', '.join(TASKS)}")
    arm = Arm(arm_file)
    if arm_file.gripper is None:
        raise PhysicsOptionError(f"{arm_file.path}: --physics {task}: the {arm.name} has no gripper (no {task} twin)")
    name = arm.robot_name
    if task == "slide":
        from rl_environments.slide_task import PUCK, SlideTask, slide_config

        cfg = slide_config(arm)
        # the slide's MJCF is the task's (made from the robot's name and its config alone)
        table_xml, object_xml = SlideTask.scene_mjcf(SimpleNamespace(arm=arm, cfg=cfg))  # type: ignore[arg-type]
        half_z, yaw_range = float(PUCK["half_height"]), 0.05
        descriptions = {"table": table_xml, "object": object_xml}
    else:
        if arm_file.manipulation is None:
            raise PhysicsOptionError(f"{arm_file.path}: --physics {task}: the arm file has no manipulation: section")
        cfg = arm.task_config("manipulation")
        half_z, yaw_range = float(cfg["object_half_size"]), float(cfg["object_yaw_range"])
        descriptions = {item: arm_file.scene_files.get(item, "") or scene_mjcf(name, cfg, item)
                        for item in ("table", "object")}
    base = (0.0, 0.0, float(cfg["robot_height"]))  # the Sim twin's spawn position (robot_pos_z: robot_height)
    rest_z = float(cfg["table_top"]) + half_z
    lo, hi = tuple(float(v) for v in cfg["object_xy_min"]), tuple(float(v) for v in cfg["object_xy_max"])
    table_at = np.asarray(cfg["table_center"], dtype=np.float64) + base
    object_at = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, rest_z]) + base
    ik_lower = np.maximum(arm.chain.lower, np.asarray(cfg["min_joint_pos"], dtype=np.float64))
    ik_upper = np.minimum(arm.chain.upper, np.asarray(cfg["max_joint_pos"], dtype=np.float64))
    start = arm.top_down_ik(ik_lower, ik_upper).solve(np.asarray(cfg["init_ee_position"], dtype=np.float64))
    return PhysicsScene(
        task, base,
        PhysicsEntity(f"{name}_table", descriptions["table"], tuple(float(v) for v in table_at),  # type: ignore[arg-type]
                      frame="table"),
        PhysicsEntity(f"{name}_object", descriptions["object"], tuple(float(v) for v in object_at),  # type: ignore[arg-type]
                      frame="object"),
        tuple(float(v) for v in start), lo, hi, rest_z, yaw_range, arm_file.base_link)  # type: ignore[arg-type]


def physics_hardware(spec: RobotSpec, arm_file: ArmFile, scene: PhysicsScene, scales: Mapping[str, float], *,
                     gap: GapProfile | None = None, seed: int | None = 0, timestep: float = 0.004) -> PhysicsHardware:
    """The robot of ``spec`` in ``scene``'s world, its physical values scaled by ``scales``.

    Raises:
        ValueError: the world cannot be made (a description, a property row: one line).
    """
    from multiros.sim.errors import SimError

    try:
        hardware = PhysicsHardware(spec, arm_file.description_uri, xacro_args=dict(arm_file.xacro_args),
                                   base_position=scene.base, entities=(scene.table, scene.object),
                                   timestep=timestep, gap=gap, seed=seed)
    except SimError as exc:
        raise ValueError(f"{arm_file.path}: the physics world cannot be made: {str(exc).splitlines()[0]}") from None
    entity = {"robot": spec.name, "object": scene.object.name, "table": scene.table.name}
    try:
        for role, rows in perturbation_rows(scales).items():
            hardware.set_properties(entity[role], rows)
    except (SimError, ValueError) as exc:
        hardware.close()
        raise ValueError(f"--physics-perturb: {str(exc).splitlines()[0]}") from None
    return hardware


# ------------------------------------------------------------------------------ between episodes
class LabHelper:
    """Puts the object back between episodes, as a person in the lab does (see the module docstring).

    :meth:`check` (the tracker calls it at every tick) watches the arm: once it has left the task's start
    pose (some joint farther than 0.15 rad) and is back (every joint within 0.05 rad: a reset's move is
    ending), the object is put down at rest. ``mode``: :data:`RESET_MODES`.
    """

    def __init__(self, hardware: PhysicsHardware, scene: PhysicsScene, arm_joints: Sequence[str], mode: str = "random",
                 rng: np.random.Generator | None = None) -> None:
        if mode not in RESET_MODES:
            raise PhysicsOptionError(f"--physics-reset {mode!r}: one of {', '.join(RESET_MODES)}")
        self.hardware, self.scene, self.mode = hardware, scene, mode
        self.rng = rng if rng is not None else np.random.default_rng(0)
        names = list(hardware.joint_names())
        self._idx = np.array([names.index(j) for j in arm_joints], dtype=np.intp)
        self._start = np.asarray(scene.start_pose, dtype=np.float64)
        self._left = True  # the arm starts at home: its first reset's move brings it back
        self.placed = 0  # the times the object was put back
        self._lock = threading.Lock()

    def next_pose(self) -> tuple[np.ndarray, tuple[float, float, float, float]]:
        """Where the object goes now (world frame), and its orientation."""
        s = self.scene
        if self.mode == "random":
            xy = self.rng.uniform(s.object_xy_min, s.object_xy_max)
            yaw = float(self.rng.uniform(-s.yaw_range, s.yaw_range))
        else:
            xy, yaw = (np.add(s.object_xy_min, s.object_xy_max) / 2), 0.0
        return np.array([xy[0], xy[1], s.rest_z]) + s.base, _yaw_quat(yaw)

    def place(self, position: Sequence[float] | np.ndarray,
              orientation: Sequence[float] | np.ndarray = (1.0, 0.0, 0.0, 0.0)) -> None:
        """Put the object down at ``position`` (world frame), at rest."""
        with self._lock:
            self.hardware.place(self.scene.object.name, position, orientation)
            self.placed += 1

    def check(self) -> None:
        """Put the object back if the arm has just come back to its start pose (see the class docstring)."""
        if self.mode == "none":
            return
        error = float(np.max(np.abs(self.hardware.joint_state().position[self._idx] - self._start)))
        if error > _LEFT:
            self._left = True
        elif self._left and error < _BACK:
            self._left = False
            self.place(*self.next_pose())


def place_object_listener(node: Any, topic: str, helper: LabHelper, frame_id: str) -> Callable[[], None]:
    """Subscribe ``topic`` (``PoseStamped`` in ``frame_id``, the base frame): each valid pose puts the object
    there; a malformed one is logged and ignored. Returns what unsubscribes."""
    from multiros.envs.real.sensor_link import PoseStamped, pose_from_msg

    base = np.asarray(helper.scene.base, dtype=np.float64)

    def on_pose(msg: Any) -> None:
        try:
            pose, why = pose_from_msg(msg, frame_id)
        except (TypeError, ValueError, AttributeError, OverflowError) as exc:
            pose, why = None, f"unreadable message ({exc})"
        if pose is None:
            _logger.warning("%s: pose ignored: %s", topic, why)
            return
        helper.place(pose[0] + base, pose[1])

    sub = node.create_subscription(PoseStamped, topic, on_pose, 10)
    return lambda: node.destroy_subscription(sub)
