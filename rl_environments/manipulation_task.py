"""The task layer of push and pick-and-place, for every arm: a table and an object next to the
robot, per-episode object and goal poses, end-effector (or joint) actions plus a gripper command,
Fetch-style observations, and the faults that end an episode.

What is the arm's comes from its robot layer (:class:`~rl_environments.arm_robot.ArmRobot`'s
constants): its top-down IK, finger joints, gripper controller and scene (table, cube, heights).
How the scene exists is the robot layer's too. In simulation the table and the object are spawned
through the node's SpawnEntity, placed through SetEntityState, and their poses come back with every
step's single StepRobot round trip (the robot env asks each step for its end-effector frame plus
``"<object entity>/object"`` and ``"<table entity>/table"``); on a real robot the object's pose
comes from a tracker's topic (:mod:`multiros.envs.real.scene`). Velocities
are finite differences of consecutive poses over the time between them.

Faults (each truncates the episode with ``info["truncated_reason"]``):

* ``"object_fell_off_table"``: the object's centre is ``fall_margin`` below the table top;
* ``"object_out_of_reach"``: it is farther than ``max_object_distance`` (horizontally) from the base;
* ``"sim_diverged"`` (also ``info["sim_diverged"] = True``, set by the env core): MuJoCo diverged in
  the step; the node restored the diverging entity at rest, and the next reset starts a clean episode.

The task is written batch-first (:mod:`multiros.envs.batch_task`): actions to commands
(:meth:`ManipulationTask.batch_act`) and the raw observation (:meth:`ManipulationTask.batch_raw_observation`)
for N envs in one numpy pass; the end-effector IK and the object's angular velocity go row by row.

Gripper commands: the action's last value in ``[-1, 1]`` maps linearly to the finger target,
-1 closed (``gripper_min``), +1 open (``gripper_max``); values outside ``[-1, 1]`` are clipped to
it (the action space's bounds, like every Box action).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import BatchTask
from multiros.robot_state import RobotStates
from multiros.utils.ros_markers import goal_marker
from rl_environments.arm_interface import ArmInterface
from rl_environments.manipulation import ObjectGoalSampler, quat_to_euler, rotation_velocities, yaw_quat
from rl_environments.reach_task import column, stack_rows

TaskKind = Literal["push", "pnp"]

#: Values of the raw observation besides the arm joints (Fetch's 25; see ManipulationTask.raw_observation).
FETCH_OBS_SIZE = 25


class ManipulationTask(BatchTask, ArmInterface):
    """Push / pick-and-place behaviour on top of an arm's robot env (see the module docstring).

    The task env calls :meth:`_setup_manipulation` after the robot env's constructor.
    """

    #: The task needs the scene (a table and an object): the robot layers read it (a real one takes
    #: the tracker's and the gripper's options then).
    SCENE_TASK: ClassVar[bool] = True
    task: TaskKind
    cfg: dict[str, Any]
    goal: np.ndarray
    prev_action: np.ndarray
    joint_targets: np.ndarray
    gripper_target: float
    _last: tuple[float, np.ndarray, np.ndarray, np.ndarray]
    _vel: np.ndarray  # EE linear, object linear, object angular velocity (9)
    _episode_start: bool
    ik_key: tuple[type, bytes, bytes]  # envs with equal keys solve a batch's IK in one call

    if TYPE_CHECKING:  # the simulated env core's, below the robot layer
        @property
        def sim_time(self) -> float: ...

        def frame_position(self, frame: str) -> np.ndarray: ...

        def frame_orientation(self, frame: str) -> np.ndarray: ...

    @staticmethod
    def manipulation_kwargs(cfg: Mapping[str, Any], kwargs: dict[str, Any]) -> dict[str, Any]:
        """Robot-env keyword arguments: the robot on the table (``robot_pos_z``) unless the user moved it."""
        kwargs.setdefault("robot_pos_z", float(cfg["robot_height"]))
        return kwargs

    def _setup_manipulation(self, cfg: Mapping[str, Any], task: TaskKind, *, ee_action_type: bool,
                            distance_threshold: float | None = None) -> None:
        self.cfg = dict(cfg)
        self.task = task
        self.chain = self.kinematic_chain()
        self.ee_action_type = bool(ee_action_type)
        self.delta_coeff = float(cfg["delta_coeff"])
        self.ee_delta_coeff = float(cfg["ee_delta_coeff"])
        self.tolerance = float(cfg["distance_threshold"] if distance_threshold is None else distance_threshold)
        self.min_joint_pos = np.asarray(cfg["min_joint_pos"], dtype=np.float64)
        self.max_joint_pos = np.asarray(cfg["max_joint_pos"], dtype=np.float64)
        ik_lower = np.maximum(self.chain.lower, self.min_joint_pos)
        ik_upper = np.minimum(self.chain.upper, self.max_joint_pos)
        self.ik = type(self).top_down_ik(ik_lower, ik_upper)
        # envs whose IKs are alike (same class and limits) solve a batch's targets in one call
        self.ik_key = (type(self.ik), ik_lower.tobytes(), ik_upper.tobytes())
        base = self.base_position
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
        n = len(self.ARM_JOINTS)
        n_act = (3 if self.ee_action_type else n) + 1
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n_act,), dtype=np.float32)
        self.prev_action = np.zeros(n_act)
        # -- the scene (the robot layer's: spawned in simulation, a tracker's poses on a robot)
        name = self.robot_name
        self.table_entity, self.object_entity = f"{name}_table", f"{name}_object"
        self.object_frame, self.table_frame = f"{self.object_entity}/object", f"{self.table_entity}/table"
        self.table_pose = np.asarray(cfg["table_center"], dtype=np.float64) + base
        self.goal = np.array([*self.sampler.goal_low, rest_z]) + base
        self.spawn_scene(self.table_entity, self.table_pose, self.object_entity,
                         np.array([*self.sampler.object_low, rest_z]) + base)
        self._track_reset()
        self.joint_targets = self.init_joint_pos.copy()
        self.gripper_target = self.gripper_range[1]

    # -- reset hooks (one env at a time) ----------------------------------------------------------------
    def _set_init_pose(self) -> None:
        self.move_to_initial_pose(self.ARM_JOINTS, self.init_joint_pos)
        self.open_fingers_at_reset(self.gripper_range[1])
        self.joint_targets = self.init_joint_pos.copy()
        self.gripper_target = self.gripper_range[1]
        type(self).command_grippers([self], [self.gripper_target])

    def _set_episode_init_params(self) -> None:
        rng = self.np_random
        base = self.base_position
        obj, yaw, goal = self.sampler.sample(rng)
        self.goal = goal + base
        self.place_object(obj + base, yaw_quat(yaw))
        self.prev_action = np.zeros(self.action_box.shape)
        self._episode_start = True  # velocities restart from the first observation
        self._show_goal()

    def _show_goal(self) -> None:
        """A sphere the size of the cube at the goal (rendered images, the viewer, RViz); once per episode."""
        to_world = getattr(self.connection, "to_world", None)  # a simulated robot's world slot
        at = self.goal if to_world is None else to_world(self.goal)
        marker = getattr(self, "_goal_marker", None)
        if marker is None:
            self._goal_marker = goal_marker(self.node, at, diameter=2 * self.half, ns=f"goal_{self.robot_name}")
        else:
            marker.update(position=at)

    # -- actions, batch-first -------------------------------------------------------------------------
    @classmethod
    def batch_act(cls, envs: Sequence[Any], actions: np.ndarray, states: RobotStates) -> None:
        """Joint targets (through each env's top-down IK for EE actions, row by row) and gripper targets
        of N envs; both sent to each robot."""
        current = cls.arm_positions_of(states)
        if all(env.ee_action_type for env in envs):
            ee = cls.ee_positions_of(envs, states)
            goals = np.clip(ee - stack_rows(envs, "base_position") + actions[:, :3] * column(envs, "ee_delta_coeff"),
                            stack_rows(envs, "ee_low"), stack_rows(envs, "ee_high"))
            key = envs[0].ik_key
            if all(env.ik_key == key for env in envs):  # one arm, one set of limits: one pass
                targets = envs[0].ik.solve_rows(goals, q0=current)
            else:
                targets = np.array([env.ik.solve(goals[j], q0=current[j]) for j, env in enumerate(envs)])
        elif not any(env.ee_action_type for env in envs):
            targets = current + actions[:, :-1] * stack_rows(envs, "delta_coeff")[:, None]
        else:
            ee = cls.ee_positions_of(envs, states)
            targets = np.array([
                env.ik.solve(np.clip(ee[j] - env.base_position + actions[j, :3] * env.ee_delta_coeff, env.ee_low,
                                     env.ee_high), q0=current[j])
                if env.ee_action_type else current[j] + actions[j, :-1] * env.delta_coeff
                for j, env in enumerate(envs)])
        targets = np.clip(targets, stack_rows(envs, "min_joint_pos"), stack_rows(envs, "max_joint_pos"))
        cls.set_arm_targets_of(envs, targets)
        for j, env in enumerate(envs):
            env.joint_targets = targets[j]
            lo, hi = env.gripper_range
            env.gripper_target = lo + (float(np.clip(actions[j, -1], -1.0, 1.0)) + 1.0) * 0.5 * (hi - lo)
            env.prev_action = actions[j]
        cls.command_grippers(envs, [env.gripper_target for env in envs])

    def _set_action(self, action: np.ndarray) -> None:
        type(self).batch_act([self], np.asarray(action, dtype=np.float64)[None], self.connection.states)

    # -- state, batch-first ---------------------------------------------------------------------------
    @classmethod
    def batch_raw_observation(cls, envs: Sequence[Any], states: RobotStates) -> np.ndarray:
        """N envs' raw observations (25 values plus the arm joints each: see :meth:`raw_observation`),
        and each env's velocity tracking moved on to this state."""
        ee = cls.ee_positions_of(envs, states)
        obj, obj_q = cls.object_poses_of(envs, states)
        vel = cls.batch_velocities(envs, cls.observation_time(envs, states), ee, obj, obj_q)
        finger_pos, finger_vel = cls.finger_states(states)
        arm = cls.arm_positions_of(states)
        return np.concatenate([ee, obj, obj - ee, finger_pos, quat_to_euler(obj_q), vel[:, 3:6],
                               vel[:, 6:9], vel[:, 0:3], finger_vel, arm], axis=1)

    @classmethod
    def finger_states(cls, states: RobotStates) -> tuple[np.ndarray, np.ndarray]:
        """Both fingers' positions and velocities (N x 2 each), in ``FINGER_JOINTS`` order.

        A driver may publish only the commanded finger: a ros2_control mimic joint has no hardware
        behind it (ROBOTIS' OpenManipulator-X driver declares ``gripper_right_joint`` in simulation
        only). The mimicking finger is then the commanded one times ``FINGER_MIMIC``, as its URDF
        ``<mimic>`` says; a simulation always has both.
        """
        where = {name: i for i, name in enumerate(states.names)}
        lead = cls.FINGER_JOINTS[0]
        if lead not in where:
            raise KeyError(f"the robot's joint states have no {lead!r}, the gripper's commanded finger "
                           f"(gripper.joints[0]); joints: {list(states.names)}")
        pos, vel = states.position[:, where[lead]], states.velocity[:, where[lead]]
        other = cls.FINGER_JOINTS[1] if len(cls.FINGER_JOINTS) > 1 else None
        if other is not None and other in where:
            return (np.stack([pos, states.position[:, where[other]]], axis=1),
                    np.stack([vel, states.velocity[:, where[other]]], axis=1))
        return np.stack([pos, cls.FINGER_MIMIC * pos], axis=1), np.stack([vel, cls.FINGER_MIMIC * vel], axis=1)

    @staticmethod
    def batch_velocities(envs: Sequence[Any], t: float, ee: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """N envs' EE linear, object linear and object angular velocities (N x 9) since each env's
        previous state (finite differences over the sim time between them, zero at an episode's first
        state); each env's tracking moves on to this state (time ``t``, rows of ``ee``, ``p``, ``q``)."""
        for j, env in enumerate(envs):
            if env._episode_start:
                env._episode_start = False
                env._last = (t, ee[j].copy(), p[j].copy(), q[j].copy())
                env._vel = np.zeros(9)
        vel = np.stack([env._vel for env in envs])
        moved = [j for j, env in enumerate(envs) if env._last[0] != t]
        if moved:
            dt = np.array([t - envs[j]._last[0] for j in moved])
            ee0, p0, q0 = (np.stack([envs[j]._last[k] for j in moved]) for k in (1, 2, 3))
            step = np.where(dt > 0, dt, 1.0)[:, None]  # rows with dt <= 0 are zeroed below
            new = np.concatenate([(ee[moved] - ee0) / step, (p[moved] - p0) / step,
                                  rotation_velocities(q0, q[moved], dt)], axis=1)
            new[dt <= 0] = 0.0
            vel[moved] = new
            for k, j in enumerate(moved):
                envs[j]._vel = new[k]
                envs[j]._last = (t, ee[j].copy(), p[j].copy(), q[j].copy())
        return vel

    def object_position(self) -> np.ndarray:
        """World position of the object's centre after the last step."""
        return type(self).object_poses_of([self], self.connection.states)[0][0].copy()

    def object_orientation(self) -> np.ndarray:
        """World orientation ``(w, x, y, z)`` of the object after the last step."""
        return type(self).object_poses_of([self], self.connection.states)[1][0].copy()

    def _track_reset(self) -> None:
        self._episode_start = False
        self._last = (type(self).observation_time([self], self.connection.states), self.ee_position(),
                      self.object_position(), self.object_orientation())
        self._vel = np.zeros(9)

    def raw_observation(self) -> np.ndarray:
        """Fetch's observation plus the arm joints (25 + arm joints values): EE position, object
        position, object minus EE, the two finger positions, object roll/pitch/yaw, object linear and
        angular velocity, EE velocity, finger velocities, arm joint positions."""
        return type(self).batch_raw_observation([self], self.connection.states)[0]

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of :meth:`raw_observation` (values outside are clipped into them)."""
        base = self.base_position
        reach = float(self.cfg["max_object_distance"]) + 0.1
        pos_lo = base + np.array([-reach, -reach, -0.5])
        pos_hi = base + np.array([reach, reach, 0.7])
        rel = np.array([2 * reach, 2 * reach, 1.2])
        g_lo, g_hi = sorted(self.gripper_range)  # a gripper may close towards either limit
        m_lo, m_hi = sorted((self.FINGER_MIMIC * g_lo, self.FINGER_MIMIC * g_hi))  # the mimicking finger's range
        lin, ang = float(self.cfg["max_linear_velocity"]), float(self.cfg["max_angular_velocity"])
        fvel = float(self.cfg["max_joint_vel"])
        low = np.concatenate([pos_lo, pos_lo, -rel, [g_lo - 0.005, m_lo - 0.005], -np.pi * np.ones(3),
                              -lin * np.ones(3), -ang * np.ones(3), -lin * np.ones(3), -fvel * np.ones(2),
                              self.chain.lower])
        high = np.concatenate([pos_hi, pos_hi, rel, [g_hi + 0.005, m_hi + 0.005], np.pi * np.ones(3),
                               lin * np.ones(3), ang * np.ones(3), lin * np.ones(3), fvel * np.ones(2),
                               self.chain.upper])
        assert low.shape == (FETCH_OBS_SIZE + len(self.ARM_JOINTS),)
        return low, high

    def check_faults(self, obj: np.ndarray | None = None) -> None:
        """Set ``info["truncated_reason"]`` when the object fell off the table or left the arm's reach
        (``obj``: the object's position after the step, read from the state when not given)."""
        type(self).batch_check_faults([self], np.asarray(self.object_position() if obj is None else obj)[None])

    @staticmethod
    def batch_check_faults(envs: Sequence[Any], obj: np.ndarray) -> None:
        """:meth:`check_faults` of N envs, their objects at the rows of ``obj`` (N x 3)."""
        base = stack_rows(envs, "base_position")
        rel = obj - base
        fell = rel[:, 2] + base[:, 2] < np.array([env.table_top - float(env.cfg["fall_margin"]) for env in envs])
        away = np.hypot(rel[:, 0], rel[:, 1]) > np.array([float(env.cfg["max_object_distance"]) for env in envs])
        for j in np.flatnonzero(fell | away).tolist():
            info = envs[j].info
            if not info.get("truncated_reason"):
                info["truncated_reason"] = "object_fell_off_table" if fell[j] else "object_out_of_reach"

    def object_goal_distance(self) -> float:
        """Distance of the object's centre from the goal."""
        return float(np.linalg.norm(self.object_position() - self.goal))
