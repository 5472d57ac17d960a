"""The reach task of every arm, plain and goal-conditioned, configured per arm by its arm file's
``reach:`` section (:mod:`rl_environments.arm_file`; a ``config_file=`` of your own has the keys under
``<robot name>:``), checked by :func:`~rl_environments.task_config.reach_schema`.

## Description
The end effector (the arm's ``ee_link``, moved by its ``tcp_offset``) must come within
``reach_tolerance`` of a goal sampled inside the config's goal box, among points the arm can reach
(forward kinematics of random joint configurations within the task's joint range). One env step is one
lockstep round trip to the simulation node: 25 physics steps of 4 ms, 100 ms (``num_sim_steps`` changes
it), long enough for the arm to settle on each 0.05 rad joint target. Episodes start at the config's
``init_joint_pos``.

## Action space
``Box(-1, 1, (n,))`` for an arm of n joints: joint deltas, ``target = joints + action * delta_coeff``,
clipped to the task's joint range. ``delta_action=False``: absolute joint targets in
``[min_joint_pos, max_joint_pos]``. ``ee_action_type=True``: ``Box(-1, 1, (3,))`` end-effector deltas
(``ee_delta_coeff`` metres) solved by damped-least-squares IK.

## Observation space
Plain envs: ``Box(float32)`` of 3 + 3 + 1 + n + n_action + n values: EE position, unit vector EE -> goal,
distance, arm joint positions, previous action, arm joint velocities. Goal envs:
``Dict(observation, achieved_goal, desired_goal)``, ``observation`` = EE position, arm joints, previous
action, joint velocities (no goal-dependent values, which HER relabelling would leave stale);
``achieved_goal`` the EE position, ``desired_goal`` the goal. Every value lies inside the declared bounds
(clipped). Camera observations: ``rgb_obs_only``, ``rgb_plus_normal_obs``,
``rgb_plus_depth_plus_normal_obs`` (:mod:`rl_environments.camera_obs`).

## Rewards
Plain: ``reward_type="dense"`` (default) ``-distance`` (``simple_dense_reward=True``) or the shaped reward
(``+reached_goal_reward`` on success, else ``multiplier_dist_reward * -distance + step_reward``, plus
``joint_limits_reward`` at a joint limit); ``"sparse"``: +1 on success, -1 otherwise. Goal envs:
``"sparse"`` (default) 0 within ``reach_tolerance``, else -1 (Fetch's); ``"dense"`` ``-distance``;
``compute_reward`` is vectorised for HER.

## Episode end
Terminated on success (``info["is_success"] = True``); truncated after 100 steps (registration).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.robot_state import RobotStates
from rl_environments.arm import Arm
from rl_environments.arm_task import (
    ArmTask,
    TaskHost,
    TaskOptions,
    column,
    load_arm_task_config,
    numbers,
    row_norms,
    rows,
)
from rl_environments.reach import (
    GoalSampler,
    goal_distance,
    goal_reward,
    is_success,
    parse_reward_type,
    reward_from_distance,
)
from rl_environments.task_config import reach_schema

__all__ = ["OBS_PARTS", "REACH_NUM_SIM_STEPS", "ReachOptions", "ReachTask"]

# Physics steps of 4 ms per env step: a 100 ms control period (MultiROS' RX200 ran its loop at 10 Hz with
# a 0.1 s action cycle; the Real twins' loop is 10 Hz too). The arm then ends each step on its joint target
# (within ~0.005 rad of a 0.05 rad delta, moving < 0.4 rad/s); with the arm default of 40 ms it lagged or
# overshot the target by 20-50 % and was still moving, and HER + SAC needed more steps (docs/tasks.md).
REACH_NUM_SIM_STEPS = 25

#: What a goal env's ``observation`` may hold, in the order a task names them (the EE position first).
OBS_PARTS = ("ee_position", "arm_positions", "prev_action", "arm_velocities")


@dataclasses.dataclass(frozen=True)
class ReachOptions(TaskOptions):
    """The reach's keyword arguments (see :class:`~rl_environments.arm_task.TaskOptions` for the common ones).

    Attributes:
        delta_action: joint deltas (True) or absolute joint targets.
        simple_dense_reward: plain envs' dense reward: ``-distance`` (True) or the shaped reward.
    """

    delta_action: bool = True
    simple_dense_reward: bool = True


class ReachTask(ArmTask):
    """The reach (see the module docstring): one env's goal, previous action and joint targets."""

    NAME = "reach"
    OPTIONS: ClassVar[type[TaskOptions]] = ReachOptions
    NUM_SIM_STEPS: ClassVar[int | None] = REACH_NUM_SIM_STEPS
    #: A goal env's ``observation``, from :data:`OBS_PARTS`.
    GOAL_OBS_PARTS: ClassVar[tuple[str, ...]] = OBS_PARTS
    options: ReachOptions

    @classmethod
    def load_config(cls, arm: Arm, options: TaskOptions) -> dict[str, Any]:
        return load_arm_task_config(arm, "reach", reach_schema(len(arm.joints)), options.config_file)

    def __init__(self, host: TaskHost, arm: Arm, options: ReachOptions, cfg: Mapping[str, Any], *,
                 goal_conditioned: bool) -> None:
        super().__init__(host, arm, options, cfg, goal_conditioned=goal_conditioned)
        self.reward_type = parse_reward_type(options.reward_type or ("sparse" if goal_conditioned else "dense"))
        parts = type(self).GOAL_OBS_PARTS
        if goal_conditioned and any(name not in OBS_PARTS for name in parts):
            raise ValueError(f"{type(self).__name__}.GOAL_OBS_PARTS names {list(parts)}; parts: {list(OBS_PARTS)}")
        self.setup(self.settings())
        self.observation_space = self.make_observation_space()

    def settings(self) -> dict[str, Any]:
        """The action kind, scales, tolerance and goal box (base frame), from the config."""
        cfg = self.cfg
        return {"delta_action": self.options.delta_action, "ee_action_type": self.options.ee_action_type,
                "delta_coeff": cfg["delta_coeff"], "ee_delta_coeff": cfg["ee_delta_coeff"],
                "tolerance": cfg["reach_tolerance"], "goal_min": cfg["position_goal_min"],
                "goal_max": cfg["position_goal_max"]}

    def setup(self, s: Mapping[str, Any]) -> None:
        """Joint ranges, the goal sampler and the action space."""
        cfg = self.cfg
        self.chain = self.arm.chain
        self.delta_action, self.ee_action_type = bool(s["delta_action"]), bool(s["ee_action_type"])
        self.delta_coeff, self.ee_delta_coeff = float(s["delta_coeff"]), float(s["ee_delta_coeff"])
        self.tolerance = float(s["tolerance"])
        self.min_joint_pos = np.asarray(cfg["min_joint_pos"], dtype=np.float64)
        self.max_joint_pos = np.asarray(cfg["max_joint_pos"], dtype=np.float64)
        self.init_joint_pos = np.asarray(cfg["init_joint_pos"], dtype=np.float64)
        n = len(self.arm.joints)
        for key in ("min_joint_pos", "max_joint_pos", "init_joint_pos"):
            if getattr(self, key).shape != (n,):
                raise ValueError(f"task config key {key!r} must have {n} values (one per arm joint), got "
                                 f"{getattr(self, key).tolist()}")
        base = self.base_position
        self.goal_min = np.asarray(s["goal_min"], dtype=np.float64) + base
        self.goal_max = np.asarray(s["goal_max"], dtype=np.float64) + base
        self.goal_sampler = GoalSampler(self.chain, s["goal_min"], s["goal_max"], base_position=base,
                                        joint_low=self.min_joint_pos, joint_high=self.max_joint_pos)
        if self.ee_action_type:
            self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        elif self.delta_action:
            self.action_space = spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        else:
            self.action_space = spaces.Box(self.min_joint_pos.astype(np.float32),
                                           self.max_joint_pos.astype(np.float32), dtype=np.float32)
        self.goal = self.goal_sampler.sample(np.random.default_rng(0))
        self.prev_action = np.zeros(self.action_space.shape, dtype=np.float64)
        self.joint_targets = self.init_joint_pos.copy()

    def make_observation_space(self) -> spaces.Space[Any]:
        """The plain env's Box or the goal env's Dict (see the module docstring)."""
        cfg, act = self.cfg, self.action_space
        ee_low = np.asarray(cfg["position_ee_min"]) + self.base_position
        ee_high = np.asarray(cfg["position_ee_max"]) + self.base_position
        n = len(self.arm.joints)
        vel = float(cfg["max_joint_vel"]) * np.ones(n)
        if self.goal_conditioned:
            return self.goal_spaces(np.concatenate([ee_low, self.chain.lower, act.low, -vel]),
                                    np.concatenate([ee_high, self.chain.upper, act.high, vel]), slice(0, 3),
                                    self.goal_min, self.goal_max)
        self.ee_low, self.ee_high, self.max_vel = ee_low, ee_high, float(cfg["max_joint_vel"])
        max_dist = float(np.linalg.norm(ee_high - ee_low))
        low = np.concatenate([ee_low, -np.ones(3), [0.0], self.chain.lower, act.low, -self.max_vel * np.ones(n)])
        high = np.concatenate([ee_high, np.ones(3), [max_dist], self.chain.upper, act.high,
                               self.max_vel * np.ones(n)])
        return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)

    # -- the episode ------------------------------------------------------------------------------------
    def reset_pose(self) -> None:
        self.connection.move_to_initial_pose(self.arm.joints, self.init_joint_pos)
        self.joint_targets = self.init_joint_pos.copy()

    def start_episode(self, rng: np.random.Generator) -> None:
        self.goal = self.goal_sampler.sample(rng)
        self.prev_action = np.zeros(self.action_space.shape, dtype=np.float64)
        self.show_goal(self.goal, 2 * self.tolerance)

    # -- actions, rows of a batch ----------------------------------------------------------------------
    @classmethod
    def act(cls, tasks: Sequence[ReachTask], actions: np.ndarray, states: RobotStates) -> None:
        """Joint targets from N actions (each env's own kind: deltas, absolute, or EE deltas), clipped into
        each env's joint range, sent to each arm; ``prev_action`` and ``joint_targets`` kept."""
        arm = tasks[0].arm
        current = arm.positions_of(states)
        kind: tuple[bool, bool] | None = (tasks[0].ee_action_type, tasks[0].delta_action)
        if len(tasks) > 1 and any((t.ee_action_type, t.delta_action) != kind for t in tasks):
            kind = None  # envs of several kinds: row by row
        if kind == (False, True):  # joint deltas, every env: one pass
            targets = current + actions * column(tasks, "delta_coeff")
        elif kind == (False, False):
            targets = actions
        else:
            targets = np.array([t.row_targets(current[j], actions[j], states, j) for j, t in enumerate(tasks)])
        targets = np.minimum(np.maximum(targets, rows(tasks, "min_joint_pos")), rows(tasks, "max_joint_pos"))
        for task, target, action in zip(tasks, targets, actions):
            task.joint_targets = target
            task.prev_action = action
            arm.command_arm(task.connection, target, task.info)

    def row_targets(self, current: np.ndarray, action: np.ndarray, states: RobotStates, j: int) -> np.ndarray:
        """One env's joint targets for its action (row ``j`` of ``states``)."""
        if self.ee_action_type:
            ee = self.arm.ee_positions_of(self.connection, states.batch_of_row(j))[0]
            target_ee = ee - self.base_position + action * self.ee_delta_coeff
            return self.chain.ik(target_ee, q0=current, max_iters=30, restarts=0, tol=1e-3).q
        if self.delta_action:
            return current + action * self.delta_coeff
        return action

    # -- observations and scores, rows of a batch -------------------------------------------------------
    @classmethod
    def results(cls, tasks: Sequence[ReachTask], states: RobotStates) -> StepResults:
        if tasks[0].goal_conditioned:
            return cls.goal_results(tasks, states)
        obs, ee, dist = cls.observe_rows(tasks, states)
        n = len(tasks)
        reward, done = np.zeros(n), np.zeros(n, dtype=bool)
        for j, task in enumerate(tasks):
            reward[j], done[j] = task.score(float(dist[j]), ee[j])
        infos = [task.info for task in tasks]
        for info in infos:
            info.setdefault("is_success", False)
        return StepResults(obs, reward, done, np.zeros(n, dtype=bool), infos)

    @classmethod
    def observe_rows(cls, tasks: Sequence[ReachTask], states: RobotStates) -> tuple[np.ndarray, np.ndarray,
                                                                                      np.ndarray]:
        """Plain envs: N observations, their end effectors and their goal distances."""
        arm = tasks[0].arm
        ee_raw = arm.ee_positions_of(tasks[0].connection, states)
        ee = np.clip(ee_raw, rows(tasks, "ee_low"), rows(tasks, "ee_high"))
        _, dist, unit = cls.goals_to(tasks, ee_raw)
        chains = [task.chain for task in tasks]
        q = np.clip(arm.positions_of(states), np.array([c.lower for c in chains]),
                    np.array([c.upper for c in chains]))
        max_vel = rows(tasks, "max_vel")[:, None]
        qd = np.clip(arm.velocities_of(states), -max_vel, max_vel)
        obs = np.concatenate([ee, unit, dist[:, None], q, rows(tasks, "prev_action"), qd], axis=1)
        boxes = [task.observation_space for task in tasks]
        low, high = np.array([b.low for b in boxes]), np.array([b.high for b in boxes])  # type: ignore[attr-defined]
        return np.clip(obs, low, high).astype(np.float32), ee_raw, dist

    def score(self, dist: float, ee: np.ndarray) -> tuple[float, bool]:
        """A plain env's reward and termination for a step that left the end effector at ``ee``."""
        reached = dist <= self.tolerance
        info = self.info
        info["is_success"] = reached
        info["distance"] = dist
        if self.reward_type == "sparse":
            return float(goal_reward(ee, self.goal, self.tolerance, "sparse", (1.0, -1.0))), reached
        if self.options.simple_dense_reward:
            return -dist, reached
        if reached:
            return self.cfg["reached_goal_reward"], reached
        reward = -self.cfg["multiplier_dist_reward"] * dist + self.cfg["step_reward"]
        if self.at_joint_limits():
            reward += self.cfg["joint_limits_reward"]
        return reward, reached

    @classmethod
    def goal_observe_rows(cls, tasks: Sequence[ReachTask], states: RobotStates) -> dict[str, np.ndarray]:
        """Goal envs: N observation dicts, stacked; one clip into each env's bounds covers the EE box, the
        joint limits and the velocity bounds."""
        parts = cls.GOAL_OBS_PARTS  # checked when the task was made
        # cast to float32 as they are joined (the bits of a cast after), then clipped in place
        obs = np.concatenate([cls.obs_part(name, tasks, states) for name in parts], axis=1, dtype=np.float32)
        if len(tasks) == 1:
            box = tasks[0].observation_space["observation"]  # type: ignore[index]
            low, high = box.low, box.high
        else:
            boxes = [task.observation_space["observation"] for task in tasks]  # type: ignore[index]
            low, high = np.array([b.low for b in boxes]), np.array([b.high for b in boxes])
        np.minimum(np.maximum(obs, low, out=obs), high, out=obs)
        return {"observation": obs, "achieved_goal": obs[:, :3].copy(),
                "desired_goal": np.array([task.goal for task in tasks], dtype=np.float32)}

    @staticmethod
    def obs_part(name: str, tasks: Sequence[ReachTask], states: RobotStates) -> np.ndarray:
        arm = tasks[0].arm
        if name == "ee_position":
            return arm.ee_positions_of(tasks[0].connection, states)
        if name == "arm_positions":
            return arm.positions_of(states)
        if name == "arm_velocities":
            return arm.velocities_of(states)
        return rows(tasks, "prev_action")

    @classmethod
    def goal_results(cls, tasks: Sequence[ReachTask], states: RobotStates) -> StepResults:
        """Goal envs: observation, reward (each env's ``reward_type``), success as termination."""
        obs = cls.goal_observe_rows(tasks, states)
        distance = goal_distance(obs["achieved_goal"], obs["desired_goal"])  # what is_success and goal_reward compute
        tolerance = numbers(tasks, "tolerance")
        success = distance <= tolerance
        types = {task.reward_type for task in tasks}
        if len(types) == 1:
            reward = reward_from_distance(distance, tolerance, types.pop()).astype(np.float64)  # type: ignore[union-attr]
        else:
            reward = np.array([np.asarray(reward_from_distance(distance[j:j + 1], t.tolerance, t.reward_type))[0]
                               for j, t in enumerate(tasks)], dtype=np.float64)
        infos = []
        for task, reached in zip(tasks, success.tolist()):
            info = task.info
            info.setdefault("is_success", reached)
            infos.append(info)
        return StepResults(obs, reward, success, np.zeros(len(tasks), dtype=bool), infos)

    def observe(self) -> Any:
        states = self.connection.states
        if self.goal_conditioned:
            return {k: v[0] for k, v in type(self).goal_observe_rows([self], states).items()}
        return type(self).observe_rows([self], states)[0][0]

    # -- goal envs (HER) ------------------------------------------------------------------------------
    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return goal_reward(achieved_goal, desired_goal, self.tolerance, self.reward_type)

    def is_success(self, achieved_goal: Any, desired_goal: Any) -> Any:
        return is_success(achieved_goal, desired_goal, self.tolerance)

    # -- helpers ------------------------------------------------------------------------------------------
    def at_joint_limits(self, margin: float = 1e-4) -> bool:
        """True when an arm joint target sits at a limit of the task's joint range."""
        q = self.joint_targets
        return bool(np.any(q <= self.min_joint_pos + margin) or np.any(q >= self.max_joint_pos - margin))

    @staticmethod
    def goals_to(tasks: Sequence[ReachTask], ee: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each env: the vector from the end effector ``ee[j]`` to its goal, its length and the unit
        vector (zeros at the goal)."""
        vec = rows(tasks, "goal") - ee
        dist = row_norms(vec)
        unit = np.zeros_like(vec)
        far = dist > 1e-9
        unit[far] = vec[far] / dist[far, None]
        return vec, dist, unit

    def scripted_policy(self) -> Any:
        from rl_environments.manipulation_scripted import ScriptedReach

        if not self.ee_action_type:
            fix = "make the env with ee_action_type=True" if self.OPTIONS is ReachOptions else \
                f"the task {self.NAME!r} acts in joint deltas"
            raise ValueError(f"the scripted policies drive end-effector actions: {fix}")
        return ScriptedReach(ee_delta_coeff=self.ee_delta_coeff)
