"""The reach tasks of every arm, written batch-first (:mod:`multiros.envs.batch_task`): actions
(joint deltas, absolute joints, or end-effector deltas through IK), episode start and goal sampling,
the goal marker, and the goal-conditioned task's observation, reward and success.

A task env mixes a task class in before its robot env. :meth:`ReachTask.batch_act` turns the
actions of N envs into joint targets in one numpy pass; :meth:`GoalReachTask.batch_results` builds
their observations and scores their goals in another. A single env is a batch of one; a batched
vector env calls the same functions for all its envs at once. Each operation is the same, row by
row, whatever N, so an env's numbers do not depend on the batch it is in
(``tests/envs/test_golden_trajectories.py``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import BatchTask, StepResults
from multiros.robot_state import RobotStates
from multiros.utils.ros_markers import goal_marker
from rl_environments.arm_interface import ArmInterface
from rl_environments.reach import GoalSampler, RewardType, goal_distance, goal_reward, is_success, reward_from_distance

__all__ = ["ReachTask", "GoalReachTask", "OBS_PARTS", "stack_rows", "column", "numbers", "row_norms"]


def stack_rows(envs: Sequence[Any], name: str) -> np.ndarray:
    """The envs' attribute ``name`` (arrays of one shape, or numbers) as rows of one array."""
    if len(envs) == 1:
        return np.asarray(getattr(envs[0], name))[None]
    return np.array([getattr(env, name) for env in envs])


def column(envs: Sequence[Any], name: str) -> float | np.ndarray:
    """The envs' number ``name`` as a column ``(N, 1)`` to scale rows with, or the number itself for
    one env (it broadcasts alike, and costs no array)."""
    if len(envs) == 1:
        return float(getattr(envs[0], name))
    return np.array([getattr(env, name) for env in envs], dtype=np.float64)[:, None]


def numbers(envs: Sequence[Any], name: str) -> float | np.ndarray:
    """The envs' number ``name``: ``(N,)``, or the number itself for one env."""
    if len(envs) == 1:
        return float(getattr(envs[0], name))
    return np.array([getattr(env, name) for env in envs], dtype=np.float64)


def row_norms(vectors: np.ndarray) -> np.ndarray:
    """``np.linalg.norm`` of each row (row by row: a batch's norms equal one env's, bit for bit)."""
    return np.array([np.linalg.norm(v) for v in vectors])


class ReachTask(BatchTask, ArmInterface):
    """Reach-task behaviour on top of an arm's robot layer (:class:`~rl_environments.arm_interface.ArmInterface`).

    The task env calls :meth:`_setup_reach` after the robot env's constructor, with its config.
    """

    cfg: dict[str, Any]
    chain: Any
    delta_action: bool
    ee_action_type: bool
    delta_coeff: float
    ee_delta_coeff: float
    tolerance: float
    min_joint_pos: np.ndarray
    max_joint_pos: np.ndarray
    init_joint_pos: np.ndarray
    goal: np.ndarray
    prev_action: np.ndarray
    joint_targets: np.ndarray
    def _setup_reach(
        self,
        cfg: Mapping[str, Any],
        *,
        delta_action: bool,
        ee_action_type: bool,
        delta_coeff: float,
        ee_delta_coeff: float,
        tolerance: float,
        goal_min: np.ndarray,
        goal_max: np.ndarray,
    ) -> None:
        self.cfg = dict(cfg)
        self.chain = self.kinematic_chain()
        self.delta_action = bool(delta_action)
        self.ee_action_type = bool(ee_action_type)
        self.delta_coeff = float(delta_coeff)
        self.ee_delta_coeff = float(ee_delta_coeff)
        self.tolerance = float(tolerance)
        self.min_joint_pos = np.asarray(cfg["min_joint_pos"], dtype=np.float64)
        self.max_joint_pos = np.asarray(cfg["max_joint_pos"], dtype=np.float64)
        self.init_joint_pos = np.asarray(cfg["init_joint_pos"], dtype=np.float64)
        n = len(self.ARM_JOINTS)
        for key, arr in (("min_joint_pos", self.min_joint_pos), ("max_joint_pos", self.max_joint_pos),
                         ("init_joint_pos", self.init_joint_pos)):
            if arr.shape != (n,):
                raise ValueError(
                    f"task config key {key!r} must have {n} values (one per arm joint), got {arr.tolist()}"
                )
        base = self.base_position
        self.goal_min = np.asarray(goal_min, dtype=np.float64) + base
        self.goal_max = np.asarray(goal_max, dtype=np.float64) + base
        self.goal_sampler = GoalSampler(
            self.chain, goal_min, goal_max, base_position=base,
            joint_low=self.min_joint_pos, joint_high=self.max_joint_pos,
        )
        if self.ee_action_type:
            self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        elif self.delta_action:
            self.action_space = spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        else:
            self.action_space = spaces.Box(
                self.min_joint_pos.astype(np.float32), self.max_joint_pos.astype(np.float32), dtype=np.float32
            )
        self.goal = self.goal_sampler.sample(np.random.default_rng(0))
        self.prev_action = np.zeros(self.action_box.shape, dtype=np.float64)
        self.joint_targets = self.init_joint_pos.copy()

    # -- reset hooks (one env at a time) ----------------------------------------------------------------
    def _set_init_pose(self) -> None:
        self.move_to_initial_pose(self.ARM_JOINTS, self.init_joint_pos)
        self.joint_targets = self.init_joint_pos.copy()

    def _set_episode_init_params(self) -> None:
        self.goal = self.goal_sampler.sample(self.np_random)
        self.prev_action = np.zeros(self.action_box.shape, dtype=np.float64)
        self._show_goal()

    def _show_goal(self) -> None:
        """A sphere of the tolerance's size at the goal, for rendered images, the viewer and RViz.

        Published once per episode (never from ``compute_reward``, which HER calls on batches).
        """
        marker = getattr(self, "_goal_marker", None)
        if marker is None:
            self._goal_marker = goal_marker(self.node, self.goal, diameter=2 * self.tolerance)
        else:
            marker.update(position=self.goal)

    # -- actions, batch-first -------------------------------------------------------------------------
    @classmethod
    def batch_act(cls, envs: Sequence[Any], actions: np.ndarray, states: RobotStates) -> None:
        """Joint targets from N envs' actions (each env's own kind: deltas, absolute, or EE deltas),
        clipped into each env's joint range, sent to each arm; ``prev_action`` and ``joint_targets`` kept."""
        current = cls.arm_positions_of(states)
        e0 = envs[0]
        kind: tuple[Any, Any] | None = (e0.ee_action_type, e0.delta_action)
        if len(envs) > 1 and any((env.ee_action_type, env.delta_action) != kind for env in envs):
            kind = None  # envs of several kinds: row by row
        if kind == (False, True):  # joint deltas, every env: one pass
            targets = current + actions * column(envs, "delta_coeff")
        elif kind == (False, False):
            targets = actions
        else:
            targets = np.array([cls._row_targets(env, current[j], actions[j], states, j)
                                for j, env in enumerate(envs)])
        targets = np.minimum(np.maximum(targets, stack_rows(envs, "min_joint_pos")),
                             stack_rows(envs, "max_joint_pos"))  # np.clip, faster
        for env, target, action in zip(envs, targets, actions):
            env.joint_targets = target
            env.prev_action = action
        cls.set_arm_targets_of(envs, targets)

    @classmethod
    def _row_targets(cls, env: Any, current: np.ndarray, action: np.ndarray, states: RobotStates, j: int) -> np.ndarray:
        if env.ee_action_type:
            ee = cls.ee_positions_of([env], _one_row(states, j))[0]
            target_ee = ee - env.base_position + action * env.ee_delta_coeff
            return env.chain.ik(target_ee, q0=current, max_iters=30, restarts=0, tol=1e-3).q
        if env.delta_action:
            return current + action * env.delta_coeff
        return action

    def _set_action(self, action: np.ndarray) -> None:
        type(self).batch_act([self], np.asarray(action, dtype=np.float64)[None], self.connection.states)

    # -- helpers for observations and rewards -----------------------------------------------------------
    def at_joint_limits(self, margin: float = 1e-4) -> bool:
        """True when an arm joint target sits at a limit of the task's joint range."""
        q = self.joint_targets
        return bool(np.any(q <= self.min_joint_pos + margin) or np.any(q >= self.max_joint_pos - margin))

    def ee_to_goal(self) -> tuple[np.ndarray, float]:
        """Unit vector from the end effector to the goal, and the distance."""
        vec = self.goal - self.ee_position()
        dist = float(np.linalg.norm(vec))
        unit = vec / dist if dist > 1e-9 else np.zeros(3)
        return unit, dist

    @classmethod
    def goals_to(cls, envs: Sequence[Any], ee: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each env: the vector from the end effector ``ee[j]`` to its goal, its length
        (:func:`row_norms`) and the unit vector (zeros at the goal), as :meth:`ee_to_goal` gives one env's."""
        vec = stack_rows(envs, "goal") - ee
        dist = row_norms(vec)
        unit = np.zeros_like(vec)
        far = dist > 1e-9
        unit[far] = vec[far] / dist[far, None]
        return vec, dist, unit


def _one_row(states: RobotStates, j: int) -> RobotStates:
    return RobotStates(states.sim_time, states.names, states.position[j:j + 1], states.velocity[j:j + 1],
                       states.effort[j:j + 1], states.frame_positions[j:j + 1], states.frame_orientations[j:j + 1])


OBS_PARTS = ("ee_position", "arm_positions", "prev_action", "arm_velocities")
_CHECKED_PARTS: set[type] = set()


class GoalReachTask(ReachTask):
    """The goal-conditioned reach task: Dict spaces, observation dict, vectorised reward and success.

    The env sets ``self.reward_type``, names what its ``observation`` holds in ``OBS_PARTS`` (in
    order, from :data:`OBS_PARTS`; the EE position first) and calls :meth:`_setup_goal_spaces` after
    ``_setup_reach``.
    """

    reward_type: RewardType
    OBS_PARTS: ClassVar[tuple[str, ...]]

    # -- batch-first ----------------------------------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> dict[str, np.ndarray]:
        """N envs' observation dicts, stacked: one clip into each env's declared bounds covers the EE
        box, joint limits and velocity bounds."""
        if cls not in _CHECKED_PARTS:
            for name in cls.OBS_PARTS:
                if name not in OBS_PARTS:
                    raise ValueError(f"{cls.__name__}.OBS_PARTS names {name!r}; parts: {list(OBS_PARTS)}")
            _CHECKED_PARTS.add(cls)
        # cast to float32 as they are joined (the bits of a cast after), then clipped in place
        obs = np.concatenate([cls._obs_part(name, envs, states) for name in cls.OBS_PARTS], axis=1,
                             dtype=np.float32)
        if len(envs) == 1:
            box = envs[0].state_space.spaces["observation"]
            low, high = box.low, box.high
        else:
            boxes = [env.state_space.spaces["observation"] for env in envs]
            low, high = np.array([b.low for b in boxes]), np.array([b.high for b in boxes])
        np.minimum(np.maximum(obs, low, out=obs), high, out=obs)
        return {"observation": obs, "achieved_goal": obs[:, :3].copy(),
                "desired_goal": np.array([env.goal for env in envs], dtype=np.float32)}

    @classmethod
    def _obs_part(cls, name: str, envs: Sequence[Any], states: RobotStates) -> np.ndarray:
        if name == "ee_position":
            return cls.ee_positions_of(envs, states)
        if name == "arm_positions":
            return cls.arm_positions_of(states)
        if name == "arm_velocities":
            return cls.arm_velocities_of(states)
        return stack_rows(envs, "prev_action")

    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        """Observation, reward (each env's ``reward_type``), success as termination, per env."""
        obs = cls.batch_observe(envs, states)
        distance = goal_distance(obs["achieved_goal"], obs["desired_goal"])  # what is_success and goal_reward compute
        tolerance = numbers(envs, "tolerance")
        success = distance <= tolerance
        types = {env.reward_type for env in envs}
        if len(types) == 1:
            reward = reward_from_distance(distance, tolerance, types.pop()).astype(np.float64)  # type: ignore[union-attr]
        else:
            reward = np.array([np.asarray(reward_from_distance(distance[j:j + 1], env.tolerance, env.reward_type))[0]
                               for j, env in enumerate(envs)], dtype=np.float64)
        infos = []
        for env, reached in zip(envs, success.tolist()):
            info = env.info
            info.setdefault("is_success", reached)
            infos.append(info)
        return StepResults(obs, reward, success, np.zeros(len(envs), dtype=bool), infos)

    # -- the hooks of one env (MultiROS names), through the batch functions --------------------------
    def _get_obs(self) -> dict[str, np.ndarray]:
        obs = type(self).batch_observe([self], self.connection.states)
        return {k: v[0] for k, v in obs.items()}

    def _setup_goal_spaces(self, obs_low: np.ndarray, obs_high: np.ndarray) -> None:
        """``observation`` bounds (its first three values are the EE position) and goal boxes."""
        obs_low, obs_high = np.asarray(obs_low, np.float32), np.asarray(obs_high, np.float32)
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(obs_low, obs_high, dtype=np.float32),
                "achieved_goal": spaces.Box(obs_low[:3], obs_high[:3], dtype=np.float32),
                "desired_goal": spaces.Box(
                    self.goal_min.astype(np.float32), self.goal_max.astype(np.float32), dtype=np.float32
                ),
            }
        )

    def _compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return goal_reward(achieved_goal, desired_goal, self.tolerance, self.reward_type)

    def _is_success(self, achieved_goal: Any, desired_goal: Any) -> Any:
        return is_success(achieved_goal, desired_goal, self.tolerance)
