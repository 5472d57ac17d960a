"""Reference tables (frobs_and_robots.md §3) and small URDF readers shared by the description tests."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import trimesh

# name: (type, parent, child, xyz, axis, lower, upper, effort, velocity); links without the rx200/ prefix.
RX200_JOINTS = {
    "waist": ("revolute", "base_link", "shoulder_link", (0, 0, 0.06566), (0, 0, 1),
              -math.pi + 1e-5, math.pi - 1e-5, 8, math.pi),
    "shoulder": ("revolute", "shoulder_link", "upper_arm_link", (0, 0, 0.03891), (0, 1, 0),
                 -1.88496, 1.97222, 18, 1.0),
    "elbow": ("revolute", "upper_arm_link", "forearm_link", (0.05, 0, 0.2), (0, 1, 0),
              -1.88496, 1.62316, 13, math.pi),
    "wrist_angle": ("revolute", "forearm_link", "wrist_link", (0.2, 0, 0), (0, 1, 0),
                    -1.74533, 2.14675, 5, math.pi),
    "wrist_rotate": ("revolute", "wrist_link", "gripper_link", (0.065, 0, 0), (1, 0, 0),
                     -math.pi + 1e-5, math.pi - 1e-5, 1, math.pi),
    "ee_arm": ("fixed", "gripper_link", "ee_arm_link", (0.043, 0, 0), None, None, None, None, None),
    "gripper": ("continuous", "ee_arm_link", "gripper_prop_link", (0.0055, 0, 0), (1, 0, 0),
                None, None, 1, math.pi),
    "gripper_bar": ("fixed", "ee_arm_link", "gripper_bar_link", (0, 0, 0), None, None, None, None, None),
    "ee_bar": ("fixed", "gripper_bar_link", "fingers_link", (0.023, 0, 0), None, None, None, None, None),
    "left_finger": ("prismatic", "fingers_link", "left_finger_link", (0, 0, 0), (0, 1, 0),
                    0.015, 0.037, 5, 1.0),
    "right_finger": ("prismatic", "fingers_link", "right_finger_link", (0, 0, 0), (0, 1, 0),
                     -0.037, -0.015, 5, 1.0),
    "ee_gripper": ("fixed", "fingers_link", "ee_gripper_link", (0.027575, 0, 0), None,
                   None, None, None, None),
}

HALF_PI = math.pi / 2
# link: (mass, com xyz, inertial rpy, (ixx, iyy, izz, ixy, ixz, iyz))
RX200_INERTIALS = {
    "base_link": (0.766135, (-0.0354389, -0.00335861, 0.0253408), (0, 0, HALF_PI),
                  (0.003353, 0.001357, 0.004111, -0.0001246, 1.106e-5, 0.0002103)),
    "shoulder_link": (0.257774, (-8.53644e-5, 1.7369e-5, 0.0132005), (0, 0, HALF_PI),
                      (0.0002663, 0.0004428, 0.0004711, 9e-10, 5.11e-8, 4.416e-7)),
    "upper_arm_link": (0.297782, (0.0119513, -0.000116923, 0.13943), (0, 0, HALF_PI),
                       (0.00171, 0.001631, 0.0001478, -9.773e-7, 2.0936e-6, 0.0002132)),
    "forearm_link": (0.258863, (0.114745, -9.38376e-5, 0), (0, 0, HALF_PI),
                     (0.001055, 6.421e-5, 0.001076, -1.8286e-6, 0, 0)),
    "wrist_link": (0.084957, (0.04236, -1.0411e-5, 0.010577), (0, 0, HALF_PI),
                   (3.082e-5, 2.822e-5, 3.152e-5, 1.91e-8, 2.3e-9, 2.5481e-6)),
    "gripper_link": (0.072885, (0.02163, 0, 0.01141), (0, 0, HALF_PI),
                     (2.537e-5, 1.836e-5, 1.674e-5, 0, 0, 4.34e-7)),
    "gripper_prop_link": (0.00434, (0.000846, -1.933e-6, 4.2e-5), (0, 0, HALF_PI),
                          (5.923e-7, 1.1156e-6, 5.743e-7, 0, 3.195e-7, -4e-10)),
    "gripper_bar_link": (0.034199, (0.009687, 5.66e-7, 0.004962), (0, 0, HALF_PI),
                         (7.4125e-6, 2.843e-5, 2.86e-5, -8e-10, -6e-10, -1.3889e-6)),
    "left_finger_link": (0.016246, (0.013816, 0, 0), (math.pi, math.pi, HALF_PI),
                         (4.731e-6, 1.5506e-6, 3.7467e-6, -4.56e-7, 0, 0)),
    "right_finger_link": (0.016246, (0.013816, 0, 0), (0, math.pi, HALF_PI),
                          (4.731e-6, 1.5506e-6, 3.7467e-6, 4.56e-7, 0, 0)),
}

IRB120_JOINTS = {
    "joint_1": ("revolute", "base_link", "link_1", (0, 0, 0), (0, 0, 1), -2.87979, 2.87979, 4.36332),
    "joint_2": ("revolute", "link_1", "link_2", (0, 0, 0.29), (0, 1, 0), -1.91986, 1.91986, 4.36332),
    "joint_3": ("revolute", "link_2", "link_3", (0, 0, 0.27), (0, 1, 0), -1.91986, 1.22173, 4.36332),
    "joint_4": ("revolute", "link_3", "link_4", (0, 0, 0.07), (1, 0, 0), -2.79253, 2.79253, 5.58505),
    "joint_5": ("revolute", "link_4", "link_5", (0.302, 0, 0), (0, 1, 0), -2.094395, 2.094395, 5.58505),
    "joint_6": ("revolute", "link_5", "link_6", (0.072, 0, 0), (1, 0, 0), -6.98132, 6.98132, 7.33038),
}
# name: (parent, child, xyz, rpy)
IRB120_FIXED = {
    "base_link-base": ("base_link", "base", (0, 0, 0), (0, 0, 0)),
    "joint_6-flange": ("link_6", "flange", (0, 0, 0), (0, 0, 0)),
    "link_6-tool0": ("flange", "tool0", (0, 0, 0), (0, HALF_PI, 0)),
}
# link: (mass, com, (ixx, ixy, ixz, iyy, iyz, izz))
IRB120_INERTIALS = {
    "base_link": (6.215, (-0.04204, 8.01e-5, 0.07964),
                  (0.0247272, -8.0784e-5, 0.00130902, 0.0491285, -8.0419e-6, 0.0472376)),
    "link_1": (3.067, (9.77e-5, -0.00012, 0.23841),
               (0.0142175, -1.28579e-5, -2.31364e-5, 0.0144041, 1.93404e-5, 0.0104533)),
    "link_2": (3.909, (0.00078, -0.00212, 0.10124),
               (0.0603111, 9.83431e-6, 5.72407e-5, 0.041569, -0.00050497, 0.0259548)),
    "link_3": (2.944, (0.02281, 0.00106, 0.05791),
               (0.00835606, -8.01545e-5, 0.00142884, 0.016713, -0.000182227, 0.0126984)),
    "link_4": (1.328, (0.2247, 0.00015, 0.00041),
               (0.00284661, -2.12765e-5, -1.6435e-5, 0.00401346, 1.31336e-5, 0.0052535)),
    "link_5": (0.546, (-0.00109, 3.68e-5, 6.22e-5),
               (0.000404891, 1.61943e-6, 8.46805e-7, 0.000892825, -1.51792e-8, 0.000815468)),
    "link_6": (0.137, (-0.00706, -0.00017, -1.32e-6), (0.001, 0, 0, 0.001, 0, 0.001)),
}


def floats(text: str | None) -> np.ndarray:
    return np.array([float(v) for v in (text or "0 0 0").split()])


def joints(urdf: str) -> dict[str, ET.Element]:
    return {j.get("name"): j for j in ET.fromstring(urdf).findall("joint")}


def links(urdf: str) -> dict[str, ET.Element]:
    return {link.get("name"): link for link in ET.fromstring(urdf).findall("link")}


def total_mass(urdf: str) -> float:
    return sum(float(m.get("value")) for m in ET.fromstring(urdf).iter("mass"))


def visual_bounds(link) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo, hi) of a yourdfpy link's primitive visuals in the link frame."""
    parts = []
    for visual in link.visuals:
        g = visual.geometry
        if g.box is not None:
            mesh = trimesh.creation.box(extents=g.box.size)
        elif g.cylinder is not None:
            mesh = trimesh.creation.cylinder(radius=g.cylinder.radius, height=g.cylinder.length, sections=64)
        elif g.sphere is not None:
            mesh = trimesh.creation.icosphere(radius=g.sphere.radius, subdivisions=3)
        else:
            raise AssertionError(f"{link.name}: non-primitive visual geometry")
        mesh.apply_transform(visual.origin if visual.origin is not None else np.eye(4))
        parts.append(mesh.bounds)
    assert parts, f"{link.name} has no visual geometry"
    bounds = np.array(parts)
    return bounds[:, 0].min(axis=0), bounds[:, 1].max(axis=0)
