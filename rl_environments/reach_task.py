"""The task layer of the reach envs, shared by every arm and by the plain and goal variants:
actions (joint deltas, absolute joints, or end-effector deltas through IK), episode start and goal
sampling, and the goal marker.

A task env mixes this in after its robot env and adds only its spaces, observation and reward.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from multiros.utils.ros_markers import goal_marker
from rl_environments.reach import GoalSampler, RewardType, goal_reward, is_success


class ReachTask:
    """Reach-task behaviour on top of an :class:`~rl_environments.arm_robot.ArmRobot` env.

    The task env sets, before calling :meth:`_setup_reach`: nothing; it passes its config dict.
    """

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
        self.chain = self.kinematic_chain()  # type: ignore[attr-defined]
        self.delta_action = bool(delta_action)
        self.ee_action_type = bool(ee_action_type)
        self.delta_coeff = float(delta_coeff)
        self.ee_delta_coeff = float(ee_delta_coeff)
        self.tolerance = float(tolerance)
        self.min_joint_pos = np.asarray(cfg["min_joint_pos"], dtype=np.float64)
        self.max_joint_pos = np.asarray(cfg["max_joint_pos"], dtype=np.float64)
        self.init_joint_pos = np.asarray(cfg["init_joint_pos"], dtype=np.float64)
        n = len(self.ARM_JOINTS)  # type: ignore[attr-defined]
        for key, arr in (("min_joint_pos", self.min_joint_pos), ("max_joint_pos", self.max_joint_pos),
                         ("init_joint_pos", self.init_joint_pos)):
            if arr.shape != (n,):
                raise ValueError(
                    f"task config key {key!r} must have {n} values (one per arm joint), got {arr.tolist()}"
                )
        base = self.base_position  # type: ignore[attr-defined]
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
        self.prev_action = np.zeros(self.action_space.shape, dtype=np.float64)
        self.joint_targets = self.init_joint_pos.copy()

    # -- hooks ------------------------------------------------------------------------------
    def _set_init_pose(self) -> None:
        self.move_to_initial_pose(self.ARM_JOINTS, self.init_joint_pos)  # type: ignore[attr-defined]
        self.joint_targets = self.init_joint_pos.copy()

    def _set_episode_init_params(self) -> None:
        self.goal = self.goal_sampler.sample(self.np_random)  # type: ignore[attr-defined]
        self.prev_action = np.zeros(self.action_space.shape, dtype=np.float64)
        self._show_goal()

    def _show_goal(self) -> None:
        """A sphere of the tolerance's size at the goal, for rendered images, the viewer and RViz.

        Published once per episode (never from ``compute_reward``, which HER calls on batches).
        """
        marker = getattr(self, "_goal_marker", None)
        if marker is None:
            self._goal_marker = goal_marker(self.node, self.goal, diameter=2 * self.tolerance)  # type: ignore[attr-defined]
        else:
            marker.update(position=self.goal)

    def _set_action(self, action: np.ndarray) -> None:
        current = self.arm_positions()  # type: ignore[attr-defined]
        if self.ee_action_type:
            target_ee = self.ee_position() - self.base_position + action * self.ee_delta_coeff  # type: ignore[attr-defined]
            result = self.chain.ik(target_ee, q0=current, max_iters=30, restarts=0, tol=1e-3)
            targets = result.q
        elif self.delta_action:
            targets = current + action * self.delta_coeff
        else:
            targets = np.asarray(action, dtype=np.float64)
        self.joint_targets = np.minimum(np.maximum(targets, self.min_joint_pos), self.max_joint_pos)  # np.clip, faster
        self.set_arm_targets(self.joint_targets)  # type: ignore[attr-defined]
        self.prev_action = np.asarray(action, dtype=np.float64)

    # -- helpers for observations and rewards -------------------------------------------------
    def at_joint_limits(self, margin: float = 1e-4) -> bool:
        """True when an arm joint target sits at a limit of the task's joint range."""
        q = self.joint_targets
        return bool(np.any(q <= self.min_joint_pos + margin) or np.any(q >= self.max_joint_pos - margin))

    def ee_to_goal(self) -> tuple[np.ndarray, float]:
        """Unit vector from the end effector to the goal, and the distance."""
        vec = self.goal - self.ee_position()  # type: ignore[attr-defined]
        dist = float(np.linalg.norm(vec))
        unit = vec / dist if dist > 1e-9 else np.zeros(3)
        return unit, dist


OBS_PARTS = ("ee_position", "arm_positions", "prev_action", "arm_velocities")


class GoalReachTask(ReachTask):
    """The goal-conditioned reach task: Dict spaces, observation dict, vectorised reward and success.

    The env sets ``self.reward_type``, names what its ``observation`` holds in ``OBS_PARTS`` (in
    order, from :data:`OBS_PARTS`; the EE position first) and calls :meth:`_setup_goal_spaces` after
    ``_setup_reach``. A batched vector env of such envs runs their step hooks for all its envs at
    once (:mod:`rl_environments.reach_batch`) unless a subclass replaces one of them.
    """

    reward_type: RewardType
    OBS_PARTS: ClassVar[tuple[str, ...]]

    @classmethod
    def batch_step_hooks(cls) -> Any:
        """The batched form of this class's step hooks, or ``None`` where a subclass replaced one
        (see :class:`rl_environments.reach_batch.GoalReachBatchHooks`)."""
        from rl_environments.reach_batch import GoalReachBatchHooks

        return GoalReachBatchHooks.for_class(cls)

    def _get_obs(self) -> dict[str, np.ndarray]:
        return self._goal_obs(np.concatenate([self._obs_part(name) for name in self.OBS_PARTS]))

    def _obs_part(self, name: str) -> np.ndarray:
        if name == "prev_action":
            return self.prev_action
        if name not in OBS_PARTS:
            raise ValueError(f"{type(self).__name__}.OBS_PARTS names {name!r}; parts: {list(OBS_PARTS)}")
        return getattr(self, name)()

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

    def _goal_obs(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        """The observation dict from raw values starting with the EE position; one clip into the
        declared bounds covers the EE box, joint limits and velocity bounds."""
        space = self.observation_space["observation"]
        obs = np.minimum(np.maximum(raw.astype(np.float32), space.low), space.high)
        return {"observation": obs, "achieved_goal": obs[:3].copy(), "desired_goal": self.goal.astype(np.float32)}

    def _compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return goal_reward(achieved_goal, desired_goal, self.tolerance, self.reward_type)

    def _is_success(self, achieved_goal: Any, desired_goal: Any) -> Any:
        return is_success(achieved_goal, desired_goal, self.tolerance)
