"""The reach task of every arm, plain and goal-conditioned, configured per arm by
its arm file's ``reach:`` section (:mod:`rl_environments.arm_file`; a ``config_file=`` of your own
has the keys under ``<robot name>:``), checked by :func:`reach_schema`.

## Description
The end effector (the robot's ``EE_LINK``) must come within ``reach_tolerance`` of a goal sampled
inside the config's goal box, among points the arm can reach (forward kinematics of random joint
configurations within the task's joint range). One env step is one lockstep round trip to the
simulation node: 25 physics steps of 4 ms, 100 ms (``num_sim_steps`` changes it), long enough for
the arm to settle on each 0.05 rad joint target. Episodes start at the config's ``init_joint_pos``.

## Action space
``Box(-1, 1, (n,))`` for an arm of n joints: joint deltas, ``target = joints + action *
delta_coeff``, clipped to the task's joint range. ``delta_action=False``: absolute joint targets in
``[min_joint_pos, max_joint_pos]``. ``ee_action_type=True``: ``Box(-1, 1, (3,))`` end-effector
deltas (``ee_delta_coeff`` metres) solved by damped-least-squares IK.

## Observation space
Plain envs: ``Box(float32)`` of 3 + 3 + 1 + n + n_action + n values: EE position, unit vector
EE -> goal, distance, arm joint positions, previous action, arm joint velocities. Goal envs:
``Dict(observation, achieved_goal, desired_goal)``, ``observation`` = EE position, arm joints,
previous action, joint velocities (no goal-dependent values, which HER relabelling would leave
stale); ``achieved_goal`` the EE position, ``desired_goal`` the goal. Every value lies inside the
declared bounds (clipped). Camera observations: ``rgb_obs_only``, ``rgb_plus_normal_obs``,
``rgb_plus_depth_plus_normal_obs`` (:mod:`rl_environments.camera_obs`).

## Rewards
Plain: ``reward_type="dense"`` (default) ``-distance`` (``simple_dense_reward=True``) or the shaped
reward (``+reached_goal_reward`` on success, else ``multiplier_dist_reward * -distance +
step_reward``, plus ``joint_limits_reward`` at a joint limit); ``"sparse"``: +1 on success, -1
otherwise. Goal envs: ``"sparse"`` (default) 0 within ``reach_tolerance``, else -1 (Fetch's);
``"dense"`` ``-distance``; ``compute_reward`` is vectorised for HER.

## Episode end
Terminated on success (``info["is_success"] = True``); truncated after 100 steps (registration).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.robot_state import RobotStates
from rl_environments.camera_obs import CameraObservations
from rl_environments.reach import goal_reward, parse_reward_type
from rl_environments.reach_task import GoalReachTask, ReachTask, stack_rows
from rl_environments.task_config import TaskConfigError, load_task_config, reach_schema

if TYPE_CHECKING:
    from rl_environments.arm_interface import ArmInterface

__all__ = ["ArmGoalReachTask", "ArmReachTask", "REACH_NUM_SIM_STEPS", "load_reach_config", "reach_schema",
           "reach_settings"]

# Physics steps of 4 ms per env step for the reach envs: a 100 ms control period (MultiROS' RX200 ran
# its loop at 10 Hz with a 0.1 s action cycle; the Real twins' loop is 10 Hz too). The arm then ends
# each step on its joint target (within ~0.005 rad of a 0.05 rad delta, moving < 0.4 rad/s); with
# the robot default of 40 ms it lagged or overshot the target by 20-50 % and was still moving, and
# HER + SAC needed more steps (docs/tasks.md "Learning speed").
REACH_NUM_SIM_STEPS = 25


def check_arm_joints(cfg: dict[str, Any], robot: type[ArmInterface], source: str | Path) -> None:
    """A config's ``arm_joints`` must be the robot's ``ARM_JOINTS``, in order."""
    joints = tuple(cfg["arm_joints"])
    if joints != tuple(robot.ARM_JOINTS):
        raise TaskConfigError(f"{source}: arm_joints {list(joints)} are not {robot.__name__}'s joints "
                              f"{list(robot.ARM_JOINTS)} (in that order)")


def load_reach_config(robot: type[ArmInterface], name: str | Path | None = None) -> dict[str, Any]:
    """Load and check a reach config for ``robot`` (an arm's robot layer class): by default
    ``<ROBOT_NAME>_reach_task_config.yaml``, keys under ``<ROBOT_NAME>:``."""
    arm = robot.ROBOT_NAME
    from_file = getattr(robot, "task_config", None)
    if name is None and from_file is not None:  # an arm file's reach: section, checked when it was loaded
        return dict(from_file("reach"))
    name = name if name is not None else f"{arm}_reach_task_config.yaml"
    cfg = load_task_config(name, reach_schema(len(robot.ARM_JOINTS)), section=arm)
    check_arm_joints(cfg, robot, name)
    return cfg


def reach_settings(cfg: dict[str, Any], *, delta_action: bool, ee_action_type: bool) -> dict[str, Any]:
    """``ReachTask._setup_reach`` arguments from a reach config."""
    return {
        "delta_action": delta_action,
        "ee_action_type": ee_action_type,
        "delta_coeff": cfg["delta_coeff"],
        "ee_delta_coeff": cfg["ee_delta_coeff"],
        "tolerance": cfg["reach_tolerance"],
        "goal_min": cfg["position_goal_min"],
        "goal_max": cfg["position_goal_max"],
    }


class ArmReachTask(CameraObservations, ReachTask):
    """The reach task, plain observation (see the module docstring), for any arm's robot layer that
    provides :class:`~rl_environments.arm_interface.ArmInterface` (simulated or real). Mix it in
    before the robot env.

    Args:
        reward_type: ``"dense"`` or ``"sparse"``.
        delta_action: joint deltas (True) or absolute joint targets.
        ee_action_type: end-effector delta actions through IK.
        simple_dense_reward: ``-distance`` (True) or the shaped reward of the original task.
        config_file: task config (file name in ``rl_environments.config`` or a path; default the arm's).
        **kwargs: camera options (:class:`~rl_environments.camera_obs.CameraObservations`) and
            robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """

    def __init__(
        self,
        reward_type: str = "dense",
        delta_action: bool = True,
        ee_action_type: bool = False,
        simple_dense_reward: bool = True,
        config_file: str | None = None,
        **kwargs: Any,
    ) -> None:
        cfg = load_reach_config(type(self), config_file)
        self.reward_type = parse_reward_type(reward_type)
        self.simple_dense_reward = bool(simple_dense_reward)
        camera = self.take_camera_options(kwargs)
        super().__init__(**kwargs)
        self._setup_reach(cfg, **reach_settings(cfg, delta_action=delta_action, ee_action_type=ee_action_type))
        self.ee_low = np.asarray(cfg["position_ee_min"]) + self.base_position
        self.ee_high = np.asarray(cfg["position_ee_max"]) + self.base_position
        self.max_vel = float(cfg["max_joint_vel"])
        n = len(self.ARM_JOINTS)
        n_act = self.action_box.shape[0]
        q_low, q_high = self.chain.lower, self.chain.upper
        max_dist = float(np.linalg.norm(self.ee_high - self.ee_low))
        low = np.concatenate(
            [self.ee_low, -np.ones(3), [0.0], q_low, self.action_box.low, -self.max_vel * np.ones(n)]
        )
        high = np.concatenate([self.ee_high, np.ones(3), [max_dist], q_high, self.action_box.high,
                               self.max_vel * np.ones(n)])
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        assert len(low) == 7 + 2 * n + n_act
        self.setup_cameras(camera)

    # -- batch-first (multiros.envs.batch_task) ----------------------------------------------------------
    @classmethod
    def batch_observe(cls, envs: Sequence[Any], states: RobotStates) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The state observations of N envs, their end effectors and their goal distances."""
        ee_raw = cls.ee_positions_of(envs, states)
        ee = np.clip(ee_raw, stack_rows(envs, "ee_low"), stack_rows(envs, "ee_high"))
        _, dist, unit = cls.goals_to(envs, ee_raw)
        chains = [env.chain for env in envs]
        q = np.clip(cls.arm_positions_of(states), np.array([c.lower for c in chains]),
                    np.array([c.upper for c in chains]))
        max_vel = stack_rows(envs, "max_vel")[:, None]
        qd = np.clip(cls.arm_velocities_of(states), -max_vel, max_vel)
        obs = np.concatenate([ee, unit, dist[:, None], q, stack_rows(envs, "prev_action"), qd], axis=1)
        spaces_ = [env.state_space for env in envs]
        low, high = np.array([sp.low for sp in spaces_]), np.array([sp.high for sp in spaces_])
        return np.clip(obs, low, high).astype(np.float32), ee_raw, dist

    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        """Observation (with the camera's images), reward and termination of N envs."""
        return cls.add_images(envs, cls.batch_state_results(envs, states))

    @classmethod
    def batch_state_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        obs, ee, dist = cls.batch_observe(envs, states)
        n = len(envs)
        reward, done = np.zeros(n), np.zeros(n, dtype=bool)
        for j, env in enumerate(envs):
            reward[j], done[j] = env._score(float(dist[j]), ee[j])
        infos = [env.info for env in envs]
        for info in infos:
            info.setdefault("is_success", False)
        return StepResults(obs, reward, done, np.zeros(n, dtype=bool), infos)

    def _score(self, dist: float, ee: np.ndarray) -> tuple[float, bool]:
        """Reward and termination of a step that left the end effector at ``ee``, ``dist`` from the goal."""
        reached = dist <= self.tolerance
        self.info["is_success"] = reached
        self.info["distance"] = dist
        if self.reward_type == "sparse":
            return float(goal_reward(ee, self.goal, self.tolerance, "sparse", (1.0, -1.0))), reached
        if self.simple_dense_reward:
            return -dist, reached
        if reached:
            return self.cfg["reached_goal_reward"], reached
        reward = -self.cfg["multiplier_dist_reward"] * dist + self.cfg["step_reward"]
        if self.at_joint_limits():
            reward += self.cfg["joint_limits_reward"]
        return reward, reached

    # -- the hooks of one env (MultiROS names), through the batch functions -----------------------------
    def _get_obs(self) -> Any:
        return self.with_images(type(self).batch_observe([self], self.connection.states)[0][0])

    def _get_reward(self) -> float:
        ee = self.ee_position()
        return self._score(float(np.linalg.norm(self.goal - ee)), ee)[0]

    def _check_if_done(self) -> bool:
        return float(np.linalg.norm(self.goal - self.ee_position())) <= self.tolerance


class ArmGoalReachTask(CameraObservations, GoalReachTask):
    """The reach task, goal-conditioned (see the module docstring), for any arm's robot layer
    (simulated or real). Mix it in before the robot env.

    Args:
        reward_type: ``"sparse"`` or ``"dense"``.
        delta_action: joint deltas (True) or absolute joint targets.
        ee_action_type: end-effector delta actions through IK.
        config_file: task config (file name in ``rl_environments.config`` or a path; default the arm's).
        **kwargs: camera options (:class:`~rl_environments.camera_obs.CameraObservations`) and
            robot/base-env knobs (``sim_mode``, ``transport``, ``num_sim_steps``, ``seed``, ...).
    """

    OBS_PARTS = ("ee_position", "arm_positions", "prev_action", "arm_velocities")

    def __init__(
        self,
        reward_type: str = "sparse",
        delta_action: bool = True,
        ee_action_type: bool = False,
        config_file: str | None = None,
        **kwargs: Any,
    ) -> None:
        cfg = load_reach_config(type(self), config_file)
        self.reward_type = parse_reward_type(reward_type)
        camera = self.take_camera_options(kwargs)
        super().__init__(**kwargs)
        self._setup_reach(cfg, **reach_settings(cfg, delta_action=delta_action, ee_action_type=ee_action_type))
        ee_low = np.asarray(cfg["position_ee_min"]) + self.base_position
        ee_high = np.asarray(cfg["position_ee_max"]) + self.base_position
        vel = cfg["max_joint_vel"] * np.ones(len(self.ARM_JOINTS))
        self._setup_goal_spaces(
            np.concatenate([ee_low, self.chain.lower, self.action_box.low, -vel]),
            np.concatenate([ee_high, self.chain.upper, self.action_box.high, vel]),
        )
        self.setup_cameras(camera)

    # -- the camera's images on top of the goal task's observation ---------------------------------------
    @classmethod
    def batch_results(cls, envs: Sequence[Any], states: RobotStates) -> StepResults:
        return cls.add_images(envs, super().batch_results(envs, states))

    def _get_obs(self) -> Any:
        return self.with_images(super()._get_obs())
