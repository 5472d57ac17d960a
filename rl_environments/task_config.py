"""Loading task configuration YAML files with a schema: missing or mistyped keys name the key and the file.

Task configs live in the repository's top-level ``config/`` folder, installed as the package
``rl_environments.config``. A user may pass a path to their own copy instead.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from multiros.excerpt import quote


class TaskConfigError(ValueError):
    """A task configuration file is missing, unreadable, or has a missing or mistyped key."""


def config_path(name: str | Path) -> Path:
    """Resolve a config file: an existing path, or a file name inside ``rl_environments.config``."""
    path = Path(name)
    if path.is_file():
        return path
    packaged = resources.files("rl_environments.config").joinpath(str(name))
    if packaged.is_file():
        return Path(str(packaged))
    available = sorted(p.name for p in resources.files("rl_environments.config").iterdir() if p.name.endswith(".yaml"))
    raise TaskConfigError(
        f"task config {str(name)!r} not found (not a file, not one of the packaged configs {available})"
    )


def _check_value(value: Any, expected: Any, key: str, source: str | Path) -> Any:
    if isinstance(expected, tuple) and expected and expected[0] == "vector":
        length = expected[1]
        if (
            not isinstance(value, list)
            or len(value) != length
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
        ):
            raise TaskConfigError(f"{source}: key {key!r} must be a list of {length} finite numbers, got "
                                  f"{quote(value)}")
        return [float(v) for v in value]
    if expected is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise TaskConfigError(f"{source}: key {key!r} must be a finite number, got {quote(value)}")
        return float(value)
    if expected is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise TaskConfigError(f"{source}: key {key!r} must be an integer, got {value!r}")
        return value
    if not isinstance(value, expected):
        raise TaskConfigError(f"{source}: key {key!r} must be of type {expected.__name__}, got {value!r}")
    return value


#: Bounds a task config's values must keep, beyond their types: (low key, high key) element-wise, and
#: keys that must be above zero. A value outside them registers and fails later in numpy or gymnasium.
ORDERED_PAIRS = (("min_joint_pos", "max_joint_pos"), ("position_ee_min", "position_ee_max"),
                 ("position_goal_min", "position_goal_max"), ("object_xy_min", "object_xy_max"),
                 ("goal_xy_min", "goal_xy_max"))
POSITIVE = ("delta_coeff", "ee_delta_coeff", "reach_tolerance", "object_half_size", "distance_threshold",
            "max_joint_vel", "max_linear_velocity", "max_angular_velocity")


def _check_bounds(out: Mapping[str, Any], source: str | Path) -> None:
    for low, high in ORDERED_PAIRS:
        if low in out and high in out and isinstance(out[low], list) and isinstance(out[high], list):
            inverted = [i for i, (a, b) in enumerate(zip(out[low], out[high])) if a > b]
            if inverted:
                i = inverted[0]
                raise TaskConfigError(f"{source}: key {low!r} is above {high!r} at index {i} "
                                      f"({out[low][i]:g} > {out[high][i]:g}): the box is inverted")
    for key in POSITIVE:
        if key in out and isinstance(out[key], float) and not out[key] > 0:
            raise TaskConfigError(f"{source}: key {key!r} must be above zero, got {out[key]:g}")


def vector(length: int) -> tuple[str, int]:
    """Schema marker: a list of ``length`` numbers."""
    return ("vector", length)


def load_task_config(name: str | Path, schema: Mapping[str, Any], section: str | None = None,
                     defaults: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Load a YAML task config and check it against ``schema`` (key -> type or :func:`vector`).

    Args:
        name: a path, or a file name in ``rl_environments.config``.
        schema: the required keys and their types; other keys are kept unchecked.
        section: a top-level key the values sit under (e.g. the robot namespace ``rx200``).
        defaults: values of keys the file may leave out (e.g. an arm's scene); the file's win.

    Raises:
        TaskConfigError: the file is missing or not YAML, or a key is missing or mistyped.
    """
    path = config_path(name)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise TaskConfigError(f"{path}: not valid YAML: {exc}") from exc
    if section is not None:
        if not isinstance(data, dict) or section not in data:
            raise TaskConfigError(f"{path}: missing top-level key {section!r}")
        data = data[section]
    if not isinstance(data, dict):
        raise TaskConfigError(f"{path}: expected a mapping of keys, got {type(data).__name__}")
    return check_task_config(data, schema, source=path, defaults=defaults)


def check_task_config(data: Mapping[str, Any], schema: Mapping[str, Any], *, source: str | Path,
                      defaults: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Check a task config's mapping against ``schema`` (as :func:`load_task_config`, for a config that
    is not a file of its own: an arm file's ``reach:`` section); ``source`` names it in errors."""
    data = {**{k: list(v) if isinstance(v, tuple) else v for k, v in (defaults or {}).items()}, **data}
    out = dict(data)
    for key, expected in schema.items():
        if key not in data:
            raise TaskConfigError(f"{source}: missing key {key!r}")
        out[key] = _check_value(data[key], expected, key, source)
    _check_bounds(out, source)
    return out


def reach_schema(n_joints: int) -> dict[str, Any]:
    """The keys of a reach config for an arm of ``n_joints`` joints."""
    return {
        "arm_joints": list,
        "min_joint_pos": vector(n_joints),
        "max_joint_pos": vector(n_joints),
        "init_joint_pos": vector(n_joints),
        "delta_coeff": float,
        "ee_delta_coeff": float,
        "position_ee_min": vector(3),
        "position_ee_max": vector(3),
        "position_goal_min": vector(3),
        "position_goal_max": vector(3),
        "reach_tolerance": float,
        "step_reward": float,
        "multiplier_dist_reward": float,
        "reached_goal_reward": float,
        "joint_limits_reward": float,
        "max_joint_vel": float,
    }


#: The scene's keys: an arm's ``SCENE`` gives them (a task config may override them, with its own
#: table and cube files to match).
SCENE_KEYS = ("robot_height", "table_center", "table_top", "object_half_size", "init_ee_position",
              "position_ee_min", "position_ee_max", "object_xy_min", "object_xy_max", "goal_xy_min", "goal_xy_max",
              "target_height_max", "max_object_distance")


def manipulation_schema(n_joints: int) -> dict[str, Any]:
    """The keys of a push / pick-and-place config (scene included) for an arm of ``n_joints`` joints."""
    return {
        "arm_joints": list,
        "min_joint_pos": vector(n_joints),
        "max_joint_pos": vector(n_joints),
        "robot_height": float,
        "table_center": vector(3),
        "table_top": float,
        "object_half_size": float,
        "init_ee_position": vector(3),
        "delta_coeff": float,
        "ee_delta_coeff": float,
        "position_ee_min": vector(3),
        "position_ee_max": vector(3),
        "gripper_min": float,
        "gripper_max": float,
        "object_xy_min": vector(2),
        "object_xy_max": vector(2),
        "object_yaw_range": float,
        "goal_xy_min": vector(2),
        "goal_xy_max": vector(2),
        "target_in_the_air": float,
        "target_height_max": float,
        "min_object_goal_distance": float,
        "distance_threshold": float,
        "fall_margin": float,
        "max_object_distance": float,
        "max_linear_velocity": float,
        "max_angular_velocity": float,
        "max_joint_vel": float,
    }
