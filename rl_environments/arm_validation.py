"""Scripted push and pick-and-place on a simulation node, per arm: proof that an arm's description,
kinematics, controllers and gripper can solve the tasks before a task env is built on them.

:class:`ArmScene` spawns one arm, its table and its cube (the description package's ``SCENE`` and
``mjcf/``) on a simulation node reached through :mod:`multiros.sim` (any
:class:`~multiros.sim.launch.SimulationConnection`), and steps it in lockstep with the
``StepRobot`` service: each control step sends the arm's group position controller the top-down IK
(:mod:`rl_environments.arm_ik`) of an end-effector target, the gripper's controller its finger
target, and reads back the end-effector and cube poses. :func:`run_push` and
:func:`run_pick_and_place` are closed-loop scripted policies on top of it; success is Fetch's (the
cube's centre within 5 cm of the goal at the episode's last step).

    from multiros.sim import launch
    from rl_environments.arm_validation import ArmScene, run_pick_and_place

    conn = launch.connect("composed", timestep=0.004)
    try:
        scene = ArmScene("ur5e", conn)
        print(run_pick_and_place(scene, seed=0))
    finally:
        conn.close()

The push is a real push: fingers closed, the pads' flat side behind the cube on the cube-goal line,
re-approaching when the cube drifts off it. The grasp aligns the fingers with the cube's faces (all
three arms have a wrist roll).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import import_module
from types import ModuleType
from typing import Any

import numpy as np

from multiros.sim.launch import SimulationConnection, robot_resource
from rl_environments.arm_ik import TopDownIK

__all__ = ["ARMS", "ArmScene", "ArmSpec", "EpisodeResult", "run_pick_and_place", "run_push"]

SUCCESS_DISTANCE = 0.05  # m, Fetch's distance_threshold


@dataclass(frozen=True)
class ArmSpec:
    """What the scripted scene needs to know about an arm beyond its description package.

    Attributes:
        name: the arm (``ARMS`` key), also its description package's stem.
        link_prefix: prefix of the description's link names (``"vx300s/"`` for Interbotix arms).
        pad_tip: how far the finger pads reach beyond the EE frame along the approach axis (m).
        pad_half_width: half the pads' extent across the closing direction, i.e. along a push (m).
        grasp_depth: the EE frame's height above the cube's centre when grasping (m; > 0 keeps the pad
            tips off the table).
        mimic: the second finger's position per unit of the commanded one (its URDF ``<mimic>``).
    """

    name: str
    link_prefix: str
    pad_tip: float
    pad_half_width: float
    grasp_depth: float = 0.0
    mimic: float = -1.0

    @property
    def arm_file_name(self) -> str:
        """The name of the arm's shipped arm file (its IK comes from there)."""
        return {"vx300s": "VX300S", "ur5e": "UR5e", "ned2": "NED2"}[self.name]

    @property
    def package(self) -> ModuleType:
        return import_module(f"rl_environments.robots.{self.name}_description")


ARMS: dict[str, ArmSpec] = {
    "vx300s": ArmSpec("vx300s", "vx300s/", pad_tip=0.0165, pad_half_width=0.016, grasp_depth=0.0),
    "ur5e": ArmSpec("ur5e", "", pad_tip=0.020, pad_half_width=0.011, grasp_depth=0.0),
    "ned2": ArmSpec("ned2", "", pad_tip=0.0146, pad_half_width=0.009, grasp_depth=0.004, mimic=1.0),
}


@dataclass
class EpisodeResult:
    """One scripted episode: ``success`` (cube within 5 cm of the goal at the end), the final
    distance, the control steps taken, and what happened (``events``: grasp retries, re-approaches)."""

    success: bool
    distance: float
    steps: int
    object_start: tuple[float, ...]
    goal: tuple[float, ...]
    events: list[str] = field(default_factory=list)


def _yaw_of(quat: np.ndarray) -> float:
    w, x, y, z = (float(v) for v in quat)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


class ArmScene:
    """One arm, its table and cube on a simulation node, stepped by end-effector targets.

    Args:
        arm: ``"vx300s"``, ``"ur5e"`` or ``"ned2"``.
        connection: the node (physics step: the connection's; 4 ms is what the packages' gains are
            tuned for).
        control_steps: physics steps per control step (10 x 4 ms = Fetch's 40 ms).
        max_speed: largest end-effector move per second (m/s).
    """

    def __init__(self, arm: str, connection: SimulationConnection, *, control_steps: int = 10,
                 max_speed: float = 0.25) -> None:
        if arm not in ARMS:
            raise ValueError(f"unknown arm {arm!r}; arms: {sorted(ARMS)}")
        self.spec = ARMS[arm]
        self.pkg = self.spec.package
        self.sim = connection.client
        self.control_steps = int(control_steps)
        self.max_speed = float(max_speed)
        self.scene: dict[str, Any] = dict(self.pkg.SCENE)
        from rl_environments.arm_registry import arm_of, top_down_ik_of

        self.ik: TopDownIK = top_down_ik_of(arm_of(self.spec.arm_file_name))
        self.entity = self.pkg.ROBOT_NAME
        self.base = np.array([0.0, 0.0, float(self.scene["robot_height"])])
        self.half = float(self.scene["object_half_size"])
        self.table_top = self.base[2] + float(self.scene["table_top"])
        self.ee_frame = self.spec.link_prefix + self.pkg.EE_LINK
        self.object_frame = "object/object"
        uri, text = robot_resource(urdf_pkg_name=self.pkg.PACKAGE_NAME, urdf_file_name=self.pkg.URDF_XACRO.name,
                                   controllers_list=list(self.pkg.SIM_CONTROLLERS))
        self.sim.spawn_entity(self.entity, uri=uri, resource_string=text, position=tuple(self.base), timeout_sec=60.0)
        pkg_uri = f"package://{self.pkg.PACKAGE_NAME}/mjcf"
        self.sim.spawn_entity("table", uri=f"{pkg_uri}/table.xml",
                              position=tuple(self.base + np.asarray(self.scene["table_center"])), timeout_sec=60.0)
        self.sim.spawn_entity("object", uri=f"{pkg_uri}/cube.xml",
                              position=tuple(self.base + (*self.scene["object_xy_min"], self.half)), timeout_sec=60.0)
        self.q = self.ik.solve(self.scene["init_ee_position"])
        self.gripper = float(self.pkg.GRIPPER_OPEN)
        self.ee_target = np.asarray(self.scene["init_ee_position"], dtype=np.float64)
        self.state: Any = None

    # -- state ------------------------------------------------------------------------------
    @property
    def ee(self) -> np.ndarray:
        """EE position in the base frame after the last step."""
        return self.state.frame_positions[0] - self.base

    @property
    def cube(self) -> np.ndarray:
        """Cube centre in the base frame after the last step."""
        return self.state.frame_positions[1] - self.base

    @property
    def cube_yaw(self) -> float:
        return _yaw_of(self.state.frame_orientations[1])

    @property
    def finger(self) -> float:
        """The commanded finger joint's position."""
        return float(self.state.position[self.state.names.index(self.pkg.GRIPPER_JOINT)])

    # -- episode ----------------------------------------------------------------------------
    def reset(self, object_xy: np.ndarray, object_yaw: float) -> None:
        """Arm at the start pose (top-down above the table, gripper open), cube at ``object_xy``."""
        self.q = self.ik.solve(self.scene["init_ee_position"])
        self.ee_target = np.asarray(self.scene["init_ee_position"], dtype=np.float64)
        self.gripper = float(self.pkg.GRIPPER_OPEN)
        names = [*self.pkg.ARM_JOINTS, *self.pkg.FINGER_JOINTS]
        positions = [*self.q, self.gripper, self.spec.mimic * self.gripper]
        self.sim.set_robot_joint_state(self.entity, names, positions, velocities=[0.0] * len(names))
        self.sim.set_entity_pose("table", tuple(self.base + np.asarray(self.scene["table_center"])))
        pos = self.base + (float(object_xy[0]), float(object_xy[1]), self.half)
        self.sim.set_entity_pose("object", tuple(pos), (math.cos(object_yaw / 2), 0.0, 0.0, math.sin(object_yaw / 2)))
        self.step(self.ee_target, None, self.gripper)
        for _ in range(5):  # let the cube settle on the table
            self.step(self.ee_target, None, self.gripper)

    def step(self, target: np.ndarray, yaw: float | None, gripper: float) -> None:
        """One control step towards ``target`` (EE speed-limited), fingers to ``gripper``."""
        dt = self.control_steps * 0.004
        delta = np.asarray(target, dtype=np.float64) - self.ee_target
        limit = self.max_speed * dt
        norm = float(np.linalg.norm(delta))
        self.ee_target = self.ee_target + (delta * (limit / norm) if norm > limit else delta)
        self.q = self.ik.solve(self.ee_target, yaw, q0=self.q)
        self.gripper = float(gripper)
        commands = {self.pkg.ARM_POSITION_CONTROLLER: self.q, self.pkg.GRIPPER_POSITION_CONTROLLER: [self.gripper]}
        self.state = self.sim.step_robot(self.entity, commands, steps=self.control_steps,
                                         frames=[self.ee_frame, self.object_frame])

    def sample(self, rng: np.random.Generator, task: str) -> tuple[np.ndarray, float, np.ndarray]:
        """Cube start ``(x, y)``, its yaw, and a goal (base frame), Fetch-style: goals on the table
        for push, lifted half of the time for pick-and-place; cube and goal >= 8 cm apart."""
        s = self.scene
        for _ in range(1000):
            obj = rng.uniform(s["object_xy_min"], s["object_xy_max"])
            goal = np.array([*rng.uniform(s["goal_xy_min"], s["goal_xy_max"]), float(s["table_top"]) + self.half])
            if task == "pnp" and rng.uniform() < 0.5:
                goal[2] += rng.uniform(0.0, float(s["target_height_max"]))
            if np.linalg.norm(goal[:2] - obj) >= 0.08:
                yaw = float(math.atan2(obj[1], obj[0]) + rng.uniform(-0.3, 0.3))
                return obj, yaw, goal
        raise RuntimeError("no cube/goal pair 8 cm apart: widen the scene's object and goal boxes")


def _face_yaw(cube_yaw: float, near: float) -> float:
    """The closing direction square to the cube's faces closest to ``near`` (cube symmetry: pi/2)."""
    k = round((near - cube_yaw) / (math.pi / 2))
    return cube_yaw + k * math.pi / 2


def _radial_yaw(xy: np.ndarray) -> float:
    return math.atan2(float(xy[1]), float(xy[0])) + math.pi / 2


def run_pick_and_place(scene: ArmScene, seed: int, max_steps: int = 200) -> EpisodeResult:
    """Grasp the cube from above, lift it, carry it to the goal and hold it there."""
    rng = np.random.default_rng(seed)
    obj_xy, obj_yaw, goal = scene.sample(rng, "pnp")
    scene.reset(obj_xy, obj_yaw)
    pkg, spec, half = scene.pkg, scene.spec, scene.half
    opened, closed = float(pkg.GRIPPER_OPEN), float(pkg.GRIPPER_CLOSED)
    rest_z = scene.cube[2]
    clear = rest_z + half + spec.pad_tip + 0.04  # pads 4 cm above the cube's top
    grasp_z = rest_z + spec.grasp_depth
    carry_z = max(goal[2], rest_z) + 0.05
    events: list[str] = []
    phase, wait, yaw = "above", 0, _face_yaw(scene.cube_yaw, _radial_yaw(scene.cube[:2]))
    offset = np.zeros(3)
    steps = 0
    for steps in range(1, max_steps + 1):
        cube = scene.cube
        if phase == "above":
            yaw = _face_yaw(scene.cube_yaw, _radial_yaw(cube[:2]))
            target, grip = np.array([cube[0], cube[1], clear]), opened
            if np.linalg.norm(scene.ee - target) < 0.01 and abs(scene.finger - opened) < 0.003:
                phase = "descend"
        elif phase == "descend":
            target, grip = np.array([cube[0], cube[1], grasp_z]), opened
            if np.linalg.norm(scene.ee - target) < 0.004:
                phase, wait = "close", 0
        elif phase == "close":
            target, grip = scene.ee_target, closed
            wait += 1
            if wait >= 12:
                if abs(scene.finger - closed) < 0.002:  # closed on nothing: missed
                    events.append(f"missed grasp at step {steps}")
                    phase = "reopen"
                else:
                    offset = scene.ee - cube
                    phase = "lift"
        elif phase == "reopen":
            target, grip = np.array([scene.ee[0], scene.ee[1], clear]), opened
            if scene.ee[2] > clear - 0.01:
                phase = "above"
        else:  # lift, carry over the goal, lower onto it, hold; the cube hangs at -offset from the EE
            grip = closed
            if phase == "lift":
                target = np.array([scene.ee_target[0], scene.ee_target[1], carry_z + offset[2]])
                if scene.ee[2] > carry_z + offset[2] - 0.01:
                    phase = "carry"
            elif phase == "carry":
                target = np.array([goal[0] + offset[0], goal[1] + offset[1], carry_z + offset[2]])
                if np.linalg.norm(scene.ee[:2] - target[:2]) < 0.01:
                    phase = "lower"
            else:
                target = goal + offset
            if np.linalg.norm(scene.ee - cube - offset) > 0.03:  # it slipped out
                events.append(f"dropped at step {steps}")
                phase = "reopen"
        scene.step(target, yaw, grip)
    distance = float(np.linalg.norm(scene.cube - goal))
    return EpisodeResult(distance <= SUCCESS_DISTANCE, distance, steps, tuple(obj_xy), tuple(goal), events)


def run_push(scene: ArmScene, seed: int, max_steps: int = 200) -> EpisodeResult:
    """Push the cube over the table to the goal with the closed fingers' flat side."""
    rng = np.random.default_rng(seed)
    obj_xy, obj_yaw, goal = scene.sample(rng, "push")
    scene.reset(obj_xy, obj_yaw)
    spec, half = scene.spec, scene.half
    closed = float(scene.pkg.GRIPPER_CLOSED)
    rest_z = scene.cube[2]
    push_z = max(rest_z, scene.table_top - scene.base[2] + spec.pad_tip + 0.004)
    clear = rest_z + half + spec.pad_tip + 0.04
    standoff = half + spec.pad_half_width + 0.002
    events: list[str] = []
    phase = "behind"
    steps = 0
    for steps in range(1, max_steps + 1):
        cube = scene.cube
        to_goal = goal[:2] - cube[:2]
        dist = float(np.linalg.norm(to_goal))
        direction = to_goal / max(dist, 1e-9)
        yaw = math.atan2(direction[1], direction[0]) + math.pi / 2  # fingers close across the push
        behind = cube[:2] - direction * (standoff + 0.03)
        if phase == "behind":
            target = np.array([*behind, clear])
            if np.linalg.norm(scene.ee - target) < 0.01:
                phase = "down"
        elif phase == "down":
            target = np.array([*behind, push_z])
            if np.linalg.norm(scene.ee - target) < 0.005:
                phase = "push"
        elif phase == "push":
            # Keep the EE on the cube-goal line, just touching the cube, and advance slowly.
            rel = scene.ee[:2] - cube[:2]
            line_err = float(direction[0] * rel[1] - direction[1] * rel[0])
            along = float(np.dot(cube[:2] - scene.ee[:2], direction))
            if dist < 0.01:
                phase = "retreat"
                target = scene.ee_target
            elif abs(line_err) > 0.015 or along < 0.0 or along > standoff + 0.05:
                events.append(f"re-approach at step {steps}")
                phase = "lift"
                target = scene.ee_target
            else:
                advance = float(np.clip(0.4 * dist, 0.002, 0.012))  # slow down near the goal: no overshoot
                target = np.array([*(cube[:2] - direction * standoff + direction * advance), push_z])
        elif phase == "lift":
            target = np.array([scene.ee[0], scene.ee[1], clear])
            if scene.ee[2] > clear - 0.01:
                phase = "behind"
        else:  # retreat: back off and up, leave the cube where it is
            target = np.array([*(cube[:2] - direction * (standoff + 0.04)), clear])
            if dist > 0.02:
                phase = "behind"
        scene.step(target, yaw, closed)
    distance = float(np.linalg.norm(scene.cube - goal))
    return EpisodeResult(distance <= SUCCESS_DISTANCE, distance, steps, tuple(obj_xy), tuple(goal), events)
