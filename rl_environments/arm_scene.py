"""The push / pick-and-place scene of an arm file, made from its sizes: the table and the cube as MJCF.

An arm file says the scene's sizes once, in ``manipulation`` (``table_half_extents``, ``robot_height``,
``object_half_size``, ``object_mass``); the tasks place the entities by the same values. Unless its
``scene:`` section names MJCF files of the user's own, the simulation spawns the MJCF these functions
make from those sizes (as text: no file to drift from the values).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["cube_mjcf", "scene_mjcf", "table_mjcf"]


def _free_box(robot_name: str, item: str, comment: str, body: str, geom: str, half: Sequence[float],
              attrs: str) -> str:
    """MJCF of one free body holding one box geom (``half``: its half sizes, m)."""
    size = " ".join(f"{float(v):g}" for v in half)
    return f"""<!--
  {comment}
-->
<mujoco model="{robot_name}_{item}">
  <worldbody>
    <body name="{body}">
      <freejoint/>
      <geom name="{geom}" type="box" size="{size}" {attrs}/>
    </body>
  </worldbody>
</mujoco>
"""


def table_mjcf(robot_name: str, half_extents: Sequence[float], robot_height: float) -> str:
    """The work table: a box of ``half_extents`` (m) standing on the floor, its top just under the robot's
    base (spawned at ``z = robot_height``); a free body heavy enough that the arm cannot move it."""
    hx, hy, _ = (float(v) for v in half_extents)
    return _free_box(robot_name, "table", f"The work table of the {robot_name} push and pick-and-place scene: a "
                     f"{2 * hx:.2f} x {2 * hy:.2f} m slab on\n  the floor, its top just under the robot's base "
                     f"(spawned at z = {robot_height:g}); friction 0.5.", "table", "top", half_extents,
                     'mass="60" friction="0.5 0.005 0.0001"\n            rgba="0.72 0.6 0.46 1"')


def cube_mjcf(robot_name: str, half_size: float, mass: float) -> str:
    """The object: a cube of ``half_size`` (m) and ``mass`` (kg) with the shipped cubes' contact settings
    (friction 0.5, torsional friction so a held cube does not spin, soft enough to be squeezed)."""
    half, mass = float(half_size), float(mass)
    return _free_box(robot_name, "cube", f"The object of the {robot_name} push and pick-and-place scene: a "
                     f"{2 * half * 100:.1f} cm cube of\n  {mass * 1000:.0f} g.", "object", "cube", (half, half, half),
                     f'mass="{mass:g}" condim="4"\n            friction="0.5 0.01 0.0002" solref="0.01 1" '
                     'solimp="0.99 0.999 0.001" rgba="0.85 0.15 0.1 1"')


def scene_mjcf(robot_name: str, scene: Mapping[str, Any], item: str) -> str:
    """``"table"`` or ``"object"`` of a ``manipulation`` section's sizes."""
    if item == "table":
        return table_mjcf(robot_name, scene["table_half_extents"], scene["robot_height"])
    if item == "object":
        return cube_mjcf(robot_name, scene["object_half_size"], scene["object_mass"])
    raise ValueError(f"a scene has a 'table' and an 'object', not {item!r}")
