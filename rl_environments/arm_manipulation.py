"""Push and pick-and-place, plain and goal-conditioned, for every arm with a gripper (its robot layer
names the IK, fingers, gripper controller and scene: :class:`~rl_environments.arm_robot.ArmRobot`),
configured per arm by its arm file's ``manipulation:`` section (:mod:`rl_environments.arm_file`; a
``config_file=`` of your own has the keys under ``<robot name>:``), checked
by :func:`manipulation_schema`; the scene's keys come from the arm's ``SCENE`` unless the file
gives them).

## Scene
The arm stands on a table (its description package's ``mjcf/table.xml``, spawned through SpawnEntity)
with a cube (``mjcf/cube.xml``); both are free MJCF bodies. Each reset puts the arm at its start pose
(the gripper above the table, pointing down, open), samples the cube's start (on the table, yawed
within ``object_yaw_range`` of square to the fingers) and the goal, never closer than
``min_object_goal_distance`` (more than the success distance), and sets the cube there through
SetEntityState. Push goals lie on the table; pick-and-place goals are lifted up to
``target_height_max`` with probability ``target_in_the_air`` (Fetch's 0.5).

## Action space
``Box(-1, 1, (4,))`` (default, ``ee_action_type=True``): end-effector deltas ``action[:3] *
ee_delta_coeff`` in the base frame, the gripper kept pointing down by the arm's top-down IK, targets
clipped into the workspace box (the finger tips stay above the table); ``action[3]`` the gripper, -1
closed, +1 open (clipped to ``[-1, 1]``). ``ee_action_type=False``: ``Box(-1, 1, (n + 1,))``, n
joint deltas ``* delta_coeff`` and the gripper.

## Observation space
Goal envs: ``Dict(observation=Box(25 + n), achieved_goal=Box(3), desired_goal=Box(3))``.
``observation`` (Fetch's 25 values plus the n arm joints): EE position, object position, object
minus EE, the two finger joints, object roll/pitch/yaw, object linear and angular velocity, EE
velocity, finger velocities, arm joints. ``achieved_goal`` is the object's position, ``desired_goal``
the goal. Plain envs: ``Box(31 + n)``: the same values, the goal, and goal minus object. World
frame throughout; values are clipped into the declared bounds. Camera observations:
``rgb_obs_only``, ``rgb_plus_normal_obs``, ``rgb_plus_depth_plus_normal_obs``
(:mod:`rl_environments.camera_obs`).

## Rewards
``reward_type="sparse"`` (goal envs' default): 0 when the object is within ``distance_threshold``
(5 cm, Fetch's) of the goal, else -1; ``"dense"`` (plain envs' default): ``-distance(object,
goal)``. ``compute_reward`` is vectorised for HER.

## Episode end
50 steps of 40 ms (Fetch's), truncated (``EPISODE_STEPS`` of the registration may differ per arm).
Success does not end the episode (``terminate_on_success=False``, Fetch's convention):
``is_success`` of the last step says whether the object is *at* the goal, not whether it passed
through it. Faults truncate early with ``info["truncated_reason"]``: ``"object_fell_off_table"``,
``"object_out_of_reach"``, ``"sim_diverged"`` (see :mod:`rl_environments.manipulation_task`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.robot_state import RobotStates
from rl_environments.arm_reach import check_arm_joints
from rl_environments.camera_obs import CameraObservations
from rl_environments.manipulation import is_success, object_reward
from rl_environments.manipulation_task import ManipulationTask, TaskKind
from rl_environments.reach import RewardType, goal_distance, parse_reward_type, reward_from_distance
from rl_environments.reach_task import stack_rows
from rl_environments.task_config import SCENE_KEYS, load_task_config, manipulation_schema

if TYPE_CHECKING:
    from rl_environments.arm_interface import ArmInterface

__all__ = ["ArmGoalManipulationTask", "ArmManipulationTask", "EPISODE_STEPS", "load_manipulation_config",
           "manipulation_schema"]

def load_manipulation_config(robot: type[ArmInterface], name: str | Path | None = None) -> dict[str, Any]:
    """Load and check a push / pick-and-place config for ``robot`` (an arm's robot layer class): by
    default ``<ROBOT_NAME>_manipulation_task_config.yaml``, keys under ``<ROBOT_NAME>:``, the scene's
    keys from ``robot.SCENE`` unless the file gives them."""
    arm = robot.ROBOT_NAME
    from_file = getattr(robot, "task_config", None)
    if name is None and from_file is not None:  # an arm file's manipulation: section, checked when loaded
        return dict(from_file("manipulation"))
    name = name if name is not None else f"{arm}_manipulation_task_config.yaml"
    scene = {k: v for k, v in robot.SCENE.items() if k in SCENE_KEYS}
    cfg = load_task_config(name, manipulation_schema(len(robot.ARM_JOINTS)), section=arm,
                           defaults=scene)
    check_arm_joints(cfg, robot, name)
    return cfg


EPISODE_STEPS = 50


class _GoalSampler:
    """``sample(rng)`` -> a world-frame goal, as the reach tasks' ``goal_sampler``."""

    def __init__(self, task: ManipulationTask) -> None:
        self._task = task

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        return self._task.sampler.sample(rng)[2] + self._task.base_position


class _Common(CameraObservations, ManipulationTask):
    TASK: ClassVar[TaskKind]
    reward_type: RewardType
    terminate_on_success: bool

    def _init_task(self, cfg: dict[str, Any], kwargs: dict[str, Any], *, reward_type: str, ee_action_type: bool,
                   distance_threshold: float | None, terminate_on_success: bool) -> None:
        self.reward_type = parse_reward_type(reward_type)
        self.terminate_on_success = bool(terminate_on_success)
        self._camera_options = self.take_camera_options(kwargs)
        super().__init__(**self.manipulation_kwargs(cfg, kwargs))  # the robot env's constructor, next in the MRO
        self._setup_manipulation(cfg, self.TASK, ee_action_type=ee_action_type, distance_threshold=distance_threshold)
        self.goal_sampler = _GoalSampler(self)
        base = self.base_position
        rest = self.sampler.rest_z
        self.goal_low = np.array([*self.sampler.goal_low, rest]) + base
        self.goal_high = np.array([*self.sampler.goal_high, rest + float(cfg["target_height_max"])]) + base

    @classmethod
    def _raw_and_faults(cls, envs: Sequence[Any], states: RobotStates) -> np.ndarray:
        """The raw observations, each env's faults noted in its info."""
        raw = cls.batch_raw_observation(envs, states)
        cls.batch_check_faults(envs, raw[:, 3:6])
        return raw


class ArmManipulationTask(_Common):
    """Push or pick-and-place as a plain env, for any arm's robot layer (see the module docstring).

    Args:
        reward_type: ``"dense"`` (default) or ``"sparse"``.
        ee_action_type: end-effector deltas + gripper (True) or joint deltas + gripper.
        distance_threshold: success distance in metres (default: the config's, 0.05).
        terminate_on_success: end the episode on success (default False, as Fetch).
        config_file: task config (file name in ``rl_environments.config`` or a path; default the arm's).
        **kwargs: camera options (:class:`~rl_environments.camera_obs.CameraObservations`) and
            robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """

    def __init__(self, reward_type: str = "dense", ee_action_type: bool = True, distance_threshold: float | None = None,
                 terminate_on_success: bool = False, config_file: str | None = None, **kwargs: Any) -> None:
        cfg = load_manipulation_config(type(self), config_file)
        self._init_task(cfg, kwargs, reward_type=reward_type, ee_action_type=ee_action_type,
                        distance_threshold=distance_threshold, terminate_on_success=terminate_on_success)
        low, high = self.observation_bounds()
        span = self.goal_high - self.goal_low
        rel = np.abs(span) + 1.0
        self.observation_space = spaces.Box(
            np.concatenate([low, self.goal_low, -rel]).astype(np.float32),
            np.concatenate([high, self.goal_high, rel]).astype(np.float32), dtype=np.float32)
        self.setup_cameras(self._camera_options)

    # -- batch-first (multiros.envs.batch_task) ----------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> np.ndarray:
        raw = cls._raw_and_faults(envs, states)
        goals = stack_rows(envs, "goal")
        obs = np.concatenate([raw, goals, goals - raw[:, 3:6]], axis=1).astype(np.float32)
        spaces_ = [env.state_space for env in envs]
        return np.minimum(np.maximum(obs, np.array([sp.low for sp in spaces_])), np.array([sp.high for sp in spaces_]))

    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        obs = cls.batch_observe(envs, states)
        n = len(envs)
        reward, done, truncated = np.zeros(n), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        for j, env in enumerate(envs):
            reward[j] = env._get_reward()
            done[j] = env._check_if_done()
            truncated[j] = bool(env.info.get("truncated_reason"))
            env.info.setdefault("is_success", False)
        return cls.add_images(envs, StepResults(obs, reward, done, truncated, [env.info for env in envs]))

    # -- the hooks of one env (MultiROS names) ------------------------------------------------------------
    def _get_obs(self) -> Any:
        return self.with_images(type(self).batch_observe([self], self.connection.states)[0])

    def _get_reward(self) -> float:
        d = self.object_goal_distance()
        self.info["is_success"] = d <= self.tolerance
        self.info["distance"] = d
        return float(object_reward(self.object_position(), self.goal, self.tolerance, self.reward_type))

    def _check_if_done(self) -> bool:
        return self.terminate_on_success and self.object_goal_distance() <= self.tolerance

    def _compute_truncated(self, info: dict[str, Any]) -> bool:
        return bool(info.get("truncated_reason"))


class ArmGoalManipulationTask(_Common):
    """Push or pick-and-place as a goal-conditioned env for HER, for any arm's robot layer (see the
    module docstring).

    Args: as :class:`ArmManipulationTask`, with ``reward_type="sparse"`` by default.
    """

    def __init__(self, reward_type: str = "sparse", ee_action_type: bool = True,
                 distance_threshold: float | None = None, terminate_on_success: bool = False,
                 config_file: str | None = None, **kwargs: Any) -> None:
        cfg = load_manipulation_config(type(self), config_file)
        self._init_task(cfg, kwargs, reward_type=reward_type, ee_action_type=ee_action_type,
                        distance_threshold=distance_threshold, terminate_on_success=terminate_on_success)
        low, high = self.observation_bounds()
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32),
            "achieved_goal": spaces.Box(low[3:6].astype(np.float32), high[3:6].astype(np.float32), dtype=np.float32),
            "desired_goal": spaces.Box(self.goal_low.astype(np.float32), self.goal_high.astype(np.float32),
                                       dtype=np.float32),
        })
        self.setup_cameras(self._camera_options)

    # -- batch-first (multiros.envs.batch_task) ----------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> dict[str, np.ndarray]:
        raw = cls._raw_and_faults(envs, states)
        boxes = [env.state_space["observation"] for env in envs]
        obs = np.minimum(np.maximum(raw.astype(np.float32), np.array([b.low for b in boxes])),
                         np.array([b.high for b in boxes]))
        return {"observation": obs, "achieved_goal": obs[:, 3:6].copy(),
                "desired_goal": stack_rows(envs, "goal").astype(np.float32)}

    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        obs = cls.batch_observe(envs, states)
        distance = goal_distance(obs["achieved_goal"], obs["desired_goal"])
        tolerance = stack_rows(envs, "tolerance")
        success = distance <= tolerance
        n = len(envs)
        kinds = {env.reward_type for env in envs}
        if len(kinds) == 1:
            reward = np.asarray(reward_from_distance(distance, tolerance, kinds.pop()), dtype=np.float64)
        else:
            reward = np.array([np.asarray(reward_from_distance(distance[j:j + 1], tolerance[j:j + 1],
                                                               env.reward_type))[0] for j, env in enumerate(envs)],
                              dtype=np.float64)
        terminated = success & stack_rows(envs, "terminate_on_success").astype(bool)
        truncated = np.zeros(n, dtype=bool)
        for j, env in enumerate(envs):
            info = env.info
            info.setdefault("is_success", bool(success[j]))
            truncated[j] = bool(info.get("truncated_reason"))
        return cls.add_images(envs, StepResults(obs, reward, terminated, truncated, [env.info for env in envs]))

    # -- the hooks of one env (MultiROS names) ------------------------------------------------------------
    def _get_obs(self) -> dict[str, np.ndarray]:
        obs = type(self).batch_observe([self], self.connection.states)
        return self.with_images({k: v[0] for k, v in obs.items()})

    def _compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return object_reward(achieved_goal, desired_goal, self.tolerance, self.reward_type)

    def _is_success(self, achieved_goal: Any, desired_goal: Any) -> Any:
        return is_success(achieved_goal, desired_goal, self.tolerance)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """Success ends the episode only with ``terminate_on_success=True``; vectorised."""
        if self.terminate_on_success:
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
