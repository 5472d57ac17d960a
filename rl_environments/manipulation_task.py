"""Push and pick-and-place, for every arm with a gripper, configured per arm by its arm file's
``manipulation:`` section (:mod:`rl_environments.arm_file`; a ``config_file=`` of your own has the keys
under ``<robot name>:``), checked by :func:`~rl_environments.task_config.manipulation_schema`.

## Scene
The arm stands on a table with a cube (made from the section's sizes, or the arm file's ``scene:``
MJCF); both are free bodies. Each reset puts the arm at its start pose (the gripper above the table,
pointing down, open), samples the cube's start (on the table, yawed within ``object_yaw_range`` of
square to the fingers) and the goal, never closer than ``min_object_goal_distance``, and sets the cube
there. Push goals lie on the table; pick-and-place goals are lifted up to ``target_height_max`` with
probability ``target_in_the_air`` (Fetch's 0.5). In simulation the table and the cube are spawned
through the node's SpawnEntity and placed through SetEntityState, and their poses come back with every
step's single StepRobot round trip; on a real robot the object's pose comes from a tracker's topic
(:mod:`multiros.envs.real.scene`) and an episode starts with the object where it lies.

## Action space
``Box(-1, 1, (4,))`` (default, ``ee_action_type=True``): end-effector deltas ``action[:3] *
ee_delta_coeff`` in the base frame, the gripper kept pointing down by the arm's top-down IK, targets
clipped into the workspace box (the finger tips stay above the table); ``action[3]`` the gripper, -1
closed (``gripper_min``), +1 open (``gripper_max``), clipped to ``[-1, 1]``. ``ee_action_type=False``:
``Box(-1, 1, (n + 1,))``, n joint deltas ``* delta_coeff`` and the gripper.

## Observation space
Goal envs: ``Dict(observation=Box(25 + n), achieved_goal=Box(3), desired_goal=Box(3))``. ``observation``
(Fetch's 25 values plus the n arm joints): EE position, object position, object minus EE, the two finger
joints, object roll/pitch/yaw, object linear and angular velocity, EE velocity, finger velocities, arm
joints. ``achieved_goal`` is the object's position, ``desired_goal`` the goal. Plain envs: ``Box(31 + n)``:
the same values, the goal, and goal minus object. ``observe_command=True`` adds three values after the arm
joints (:class:`ManipulationOptions`). World frame throughout; velocities are finite
differences of consecutive poses over the time between them; values are clipped into the declared
bounds. Camera observations: ``rgb_obs_only``, ``rgb_plus_normal_obs``,
``rgb_plus_depth_plus_normal_obs`` (:mod:`rl_environments.camera_obs`).

## Rewards
``reward_type="sparse"`` (goal envs' default): 0 when the object is within ``distance_threshold`` (5 cm,
Fetch's) of the goal, else -1; ``"dense"`` (plain envs' default): ``-distance(object, goal)``.
``compute_reward`` is vectorised for HER.

## Episode end
50 steps of 40 ms (Fetch's), truncated. Success does not end the episode (``terminate_on_success=False``,
Fetch's convention): ``is_success`` of the last step says whether the object is *at* the goal. Faults
truncate early with ``info["truncated_reason"]``: ``"object_fell_off_table"`` (the object's centre
``fall_margin`` below the table top), ``"object_out_of_reach"`` (farther than ``max_object_distance``
from the base), ``"sim_diverged"`` (MuJoCo diverged; the node restored the entity at rest).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, TypeVar, cast

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.envs.connection import SceneEntity
from multiros.robot_state import RobotStates
from rl_environments.arm import Arm
from rl_environments.arm_task import ArmTask, TaskHost, TaskOptions, column, load_arm_task_config, rows
from rl_environments.manipulation import (
    ObjectGoalSampler,
    is_success,
    object_reward,
    quat_to_euler,
    rotation_velocities,
    yaw_quat,
)
from rl_environments.reach import RewardType, goal_distance, parse_reward_type, reward_from_distance
from rl_environments.task_config import SCENE_KEYS, manipulation_schema

__all__ = ["EPISODE_STEPS", "FETCH_OBS_SIZE", "ManipulationOptions", "ManipulationTask", "ObjectTask",
           "PickAndPlaceTask", "PushTask"]

TaskT = TypeVar("TaskT", bound="ObjectTask")

#: Values of the raw observation besides the arm joints (Fetch's 25; see ManipulationTask.raw_observation).
FETCH_OBS_SIZE = 25
EPISODE_STEPS = 50


@dataclasses.dataclass(frozen=True)
class ManipulationOptions(TaskOptions):
    """Push's and pick-and-place's keyword arguments (the common ones: :class:`~rl_environments.arm_task.TaskOptions`).

    Attributes:
        ee_action_type: end-effector deltas + gripper (True, the default) or joint deltas + gripper.
        distance_threshold: success distance in metres (default: the config's, 0.05).
        terminate_on_success: end the episode on success (default False, as Fetch).
        command_lead: how far the commanded end effector (m; rad per joint for joint actions) may run ahead
            of the measured one. 0 (the default, Fetch's): each action moves from where the arm is
            measured. Above 0: each action moves on from the last command, kept within ``command_lead``
            of the measured arm, so commands add up through a servo's lag, latency and dead band (on a
            real arm the measured pose trails the command; from it, a lagging arm moves a fraction of
            each action and a late one chases old readings).
        observe_command: three more observation values after the arm joints (before a plain env's goal):
            the last commanded end effector minus the measured one (m, base frame, zeros before the
            episode's first action; end-effector actions only): what a lagging or late servo has still
            to move, which the measured pose alone does not say.
    """

    ee_action_type: bool = True
    distance_threshold: float | None = None
    terminate_on_success: bool = False
    command_lead: float = 0.0
    observe_command: bool = False

    def __post_init__(self) -> None:
        lead = self.command_lead
        if isinstance(lead, bool) or not isinstance(lead, (int, float)) or not 0.0 <= lead <= 1.0:
            raise ValueError(f"command_lead must be a number in [0, 1] (m, or rad for joint actions); got {lead!r}")
        if not isinstance(self.observe_command, bool):
            raise ValueError(f"observe_command must be true or false; got {self.observe_command!r}")
        if self.observe_command and not self.ee_action_type:
            raise ValueError("observe_command needs end-effector actions (ee_action_type=True): joint actions "
                             "command no end effector")


COMMAND_OFFSET_BOUND = 0.25  # m, the observed command offset's bound (``observe_command``)


def _command_reference(tasks: Sequence[ObjectTask], measured: np.ndarray, last: str) -> np.ndarray:
    """Where N envs' deltas move from: the ``measured`` rows, or, for an env with a ``command_lead``, its
    last command (the task's value ``last``; NaN: none yet) within the lead of them."""
    if not any(task.command_lead for task in tasks):
        return measured
    lead = column(tasks, "command_lead")
    return measured + np.clip(np.nan_to_num(rows(tasks, last) - measured), -lead, lead)


class ObjectTask(ArmTask):
    """A task with an object on a table next to the arm: the scene, the object's pose and velocities, the
    per-episode object and goal, and the faults that end an episode (push, pick-and-place, slide)."""

    SCENE = True
    options: ManipulationOptions
    reward_type: RewardType
    goal_low: np.ndarray
    goal_high: np.ndarray
    table_top: float
    half: float
    _last: tuple[float, np.ndarray, np.ndarray, np.ndarray]
    _vel: np.ndarray  # EE linear, object linear, object angular velocity (9)
    _episode_start: bool

    @classmethod
    def side_defaults(cls, cfg: Mapping[str, Any], kwargs: dict[str, Any]) -> None:
        kwargs.setdefault("robot_pos_z", float(cfg["robot_height"]))  # the arm on its table

    def setup_tool(self) -> None:
        """What an end-effector task keeps from its options and config: the reward, the success distance, the
        joint range, the arm's top-down IK within it, the end effector's box and the table's height."""
        cfg, options = self.cfg, self.options
        self.reward_type = parse_reward_type(options.reward_type or ("sparse" if self.goal_conditioned else "dense"))
        self.chain = self.arm.chain
        self.ee_action_type = bool(options.ee_action_type)
        self.ee_delta_coeff = float(cfg["ee_delta_coeff"])
        self.tolerance = float(cfg["distance_threshold"] if options.distance_threshold is None
                               else options.distance_threshold)
        self.min_joint_pos = np.asarray(cfg["min_joint_pos"], dtype=np.float64)
        self.max_joint_pos = np.asarray(cfg["max_joint_pos"], dtype=np.float64)
        ik_lower = np.maximum(self.chain.lower, self.min_joint_pos)
        ik_upper = np.minimum(self.chain.upper, self.max_joint_pos)
        self.ik = self.arm.top_down_ik(ik_lower, ik_upper)
        # envs whose IKs are alike (same class and limits) solve a batch's targets in one call
        self.ik_key = (type(self.ik), ik_lower.tobytes(), ik_upper.tobytes())
        self.ee_low = np.asarray(cfg["position_ee_min"], dtype=np.float64)
        self.ee_high = np.asarray(cfg["position_ee_max"], dtype=np.float64)
        self.table_top = float(cfg["table_top"]) + self.base_position[2]
        self.command_lead = float(options.command_lead)
        self.ee_goal = np.full(3, np.nan)  # the last commanded end effector (base frame); NaN: none yet

    @classmethod
    def ee_goals(cls, tasks: Sequence[ObjectTask], ee: np.ndarray, deltas: np.ndarray) -> np.ndarray:
        """N envs' end-effector goals (base frame) for end-effector deltas ``deltas`` (units of
        ``ee_delta_coeff``) from the measured ``ee`` (world frame), or from each env's last goal within its
        ``command_lead`` of it; clipped into the box and kept as the next step's last goal."""
        ref = _command_reference(tasks, ee - rows(tasks, "base_position"), "ee_goal")
        goals = np.clip(ref + deltas * column(tasks, "ee_delta_coeff"), rows(tasks, "ee_low"), rows(tasks, "ee_high"))
        for task, goal in zip(tasks, goals):
            task.ee_goal = goal
        return goals

    def add_scene(self, rest_z: float, object_xy: Sequence[float], mjcf: tuple[str, str] | None = None) -> None:
        """Spawn the table and the object (a robot's connection serves the tracker's object and the standing
        table instead), the object resting at ``object_xy`` (base frame). ``mjcf``: the table's and the
        object's MJCF (default the arm file's scene)."""
        base = self.base_position
        name = self.host.robot_name
        self.table_entity, self.object_entity = f"{name}_table", f"{name}_object"
        self.object_frame, self.table_frame = f"{self.object_entity}/object", f"{self.table_entity}/table"
        self.table_pose = np.asarray(self.cfg["table_center"], dtype=np.float64) + base
        at = np.array([*object_xy, rest_z]) + base
        if mjcf is None:
            entities = (self.arm.scene_entity("table", self.table_entity, self.table_pose, movable=False),
                        self.arm.scene_entity("object", self.object_entity, at, movable=True))
        else:
            entities = (SceneEntity(self.table_entity, "", _point(self.table_pose), self.table_frame, movable=False,
                                    mjcf=mjcf[0]),
                        SceneEntity(self.object_entity, "", _point(at), self.object_frame, movable=True, mjcf=mjcf[1]))
        self.connection.add_scene(entities)
        self.track_reset()

    def scene_entities(self) -> tuple[str, ...]:
        return (self.object_entity, self.table_entity)

    def tracked_frames(self) -> tuple[str, ...]:
        return (self.object_frame,)

    def place_object(self, position: np.ndarray, quat: np.ndarray) -> None:
        """Teleport the object (at rest) to its episode start; put the table back when knocked. On a robot
        nothing moves (put it back by hand; ``reset_env_prompt=True`` asks before each reset)."""
        table = self.connection.frame_positions(self.connection.states, self.table_frame)[0]
        if np.linalg.norm(table - self.table_pose) > 1e-3:
            self.connection.place_entity(self.table_entity, self.table_pose, np.array([1.0, 0, 0, 0]))
        self.connection.place_entity(self.object_entity, position, quat)

    def show_object_goal(self) -> None:
        """A sphere the size of the object at the goal (in the shared world's frame), once per episode."""
        to_world = getattr(self.connection, "to_world", None)  # a simulated robot's world slot
        self.show_goal(self.goal if to_world is None else to_world(self.goal), 2 * self.half,
                       ns=f"goal_{self.host.robot_name}")

    # -- the object, rows of a batch ------------------------------------------------------------------
    @staticmethod
    def object_poses_of(tasks: Sequence[ObjectTask], states: RobotStates) -> tuple[np.ndarray, np.ndarray]:
        """``(N, 3)`` positions and ``(N, 4)`` orientations ``(w, x, y, z)`` of the objects (frames returned
        with the step in simulation, a tracker's poses on a robot: the connection's)."""
        return tasks[0].connection.frame_poses(states, tasks[0].object_frame)

    @staticmethod
    def velocities(tasks: Sequence[ObjectTask], t: float, ee: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """N envs' EE linear, object linear and object angular velocities (N x 9) since each env's previous
        state (finite differences over the time between them, zero at an episode's first state); each env's
        tracking moves on to this state (time ``t``, rows of ``ee``, ``p``, ``q``)."""
        for j, task in enumerate(tasks):
            if task._episode_start:
                task._episode_start = False
                task._last = (t, ee[j].copy(), p[j].copy(), q[j].copy())
                task._vel = np.zeros(9)
        vel = np.stack([task._vel for task in tasks])
        moved = [j for j, task in enumerate(tasks) if task._last[0] != t]
        if moved:
            dt = np.array([t - tasks[j]._last[0] for j in moved])
            ee0, p0, q0 = (np.stack([tasks[j]._last[k] for j in moved]) for k in (1, 2, 3))
            step = np.where(dt > 0, dt, 1.0)[:, None]  # rows with dt <= 0 are zeroed below
            new = np.concatenate([(ee[moved] - ee0) / step, (p[moved] - p0) / step,
                                  rotation_velocities(q0, q[moved], dt)], axis=1)
            new[dt <= 0] = 0.0
            vel[moved] = new
            for k, j in enumerate(moved):
                tasks[j]._vel = new[k]
                tasks[j]._last = (t, ee[j].copy(), p[j].copy(), q[j].copy())
        return vel

    @staticmethod
    def check_faults(tasks: Sequence[ObjectTask], obj: np.ndarray) -> None:
        """``info["truncated_reason"]`` of each env whose object (row of ``obj``) fell off the table or left
        the arm's reach."""
        base = rows(tasks, "base_position")
        rel = obj - base
        fell = rel[:, 2] + base[:, 2] < np.array([t.table_top - float(t.cfg["fall_margin"]) for t in tasks])
        away = np.hypot(rel[:, 0], rel[:, 1]) > np.array([float(t.cfg["max_object_distance"]) for t in tasks])
        for j in np.flatnonzero(fell | away).tolist():
            info = tasks[j].info
            if not info.get("truncated_reason"):
                info["truncated_reason"] = "object_fell_off_table" if fell[j] else "object_out_of_reach"

    # -- one env ----------------------------------------------------------------------------------------
    def object_position(self) -> np.ndarray:
        """World position of the object's centre after the last step."""
        return self.object_poses_of([self], self.connection.states)[0][0].copy()

    def object_orientation(self) -> np.ndarray:
        """World orientation ``(w, x, y, z)`` of the object after the last step."""
        return self.object_poses_of([self], self.connection.states)[1][0].copy()

    def ee_position(self) -> np.ndarray:
        """World position of the end effector after the last step."""
        return self.arm.ee_positions_of(self.connection, self.connection.states)[0].copy()

    def object_goal_distance(self) -> float:
        """Distance of the object's centre from the goal."""
        return float(np.linalg.norm(self.object_position() - self.goal))

    def track_reset(self) -> None:
        self._episode_start = False
        self._last = (self.connection.observation_time(self.connection.states), self.ee_position(),
                      self.object_position(), self.object_orientation())
        self._vel = np.zeros(9)

    # -- goal envs (HER) -------------------------------------------------------------------------------
    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return object_reward(achieved_goal, desired_goal, self.tolerance, self.reward_type)

    def is_success(self, achieved_goal: Any, desired_goal: Any) -> Any:
        return is_success(achieved_goal, desired_goal, self.tolerance)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """Success ends the episode only with ``terminate_on_success=True``; vectorised."""
        if self.options.terminate_on_success:
            return is_success(achieved_goal, desired_goal, self.tolerance)
        return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool) if np.ndim(achieved_goal) > 1 else False

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """True where the info carries a fault (``truncated_reason``); reads only its arguments."""
        if np.ndim(achieved_goal) > 1:
            infos = list(info) if info is not None else []
            out = np.zeros(np.shape(achieved_goal)[:-1], dtype=bool)
            for i, item in enumerate(infos[: out.size]):
                out.flat[i] = bool(isinstance(item, dict) and item.get("truncated_reason"))
            return out
        return bool(isinstance(info, dict) and info.get("truncated_reason"))

    # -- scoring, rows of a batch --------------------------------------------------------------------------
    @classmethod
    def raw_rows(cls: type[TaskT], tasks: Sequence[TaskT], states: RobotStates) -> np.ndarray:
        """N raw state observations (the task's), before the goal."""
        raise NotImplementedError

    @classmethod
    def observed_rows(cls: type[TaskT], tasks: Sequence[TaskT], states: RobotStates) -> np.ndarray:
        """N raw observations, ending with the command offset where ``observe_command`` asks for it."""
        raw = cls.raw_rows(tasks, states)
        if not tasks[0].options.observe_command:
            return raw
        measured = raw[:, 0:3] - rows(tasks, "base_position")
        return np.concatenate([raw, np.nan_to_num(rows(tasks, "ee_goal") - measured)], axis=1)

    @classmethod
    def results(cls: type[TaskT], tasks: Sequence[TaskT], states: RobotStates) -> StepResults:
        raw = cls.observed_rows(tasks, states)
        cls.check_faults(tasks, raw[:, 3:6])
        n = len(tasks)
        if not tasks[0].goal_conditioned:
            obs = cls.plain_observation(tasks, raw)
            reward, done, truncated = np.zeros(n), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
            for j, task in enumerate(tasks):
                position = task.object_position()  # one read of the frame for the distance, reward and end
                d = float(np.linalg.norm(position - task.goal))
                info = task.info
                info["is_success"] = d <= task.tolerance
                info["distance"] = d
                reward[j] = float(object_reward(position, task.goal, task.tolerance, task.reward_type))
                done[j] = task.options.terminate_on_success and d <= task.tolerance
                truncated[j] = bool(info.get("truncated_reason"))
                info.setdefault("is_success", False)
            return StepResults(obs, reward, done, truncated, [task.info for task in tasks])
        goal_obs = cls.goal_observation(tasks, raw)
        distance = goal_distance(goal_obs["achieved_goal"], goal_obs["desired_goal"])
        tolerance = rows(tasks, "tolerance")
        success = distance <= tolerance
        kinds = {task.reward_type for task in tasks}
        if len(kinds) == 1:
            reward = np.asarray(reward_from_distance(distance, tolerance, kinds.pop()), dtype=np.float64)
        else:
            reward = np.array([np.asarray(reward_from_distance(distance[j:j + 1], tolerance[j:j + 1],
                                                               task.reward_type))[0] for j, task in enumerate(tasks)],
                              dtype=np.float64)
        terminated = success & np.array([task.options.terminate_on_success for task in tasks], dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        for j, task in enumerate(tasks):
            info = task.info
            info.setdefault("is_success", bool(success[j]))
            truncated[j] = bool(info.get("truncated_reason"))
        return StepResults(goal_obs, reward, terminated, truncated, [task.info for task in tasks])

    @staticmethod
    def plain_observation(tasks: Sequence[ObjectTask], raw: np.ndarray) -> np.ndarray:
        goals = rows(tasks, "goal")
        obs = np.concatenate([raw, goals, goals - raw[:, 3:6]], axis=1).astype(np.float32)
        boxes = [cast(spaces.Box, task.observation_space) for task in tasks]
        return np.minimum(np.maximum(obs, np.array([b.low for b in boxes])), np.array([b.high for b in boxes]))

    @staticmethod
    def goal_observation(tasks: Sequence[ObjectTask], raw: np.ndarray) -> dict[str, np.ndarray]:
        boxes = [cast(spaces.Box, cast(spaces.Dict, task.observation_space)["observation"]) for task in tasks]
        obs = np.minimum(np.maximum(raw.astype(np.float32), np.array([b.low for b in boxes])),
                         np.array([b.high for b in boxes]))
        return {"observation": obs, "achieved_goal": obs[:, 3:6].copy(),
                "desired_goal": rows(tasks, "goal").astype(np.float32)}

    def observe(self) -> Any:
        raw = type(self).observed_rows([self], self.connection.states)
        type(self).check_faults([self], raw[:, 3:6])
        if self.goal_conditioned:
            return {k: v[0] for k, v in self.goal_observation([self], raw).items()}
        return self.plain_observation([self], raw)[0]

    def object_spaces(self, low: np.ndarray, high: np.ndarray) -> spaces.Space[Any]:
        """The env's space from the raw observation's bounds (the object's position at 3:6), and the command
        offset's where ``observe_command`` asks for it."""
        if self.options.observe_command:
            low = np.concatenate([low, np.full(3, -COMMAND_OFFSET_BOUND)])
            high = np.concatenate([high, np.full(3, COMMAND_OFFSET_BOUND)])
        if self.goal_conditioned:
            return self.goal_spaces(low, high, slice(3, 6), self.goal_low, self.goal_high)
        rel = np.abs(self.goal_high - self.goal_low) + 1.0
        return spaces.Box(np.concatenate([low, self.goal_low, -rel]).astype(np.float32),
                          np.concatenate([high, self.goal_high, rel]).astype(np.float32), dtype=np.float32)


def _point(position: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in np.asarray(position, dtype=np.float64).reshape(3))
    return x, y, z


class ManipulationTask(ObjectTask):
    """Push or pick-and-place (see the module docstring): one env's goal, targets and velocity tracking."""

    KIND: ClassVar[str]
    OPTIONS = ManipulationOptions

    @classmethod
    def load_config(cls, arm: Arm, options: TaskOptions) -> dict[str, Any]:
        scene = {k: v for k, v in (arm.file.manipulation or {}).items() if k in SCENE_KEYS}
        return load_arm_task_config(arm, "manipulation", manipulation_schema(len(arm.joints)), options.config_file,
                                    defaults=scene)

    def __init__(self, host: TaskHost, arm: Arm, options: ManipulationOptions, cfg: Mapping[str, Any], *,
                 goal_conditioned: bool) -> None:
        super().__init__(host, arm, options, cfg, goal_conditioned=goal_conditioned)
        cfg = self.cfg
        self.setup_tool()
        self.delta_coeff = float(cfg["delta_coeff"])
        base = self.base_position
        self.gripper_range = (float(cfg["gripper_min"]), float(cfg["gripper_max"]))
        self.half = float(cfg["object_half_size"])
        rest_z = float(cfg["table_top"]) + self.half
        self.sampler = ObjectGoalSampler(
            tuple(cfg["object_xy_min"]), tuple(cfg["object_xy_max"]), tuple(cfg["goal_xy_min"]),
            tuple(cfg["goal_xy_max"]), rest_z,
            air_probability=float(cfg["target_in_the_air"]) if self.KIND == "pnp" else 0.0,
            air_height=float(cfg["target_height_max"]), min_distance=float(cfg["min_object_goal_distance"]),
            yaw_range=float(cfg["object_yaw_range"]))
        self.init_joint_pos = self.ik.solve(np.asarray(cfg["init_ee_position"], dtype=np.float64))
        n_act = (3 if self.ee_action_type else len(arm.joints)) + 1
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n_act,), dtype=np.float32)
        self.prev_action = np.zeros(n_act)
        self.goal = np.array([*self.sampler.goal_low, rest_z]) + base
        if arm.gripper_controller:
            self.connection.use_gripper(arm.gripper_controller, self.gripper_range)
        self.add_scene(rest_z, self.sampler.object_low)
        self.joint_targets = self.init_joint_pos.copy()
        self.gripper_target = self.gripper_range[1]
        self.goal_sampler = _ObjectGoals(self)
        self.goal_low = np.array([*self.sampler.goal_low, rest_z]) + base
        self.goal_high = np.array([*self.sampler.goal_high, rest_z + float(cfg["target_height_max"])]) + base
        self.observation_space = self.object_spaces(*self.observation_bounds())

    # -- the episode ------------------------------------------------------------------------------------
    def reset_pose(self) -> None:
        self.connection.move_to_initial_pose(self.arm.joints, self.init_joint_pos)
        self.arm.open_gripper_at_reset(self.connection, self.gripper_range[1])
        self.joint_targets = self.init_joint_pos.copy()
        self.gripper_target = self.gripper_range[1]
        self.arm.command_gripper(self.connection, self.gripper_target)

    def start_episode(self, rng: np.random.Generator) -> None:
        base = self.base_position
        obj, yaw, goal = self.sampler.sample(rng)
        self.goal = goal + base
        self.place_object(obj + base, yaw_quat(yaw))
        self.prev_action = np.zeros(self.action_space.shape)
        self.ee_goal = np.full(3, np.nan)  # the first action moves from where the arm is
        self._episode_start = True  # velocities restart from the first observation
        self.show_object_goal()

    # -- actions, rows of a batch ------------------------------------------------------------------------
    @classmethod
    def act(cls, tasks: Sequence[ManipulationTask], actions: np.ndarray, states: RobotStates) -> None:
        """Joint targets (through each env's top-down IK for EE actions) and gripper targets of N envs."""
        arm = tasks[0].arm
        current = arm.positions_of(states)
        if any(task.ee_action_type for task in tasks):
            goals = cls.ee_goals(tasks, arm.ee_positions_of(tasks[0].connection, states), actions[:, :3])
        if not all(task.ee_action_type for task in tasks):
            joint_targets = (_command_reference(tasks, current, "joint_targets")
                             + actions[:, :-1] * rows(tasks, "delta_coeff")[:, None])
        if all(task.ee_action_type for task in tasks):
            key = tasks[0].ik_key
            if all(task.ik_key == key for task in tasks):  # one arm, one set of limits: one pass
                targets = tasks[0].ik.solve_rows(goals, q0=current)
            else:
                targets = np.array([task.ik.solve(goals[j], q0=current[j]) for j, task in enumerate(tasks)])
        elif not any(task.ee_action_type for task in tasks):
            targets = joint_targets
        else:
            targets = np.array([t.ik.solve(goals[j], q0=current[j]) if t.ee_action_type else joint_targets[j]
                                for j, t in enumerate(tasks)])
        targets = np.clip(targets, rows(tasks, "min_joint_pos"), rows(tasks, "max_joint_pos"))
        for task, row in zip(tasks, targets):
            arm.command_arm(task.connection, row, task.info)
        for j, task in enumerate(tasks):
            task.joint_targets = targets[j]
            lo, hi = task.gripper_range
            task.gripper_target = lo + (float(np.clip(actions[j, -1], -1.0, 1.0)) + 1.0) * 0.5 * (hi - lo)
            task.prev_action = actions[j]
        for task in tasks:
            arm.command_gripper(task.connection, task.gripper_target)

    # -- observations -------------------------------------------------------------------------------------
    @classmethod
    def raw_rows(cls, tasks: Sequence[ManipulationTask], states: RobotStates) -> np.ndarray:
        """N raw observations: Fetch's 25 values plus the arm joints (see the module docstring); each env's
        velocity tracking moves on to this state."""
        arm, connection = tasks[0].arm, tasks[0].connection
        ee = arm.ee_positions_of(connection, states)
        obj, obj_q = cls.object_poses_of(tasks, states)
        vel = cls.velocities(tasks, connection.observation_time(states), ee, obj, obj_q)
        finger_pos, finger_vel = arm.finger_states(states)
        return np.concatenate([ee, obj, obj - ee, finger_pos, quat_to_euler(obj_q), vel[:, 3:6],
                               vel[:, 6:9], vel[:, 0:3], finger_vel, arm.positions_of(states)], axis=1)

    def raw_observation(self) -> np.ndarray:
        """This env's raw observation now (see :meth:`raw_rows`)."""
        return type(self).raw_rows([self], self.connection.states)[0]

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of :meth:`raw_observation` (values outside are clipped into them)."""
        base = self.base_position
        reach = float(self.cfg["max_object_distance"]) + 0.1
        pos_lo = base + np.array([-reach, -reach, -0.5])
        pos_hi = base + np.array([reach, reach, 0.7])
        rel = np.array([2 * reach, 2 * reach, 1.2])
        g_lo, g_hi = sorted(self.gripper_range)  # a gripper may close towards either limit
        mimic = self.arm.finger_mimic
        m_lo, m_hi = sorted((mimic * g_lo, mimic * g_hi))  # the mimicking finger's range
        lin, ang = float(self.cfg["max_linear_velocity"]), float(self.cfg["max_angular_velocity"])
        fvel = float(self.cfg["max_joint_vel"])
        low = np.concatenate([pos_lo, pos_lo, -rel, [g_lo - 0.005, m_lo - 0.005], -np.pi * np.ones(3),
                              -lin * np.ones(3), -ang * np.ones(3), -lin * np.ones(3), -fvel * np.ones(2),
                              self.chain.lower])
        high = np.concatenate([pos_hi, pos_hi, rel, [g_hi + 0.005, m_hi + 0.005], np.pi * np.ones(3),
                               lin * np.ones(3), ang * np.ones(3), lin * np.ones(3), fvel * np.ones(2),
                               self.chain.upper])
        assert low.shape == (FETCH_OBS_SIZE + len(self.arm.joints),)
        return low, high

    def scripted_policy(self) -> Any:
        from rl_environments.manipulation_scripted import scripted_object_policy

        return scripted_object_policy(self)


class _ObjectGoals:
    """``sample(rng)`` -> a world-frame goal, as the reach's ``goal_sampler`` gives one."""

    def __init__(self, task: ManipulationTask) -> None:
        self._task = task

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        return self._task.sampler.sample(rng)[2] + self._task.base_position


class PushTask(ManipulationTask):
    """Push a cube to a goal on the table (see the module docstring)."""

    NAME = KIND = "push"


class PickAndPlaceTask(ManipulationTask):
    """Pick a cube and place it at a goal on the table or in the air (see the module docstring)."""

    NAME = KIND = "pnp"
