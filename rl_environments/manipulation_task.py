"""The task layer of push and pick-and-place: a table and an object spawned through the node's
SpawnEntity, their poses returned by every step's single StepRobot round trip, per-episode object
and goal poses set through SetEntityState, end-effector (or joint) actions plus a gripper
command, Fetch-style observations, and the faults that end an episode.

How the object's pose comes back: the robot env asks each step for its end-effector frame plus
``"<object entity>/object"`` and ``"<table entity>/table"`` (another entity's frame, which the
node's frame sets resolve); no extra service call per step. Velocities are finite differences of
consecutive poses over the sim time between them.

Faults (each truncates the episode with ``info["truncated_reason"]``):

* ``"object_fell_off_table"``: the object's centre is ``fall_margin`` below the table top;
* ``"object_out_of_reach"``: it is farther than ``max_object_distance`` (horizontally) from the base;
* ``"sim_diverged"`` (also ``info["sim_diverged"] = True``): MuJoCo diverged in the step; the node
  restored the diverging entity at rest, and the next reset starts a clean episode.

Gripper commands: the action's last value in ``[-1, 1]`` maps linearly to the finger target,
-1 closed (``gripper_min``), +1 open (``gripper_max``); values outside ``[-1, 1]`` are clipped to
it (the action space's bounds, like every Box action).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
from gymnasium import spaces

from multiros.sim.client import SimulationServiceError
from multiros.utils.ros_markers import goal_marker
from rl_environments.manipulation import ObjectGoalSampler, RX200TopDownIK, quat_to_euler, rotation_velocity, yaw_quat

TaskKind = Literal["push", "pnp"]

_UNSTABLE = 104  # uniros_interfaces StepRobot UNSTABLE
TABLE_URI = "package://rx200_description/mjcf/table.xml"
OBJECT_URI = "package://rx200_description/mjcf/cube.xml"
GRIPPER_CONTROLLER = "gripper_controller"
FINGER_JOINTS = ("left_finger", "right_finger")
OBS_SIZE = 30  # see ManipulationTask.raw_observation


class ManipulationTask:
    """Push / pick-and-place behaviour on top of the RX200 robot env (see the module docstring).

    The task env calls :meth:`_setup_manipulation` after the robot env's constructor.
    """

    task: TaskKind

    @staticmethod
    def manipulation_kwargs(cfg: Mapping[str, Any], kwargs: dict[str, Any]) -> dict[str, Any]:
        """Robot-env keyword arguments: the robot on the table (``robot_pos_z``) unless the user moved it."""
        kwargs.setdefault("robot_pos_z", float(cfg["robot_height"]))
        return kwargs

    def _setup_manipulation(self, cfg: Mapping[str, Any], task: TaskKind, *, ee_action_type: bool,
                            distance_threshold: float | None = None) -> None:
        self.cfg = dict(cfg)
        self.task = task
        self.chain = self.kinematic_chain()  # type: ignore[attr-defined]
        self.ee_action_type = bool(ee_action_type)
        self.delta_coeff = float(cfg["delta_coeff"])
        self.ee_delta_coeff = float(cfg["ee_delta_coeff"])
        self.tolerance = float(cfg["distance_threshold"] if distance_threshold is None else distance_threshold)
        self.min_joint_pos = np.asarray(cfg["min_joint_pos"], dtype=np.float64)
        self.max_joint_pos = np.asarray(cfg["max_joint_pos"], dtype=np.float64)
        self.ik = RX200TopDownIK(np.maximum(self.chain.lower, self.min_joint_pos),
                                 np.minimum(self.chain.upper, self.max_joint_pos))
        base = self.base_position  # type: ignore[attr-defined]
        self.ee_low = np.asarray(cfg["position_ee_min"], dtype=np.float64)
        self.ee_high = np.asarray(cfg["position_ee_max"], dtype=np.float64)
        self.gripper_range = (float(cfg["gripper_min"]), float(cfg["gripper_max"]))
        self.table_top = float(cfg["table_top"]) + base[2]
        self.half = float(cfg["object_half_size"])
        rest_z = float(cfg["table_top"]) + self.half
        self.sampler = ObjectGoalSampler(
            tuple(cfg["object_xy_min"]), tuple(cfg["object_xy_max"]), tuple(cfg["goal_xy_min"]),
            tuple(cfg["goal_xy_max"]), rest_z,
            air_probability=float(cfg["target_in_the_air"]) if task == "pnp" else 0.0,
            air_height=float(cfg["target_height_max"]), min_distance=float(cfg["min_object_goal_distance"]),
            yaw_range=float(cfg["object_yaw_range"]),
        )
        self.init_joint_pos = self.ik.solve(np.asarray(cfg["init_ee_position"], dtype=np.float64))
        n = len(self.ARM_JOINTS)  # type: ignore[attr-defined]
        n_act = (3 if self.ee_action_type else n) + 1
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n_act,), dtype=np.float32)
        self.prev_action = np.zeros(n_act)
        # -- the scene: table and object through SpawnEntity, their root bodies as extra frames
        name = self.robot_name  # type: ignore[attr-defined]
        self.table_entity, self.object_entity = f"{name}_table", f"{name}_object"
        self.table_pose = np.asarray(cfg["table_center"], dtype=np.float64) + base
        self._spawn_object(self.table_entity, TABLE_URI, self.table_pose)
        self.goal = np.array([*self.sampler.goal_low, rest_z]) + base
        self._spawn_object(self.object_entity, OBJECT_URI, np.array([*self.sampler.object_low, rest_z]) + base)
        self.object_frame, self.table_frame = f"{self.object_entity}/object", f"{self.table_entity}/table"
        self.frames = (*self.frames, self.object_frame, self.table_frame)  # type: ignore[has-type]
        self._frame_index = {}  # rebuilt from self.frames by the next state
        self._refresh_state(0)  # type: ignore[attr-defined]
        self._track_reset()
        self.joint_targets = self.init_joint_pos.copy()
        self.gripper_target = self.gripper_range[1]

    def _spawn_object(self, entity: str, uri: str, position: np.ndarray) -> None:
        slot = self._slot if self._slot is not None else 0.0  # type: ignore[attr-defined]
        self.sim.spawn_entity(entity, uri=uri, position=tuple(position + slot),  # type: ignore[attr-defined]
                              timeout_sec=max(self.timeout_sec, 30.0))  # type: ignore[attr-defined]

    def _place(self, entity: str, position: np.ndarray, quat: np.ndarray) -> None:
        """SetEntityState: the pose (and, on Jazzy/Kilted definitions, zero twist)."""
        slot = self._slot if self._slot is not None else 0.0  # type: ignore[attr-defined]
        self.sim.set_entity_pose(entity, tuple(position + slot), tuple(quat))  # type: ignore[attr-defined]

    # -- hooks ------------------------------------------------------------------------------
    def _set_init_pose(self) -> None:
        self.move_to_initial_pose(self.ARM_JOINTS, self.init_joint_pos)  # type: ignore[attr-defined]
        self.set_joint_positions(["left_finger"], [self.gripper_range[1]])  # type: ignore[attr-defined]
        self.joint_targets = self.init_joint_pos.copy()
        self.gripper_target = self.gripper_range[1]
        self.send_command(GRIPPER_CONTROLLER, [self.gripper_target])  # type: ignore[attr-defined]

    def _set_episode_init_params(self) -> None:
        rng = self.np_random  # type: ignore[attr-defined]
        base = self.base_position  # type: ignore[attr-defined]
        obj, yaw, goal = self.sampler.sample(rng)
        self.goal = goal + base
        if np.linalg.norm(self.frame_position(self.table_frame) - self.table_pose) > 1e-3:  # type: ignore[attr-defined]
            self._place(self.table_entity, self.table_pose, np.array([1.0, 0, 0, 0]))  # knocked (shared world)
        self._place(self.object_entity, obj + base, yaw_quat(yaw))
        self.prev_action = np.zeros(self.action_space.shape)
        self._episode_start = True  # velocities restart from the first observation
        self._show_goal()

    def _show_goal(self) -> None:
        """A sphere the size of the cube at the goal (rendered images, the viewer, RViz); once per episode."""
        slot = self._slot if self._slot is not None else 0.0  # type: ignore[attr-defined]
        marker = getattr(self, "_goal_marker", None)
        if marker is None:
            self._goal_marker = goal_marker(self.node, self.goal + slot, diameter=2 * self.half,  # type: ignore[attr-defined]
                                            ns=f"goal_{self.robot_name}")  # type: ignore[attr-defined]
        else:
            marker.update(position=self.goal + slot)

    def _set_action(self, action: np.ndarray) -> None:
        current = self.arm_positions()  # type: ignore[attr-defined]
        if self.ee_action_type:
            base = self.base_position  # type: ignore[attr-defined]
            target = self.ee_position() - base + action[:3] * self.ee_delta_coeff  # type: ignore[attr-defined]
            targets = self.ik.solve(np.clip(target, self.ee_low, self.ee_high))
        else:
            targets = current + action[:-1] * self.delta_coeff
        self.joint_targets = np.clip(targets, self.min_joint_pos, self.max_joint_pos)
        self.set_arm_targets(self.joint_targets)  # type: ignore[attr-defined]
        lo, hi = self.gripper_range
        self.gripper_target = lo + (float(np.clip(action[-1], -1.0, 1.0)) + 1.0) * 0.5 * (hi - lo)
        self.send_command(GRIPPER_CONTROLLER, [self.gripper_target])  # type: ignore[attr-defined]
        self.prev_action = np.asarray(action, dtype=np.float64)

    def _advance(self) -> None:
        """The step's round trip; a diverging contact ends the episode (truncated) instead of raising."""
        try:
            super()._advance()  # type: ignore[misc]
        except SimulationServiceError as exc:
            if exc.code != _UNSTABLE:
                raise
            self.info["sim_diverged"] = True
            self.info["sim_error"] = exc.message
            self.info["truncated_reason"] = "sim_diverged"
            self._refresh_state(0)  # type: ignore[attr-defined]

    # -- state --------------------------------------------------------------------------------
    def object_position(self) -> np.ndarray:
        """World position of the object's centre after the last step."""
        return self.frame_position(self.object_frame)  # type: ignore[attr-defined]

    def object_orientation(self) -> np.ndarray:
        """World orientation ``(w, x, y, z)`` of the object after the last step."""
        return self.frame_orientation(self.object_frame)  # type: ignore[attr-defined]

    def _track_reset(self) -> None:
        self._last = (self.sim_time, self.ee_position(), self.object_position(),  # type: ignore[attr-defined]
                      self.object_orientation())
        self._vel = (np.zeros(3), np.zeros(3), np.zeros(3))

    def _velocities(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """EE linear, object linear and object angular velocity since the previous state."""
        t = self.sim_time  # type: ignore[attr-defined]
        t0, ee0, p0, q0 = self._last
        if t != t0:
            dt = t - t0
            ee, p, q = self.ee_position(), self.object_position(), self.object_orientation()  # type: ignore[attr-defined]
            self._vel = ((ee - ee0) / dt, (p - p0) / dt, rotation_velocity(q0, q, dt)) if dt > 0 else (
                np.zeros(3), np.zeros(3), np.zeros(3))
            self._last = (t, ee, p, q)
        return self._vel

    def raw_observation(self) -> np.ndarray:
        """Fetch's observation plus the arm joints (30 values): EE position, object position, object
        minus EE, the two finger positions, object roll/pitch/yaw, object linear and angular velocity,
        EE velocity, finger velocities, arm joint positions."""
        if getattr(self, "_episode_start", False):
            self._episode_start = False
            self._track_reset()
        ee, obj = self.ee_position(), self.object_position()  # type: ignore[attr-defined]
        ee_vel, obj_vel, obj_rot_vel = self._velocities()
        fingers = self.joint_positions(FINGER_JOINTS)  # type: ignore[attr-defined]
        finger_vel = self.joint_velocities(FINGER_JOINTS)  # type: ignore[attr-defined]
        return np.concatenate([ee, obj, obj - ee, fingers, quat_to_euler(self.object_orientation()), obj_vel,
                               obj_rot_vel, ee_vel, finger_vel, self.arm_positions()])  # type: ignore[attr-defined]

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of :meth:`raw_observation` (values outside are clipped into them)."""
        base = self.base_position  # type: ignore[attr-defined]
        reach = float(self.cfg["max_object_distance"]) + 0.1
        pos_lo = base + np.array([-reach, -reach, -0.5])
        pos_hi = base + np.array([reach, reach, 0.7])
        rel = np.array([2 * reach, 2 * reach, 1.2])
        g_lo, g_hi = self.gripper_range
        lin, ang = float(self.cfg["max_linear_velocity"]), float(self.cfg["max_angular_velocity"])
        fvel = float(self.cfg["max_joint_vel"])
        low = np.concatenate([pos_lo, pos_lo, -rel, [g_lo - 0.005, -g_hi - 0.005], -np.pi * np.ones(3),
                              -lin * np.ones(3), -ang * np.ones(3), -lin * np.ones(3), -fvel * np.ones(2),
                              self.chain.lower])
        high = np.concatenate([pos_hi, pos_hi, rel, [g_hi + 0.005, -g_lo + 0.005], np.pi * np.ones(3),
                               lin * np.ones(3), ang * np.ones(3), lin * np.ones(3), fvel * np.ones(2),
                               self.chain.upper])
        assert low.shape == (OBS_SIZE,)
        return low, high

    def check_faults(self) -> None:
        """Set ``info["truncated_reason"]`` when the object fell off the table or left the arm's reach."""
        if self.info.get("truncated_reason"):  # type: ignore[attr-defined]
            return
        obj = self.object_position() - self.base_position  # type: ignore[attr-defined]
        if obj[2] + self.base_position[2] < self.table_top - float(self.cfg["fall_margin"]):  # type: ignore[attr-defined]
            self.info["truncated_reason"] = "object_fell_off_table"  # type: ignore[attr-defined]
        elif float(np.hypot(obj[0], obj[1])) > float(self.cfg["max_object_distance"]):
            self.info["truncated_reason"] = "object_out_of_reach"  # type: ignore[attr-defined]

    def object_goal_distance(self) -> float:
        """Distance of the object's centre from the goal."""
        return float(np.linalg.norm(self.object_position() - self.goal))
