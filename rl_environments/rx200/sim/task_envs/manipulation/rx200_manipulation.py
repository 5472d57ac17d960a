"""The RX200 push and pick-and-place tasks, plain and goal-conditioned (the four env modules
only bind them to the simulated robot env and pick push or pick-and-place).

## Scene
The RX200 stands on a table (``package://rx200_description/mjcf/table.xml``, spawned through
SpawnEntity) with a 3 cm, 30 g cube (``mjcf/cube.xml``); both are free MJCF bodies. Each reset
puts the arm at its start pose (gripper 10 cm above the table, pointing down, open), samples the
cube's start (on the table, yawed within 0.3 rad of square to the fingers) and the goal, never
closer than ``min_object_goal_distance`` (8 cm, more than the 5 cm success distance), and sets the
cube there through SetEntityState. Push goals lie on the table; pick-and-place goals are lifted
up to 15 cm with probability 0.5 (Fetch's ``target_in_the_air``).

## Action space
``Box(-1, 1, (4,))`` (default, ``ee_action_type=True``): end-effector deltas ``action[:3] *
ee_delta_coeff`` (2 cm per step) in the base frame, the gripper kept pointing down by closed-form IK,
targets clipped into the workspace box (finger tips at least 2 mm above the table); ``action[3]``
the gripper, -1 closed, +1 open (clipped to ``[-1, 1]``). ``ee_action_type=False``: ``Box(-1, 1,
(6,))``, five joint deltas ``* delta_coeff`` (0.05 rad) and the gripper.

## Observation space
Goal envs: ``Dict(observation=Box(30), achieved_goal=Box(3), desired_goal=Box(3))``. ``observation``
(Fetch's 25 values plus the 5 arm joints): EE position, object position, object minus EE, the two
finger joints, object roll/pitch/yaw, object linear and angular velocity, EE velocity, finger
velocities, arm joints. ``achieved_goal`` is the object's position, ``desired_goal`` the goal. Plain
envs: ``Box(36)``: the same 30 values, the goal, and goal minus object. World frame throughout;
values are clipped into the declared bounds.

## Rewards
``reward_type="sparse"`` (goal envs' default): 0 when the object is within ``distance_threshold``
(5 cm, Fetch's) of the goal, else -1; ``"dense"`` (plain envs' default): ``-distance(object,
goal)``. ``compute_reward`` is vectorised for HER.

## Episode end
50 steps (2 s of simulated time at 40 ms per step), truncated, as Fetch's 50 steps of 40 ms:
the scripted policies finish pushes in about 25 steps and pick-and-place in about 35. Success
does not end the episode (``terminate_on_success=False``, Fetch's convention): ``is_success`` of
the last step says whether the object is *at* the goal, not whether it passed through it. Faults
truncate early with ``info["truncated_reason"]``: ``"object_fell_off_table"``,
``"object_out_of_reach"``, ``"sim_diverged"`` (see :mod:`rl_environments.manipulation_task`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.robot_state import RobotStates
from rl_environments.manipulation import is_success, object_reward
from rl_environments.manipulation_task import ManipulationTask, TaskKind
from rl_environments.reach import RewardType, goal_distance, parse_reward_type, reward_from_distance
from rl_environments.reach_task import stack_rows
from rl_environments.rx200.sim.task_envs.manipulation.config import load_rx200_manipulation_config

EPISODE_STEPS = 50


class _GoalSampler:
    """``sample(rng)`` -> a world-frame goal, as the reach tasks' ``goal_sampler``."""

    def __init__(self, task: ManipulationTask) -> None:
        self._task = task

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        return self._task.sampler.sample(rng)[2] + self._task.base_position


class _Common(ManipulationTask):
    TASK: ClassVar[TaskKind]
    reward_type: RewardType
    terminate_on_success: bool

    def _init_task(self, cfg: dict[str, Any], kwargs: dict[str, Any], *, reward_type: str, ee_action_type: bool,
                   distance_threshold: float | None, terminate_on_success: bool) -> None:
        self.reward_type = parse_reward_type(reward_type)
        self.terminate_on_success = bool(terminate_on_success)
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
        for j, env in enumerate(envs):
            env.check_faults(raw[j, 3:6])
        return raw


class RX200ManipulationTask(_Common):
    """RX200 push or pick-and-place as a plain env (see the module docstring).

    Args:
        reward_type: ``"dense"`` (default) or ``"sparse"``.
        ee_action_type: end-effector deltas + gripper (True) or joint deltas + gripper.
        distance_threshold: success distance in metres (default: the config's, 0.05).
        terminate_on_success: end the episode on success (default False, as Fetch).
        config_file: task config (file name in ``rl_environments.config`` or a path).
        **kwargs: robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """


    def __init__(self, reward_type: str = "dense", ee_action_type: bool = True, distance_threshold: float | None = None,
                 terminate_on_success: bool = False, config_file: str = "rx200_manipulation_task_config.yaml",
                 **kwargs: Any) -> None:
        cfg = load_rx200_manipulation_config(config_file)
        self._init_task(cfg, kwargs, reward_type=reward_type, ee_action_type=ee_action_type,
                        distance_threshold=distance_threshold, terminate_on_success=terminate_on_success)
        low, high = self.observation_bounds()
        span = self.goal_high - self.goal_low
        rel = np.abs(span) + 1.0
        self.observation_space = spaces.Box(
            np.concatenate([low, self.goal_low, -rel]).astype(np.float32),
            np.concatenate([high, self.goal_high, rel]).astype(np.float32), dtype=np.float32)

    # -- batch-first (multiros.envs.batch_task) ----------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> np.ndarray:
        raw = cls._raw_and_faults(envs, states)
        goals = stack_rows(envs, "goal")
        obs = np.concatenate([raw, goals, goals - raw[:, 3:6]], axis=1).astype(np.float32)
        spaces_ = [env.observation_space for env in envs]
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
        return StepResults(obs, reward, done, truncated, [env.info for env in envs])

    # -- the hooks of one env (MultiROS names) ------------------------------------------------------------
    def _get_obs(self) -> np.ndarray:
        return type(self).batch_observe([self], self.connection.states)[0]

    def _get_reward(self) -> float:
        d = self.object_goal_distance()
        self.info["is_success"] = d <= self.tolerance
        self.info["distance"] = d
        return float(object_reward(self.object_position(), self.goal, self.tolerance, self.reward_type))

    def _check_if_done(self) -> bool:
        return self.terminate_on_success and self.object_goal_distance() <= self.tolerance

    def _compute_truncated(self, info: dict[str, Any]) -> bool:
        return bool(info.get("truncated_reason"))


class RX200GoalManipulationTask(_Common):
    """RX200 push or pick-and-place as a goal-conditioned env for HER (see the module docstring).

    Args: as :class:`RX200ManipulationTask`, with ``reward_type="sparse"`` by default.
    """


    def __init__(self, reward_type: str = "sparse", ee_action_type: bool = True,
                 distance_threshold: float | None = None, terminate_on_success: bool = False,
                 config_file: str = "rx200_manipulation_task_config.yaml", **kwargs: Any) -> None:
        cfg = load_rx200_manipulation_config(config_file)
        self._init_task(cfg, kwargs, reward_type=reward_type, ee_action_type=ee_action_type,
                        distance_threshold=distance_threshold, terminate_on_success=terminate_on_success)
        low, high = self.observation_bounds()
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32),
            "achieved_goal": spaces.Box(low[3:6].astype(np.float32), high[3:6].astype(np.float32), dtype=np.float32),
            "desired_goal": spaces.Box(self.goal_low.astype(np.float32), self.goal_high.astype(np.float32),
                                       dtype=np.float32),
        })

    # -- batch-first (multiros.envs.batch_task) ----------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> dict[str, np.ndarray]:
        raw = cls._raw_and_faults(envs, states)
        boxes = [env.observation_space["observation"] for env in envs]
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
        reward = np.array([np.asarray(reward_from_distance(distance[j:j + 1], tolerance[j:j + 1], env.reward_type))[0]
                           for j, env in enumerate(envs)], dtype=np.float64)
        terminated = success & stack_rows(envs, "terminate_on_success").astype(bool)
        truncated = np.zeros(n, dtype=bool)
        for j, env in enumerate(envs):
            info = env.info
            info.setdefault("is_success", bool(success[j]))
            truncated[j] = bool(info.get("truncated_reason"))
        return StepResults(obs, reward, terminated, truncated, [env.info for env in envs])

    # -- the hooks of one env (MultiROS names) ------------------------------------------------------------
    def _get_obs(self) -> dict[str, np.ndarray]:
        obs = type(self).batch_observe([self], self.connection.states)
        return {k: v[0] for k, v in obs.items()}

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
