"""The arm envs: an arm, a task and a side make an env.

Every shipped arm ID is one of four classes made with keyword arguments, e.g.
``gymnasium.make("RX200PushGoalSim-v0")`` is ``ArmSimGoalEnv(arm="RX200", task="push")``:

==========================  =====================================  ==============================
class                       side                                   observations
==========================  =====================================  ==============================
:class:`ArmSimEnv`          the MuJoCo simulation node             a Box (or a Dict with images)
:class:`ArmSimGoalEnv`      the MuJoCo simulation node             a goal Dict, for HER
:class:`ArmRealEnv`         a real robot's ros2_control driver     a Box
:class:`ArmRealGoalEnv`     a real robot's ros2_control driver     a goal Dict
==========================  =====================================  ==============================

* the **arm** is a value made from its arm file (:class:`~rl_environments.arm.Arm`): joints, end effector,
  chain, gripper, scene, and each side's constructor arguments;
* the **task** is an object the env makes once its side is up (:class:`~rl_environments.arm_task.ArmTask`:
  reach, push, pick-and-place, slide, FRobs_RL's reacher; the table in :data:`rl_environments.env_ids.TASKS`);
* the **side** is the env core the class stands on (:class:`~multiros.envs.sim_env.MujocoEnvCore` or
  :class:`~multiros.envs.real.core.RealEnvCore`): it builds the robot's connection from its knobs;
* **cameras** are a component (:class:`~rl_environments.camera_obs.Cameras`) when the env observes images.

A step is the same for one env and for the N envs of a batched vector env (:mod:`multiros.envs.batch`):
:func:`~multiros.envs.batch_task.act_rows` (each env's info emptied, its connection's checks, then the
task's :meth:`~rl_environments.arm_task.ArmTask.act` on the rows of checked actions), the connection's
advance (one call per node in a batch), and the task's
:meth:`~rl_environments.arm_task.ArmTask.results` with the cameras' images.

Keyword arguments: the task's options (its ``OPTIONS`` record, e.g. ``reward_type``, ``ee_action_type``),
camera options (:mod:`rl_environments.camera_obs`), and the side's knobs (``sim_mode``, ``seed``,
``num_sim_steps``...; on a robot ``namespace``, ``max_joint_delta``, ``base_position``...).

The MultiROS hook classes (:class:`~multiros.envs.MujocoBaseEnv`, :class:`~multiros.envs.MujocoGoalEnv`,
:class:`~multiros.envs.real.RealBaseEnv`, :class:`~multiros.envs.real.RealGoalEnv`) stay for envs written
by hand (docs/create_env.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium_robotics.core import GoalEnv

from multiros.envs.base_env import end_on_fault
from multiros.envs.batch_task import StepResults, act_rows
from multiros.envs.core import EnvCore
from multiros.envs.errors import EnvError, StepAfterFailedReset
from multiros.envs.real.core import RealEnvCore
from multiros.envs.sim_env import MujocoEnvCore
from multiros.robot_state import RobotStates
from rl_environments.arm import Arm
from rl_environments.arm_task import ArmTask
from rl_environments.camera_obs import Cameras, parse_camera_options
from rl_environments.randomization import WorldRandomizer

__all__ = ["ArmEnv", "ArmRealEnv", "ArmRealGoalEnv", "ArmSimEnv", "ArmSimGoalEnv", "TaskAttributeWarning",
           "arm_env_class"]

StepResult = tuple[Any, float, bool, bool, dict[str, Any]]


#: What a task reads of its env (arm_task.TaskHost): never looked up on the task (it would ask the env again).
_HOST = frozenset({"connection", "info", "node", "np_random", "robot_name", "task", "arm", "cameras"})


class TaskAttributeWarning(DeprecationWarning):
    """An arm env's task value read from the env (``env.goal``): it is the task's (``env.task.goal``)."""


class ArmEnv(EnvCore):
    """What the four arm env classes share: their construction, reset and step (see the module docstring).

    Args:
        arm: the arm's name (a registered arm file's ``name``, e.g. ``"RX200"``) or an
            :class:`~rl_environments.arm.Arm`.
        task: the task's name in :data:`rl_environments.env_ids.TASKS` (``"reach"``, ``"push"``, ``"pnp"``,
            ``"slide"``, ...) or an :class:`~rl_environments.arm_task.ArmTask` class.
        **kwargs: the task's options, camera options and the side's knobs.
    """

    #: An env class of its own for one arm and task (the names kept from earlier releases) sets these.
    ARM: ClassVar[str | None] = None
    TASK: ClassVar[str | None] = None
    arm: Arm
    task: ArmTask
    cameras: Cameras | None
    randomizer: WorldRandomizer | None
    _failed_reset: str | None = None  # the error of the last reset, while no reset has succeeded since

    def __init__(self, arm: str | Arm | None = None, task: str | type[ArmTask] | None = None, **kwargs: Any) -> None:
        from rl_environments.arm_registry import arm_value
        from rl_environments.env_ids import task_class

        gym.Env.__init__(self)
        arm, task = arm or self.ARM, task or self.TASK
        if arm is None or task is None:
            raise TypeError(f"{type(self).__name__} needs arm= (an arm's name) and task= (a task's name)")
        self.arm = arm if isinstance(arm, Arm) else arm_value(arm)
        task_cls = task_class(task) if isinstance(task, str) else task
        options = task_cls.OPTIONS.take(kwargs)
        cfg = task_cls.load_config(self.arm, options)
        task_cls.side_defaults(cfg, kwargs)
        camera = parse_camera_options(kwargs, type(self).__name__, real=self.ON_ROBOT,
                                      defaults=self.arm.camera_defaults)
        randomization = kwargs.pop("randomization", None)
        self.randomizer = None
        try:
            self._open_side(task_cls, cfg, kwargs)
            self.task = task_cls(self, self.arm, options, cfg, goal_conditioned=isinstance(self, GoalEnv))
            self.action_space = self.task.action_space
            self.observation_space = self.task.observation_space
            self.cameras = None
            if camera is not None:
                self.cameras = Cameras(camera, self.connection, self.arm.camera_view, self.arm.camera_topics,
                                       self.connection.base_position)
                self.observation_space = self.cameras.open(self.task.observation_space)
            if self.ON_ROBOT:  # the task's joint range tightens the safety rules' (the tighter bound wins)
                self.connection.limit_joints(self.task.min_joint_pos, self.task.max_joint_pos)
            self.randomizer = WorldRandomizer.for_env(self, randomization)
        except BaseException:
            self.close()
            raise

    def _open_side(self, task_cls: type[ArmTask], cfg: dict[str, Any], kwargs: dict[str, Any]) -> None:
        """The side's connection, from the arm's constructor arguments and the user's knobs."""
        if isinstance(self, RealEnvCore):
            box = (cfg["position_ee_min"], cfg["position_ee_max"]) if task_cls.SCENE else None
            opts, setup = self.arm.real_kwargs(kwargs, scene=box)
            self._init_real(**opts)
            setup.apply(self.connection)
        elif isinstance(self, MujocoEnvCore):
            if task_cls.NUM_SIM_STEPS:
                kwargs.setdefault("num_sim_steps", task_cls.NUM_SIM_STEPS)
            self._init_core(**self.arm.sim_kwargs(kwargs))
        else:
            raise TypeError(f"{type(self).__name__} stands on no side (MujocoEnvCore or RealEnvCore)")

    # -- an episode --------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        try:
            seed = self._take_seed(seed)
            super().reset(seed=seed)  # type: ignore[misc]  # gymnasium's: the random stream
            self.info = {}
            self.connection.reset(self.info)
            self.arm.arm_index(self.robot_state.names)  # the robot reports the arm's joints
            if self.randomizer is not None:  # this episode's world (rl_environments.randomization)
                self.randomizer.apply(seed)
            self.task.reset_pose()
            self.task.start_episode(self.np_random)  # type: ignore[attr-defined]
            self.connection.start_episode(self.info)
            obs = self.observe()
            info = self.info
            success = self.task.is_success(obs["achieved_goal"], obs["desired_goal"]) if self.task.goal_conditioned \
                else False
            info.setdefault("is_success", bool(success))
        except BaseException as exc:
            self._failed_reset = f"{type(exc).__name__}: {exc}"[:300]
            raise
        self._failed_reset = None
        return obs, info

    def step(self, action: Any) -> StepResult:
        """Act, advance the robot, score: one env as a batch of one."""
        if self._failed_reset is not None:
            raise StepAfterFailedReset(f"{type(self).__name__}.step() after a reset that failed "
                                       f"({self._failed_reset}); call reset() again and step once it returns")
        actions = self.check_actions(np.asarray(action, dtype=np.float64)[None], single=True)
        act_rows(type(self), [self], actions, self.connection.states)
        self.step_advance()
        return end_on_fault(type(self).batch_results([self], self.connection.states)).row(0)

    # -- the step of N envs (multiros.envs.batch: a batched vector env calls these) --------------------
    @classmethod
    def batch_act(cls, envs: Sequence[ArmEnv], actions: np.ndarray, states: RobotStates) -> None:
        """The task's commands for N envs' checked ``actions`` (rows in ``envs``' order)."""
        type(envs[0].task).act([env.task for env in cls._alike(envs)], actions, states)

    @classmethod
    def batch_results(cls, envs: Sequence[ArmEnv], states: RobotStates) -> StepResults:
        """N envs' observations (with their cameras' images), rewards, episode ends and infos."""
        results = type(envs[0].task).results([env.task for env in cls._alike(envs)], states)
        return Cameras.add_images([env.cameras for env in envs], results)

    @staticmethod
    def _alike(envs: Sequence[ArmEnv]) -> Sequence[ArmEnv]:
        kind = type(envs[0].task)
        if any(type(env.task) is not kind for env in envs):
            raise EnvError(f"a batch steps envs of one task; got {sorted({type(e.task).__name__ for e in envs})}")
        return envs

    def observe(self) -> Any:
        """This env's observation now (the task's, with the cameras' images)."""
        obs = self.task.observe()
        return obs if self.cameras is None else self.cameras.with_images(obs)

    # -- goal-conditioned envs: vectorised, reading only their arguments (HER); the goal classes name them
    # compute_reward, compute_terminated and compute_truncated (a plain env has none: checkers take an env
    # with compute_reward for a goal env)
    def goal_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return self.task.compute_reward(achieved_goal, desired_goal, info)

    def goal_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return self.task.compute_terminated(achieved_goal, desired_goal, info)

    def goal_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return self.task.compute_truncated(achieved_goal, desired_goal, info)

    @classmethod
    def accepted_keywords(cls, kwargs: dict[str, Any]) -> list[str]:
        """The task's options and the camera options an env of these keyword arguments takes (besides the
        side's knobs)."""
        import dataclasses

        from rl_environments.camera_obs import CAMERA_KEYWORDS
        from rl_environments.env_ids import task_class

        task = kwargs.get("task") or cls.TASK
        task_cls = task_class(task) if isinstance(task, str) else task
        names = [f.name for f in dataclasses.fields(task_cls.OPTIONS)] if task_cls is not None else []
        return ["arm", "task", "randomization", *names, *CAMERA_KEYWORDS]

    @classmethod
    def entity_name(cls, kwargs: dict[str, Any]) -> str:
        """The robot's entity name an env of these keyword arguments spawns (a batch names its robots after it)."""
        from rl_environments.arm_registry import arm_value

        arm = kwargs.get("arm") or cls.ARM
        named = kwargs.get("robot_name")
        return str(named or (arm.robot_name if isinstance(arm, Arm) else arm_value(str(arm)).robot_name))

    def __getattr__(self, name: str) -> Any:
        # The env classes of earlier releases were their task: code that reads a task's value from the env
        # (``env.unwrapped.goal``) keeps working, with a warning naming where it lives now.
        task = self.__dict__.get("task")
        if name.startswith(("_", "compute_")) or name in _HOST or task is None or not hasattr(task, name):
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        import warnings

        warnings.warn(f"{type(self).__name__}.{name} is the task's: read env.task.{name}", TaskAttributeWarning,
                      stacklevel=2)
        return getattr(task, name)

    # -- the arm now, for scripted policies and your own code -------------------------------------------
    def arm_positions(self) -> np.ndarray:
        """Arm joint positions after the last step, in the arm's joint order."""
        return self.arm.positions_of(self.connection.states)[0].copy()

    def ee_position(self) -> np.ndarray:
        """World position of the end effector after the last step."""
        return self.arm.ee_positions_of(self.connection, self.connection.states)[0].copy()


class ArmSimEnv(MujocoEnvCore, ArmEnv, gym.Env):
    """An arm and a task on the MuJoCo simulation node, plain observations (knobs:
    :class:`~multiros.envs.sim_env.MujocoEnvCore`)."""


class ArmSimGoalEnv(MujocoEnvCore, ArmEnv, GoalEnv):
    """An arm and a task on the MuJoCo simulation node, goal-conditioned for HER."""

    compute_reward = ArmEnv.goal_reward
    compute_terminated = ArmEnv.goal_terminated
    compute_truncated = ArmEnv.goal_truncated


class ArmRealEnv(RealEnvCore, ArmEnv, gym.Env):
    """An arm and a task on a real robot's driver, plain observations (knobs:
    :class:`~multiros.envs.real.core.RealEnvCore` and :meth:`~rl_environments.arm.Arm.real_kwargs`)."""


class ArmRealGoalEnv(RealEnvCore, ArmEnv, GoalEnv):
    """An arm and a task on a real robot's driver, goal-conditioned: a policy trained on
    :class:`ArmSimGoalEnv` runs here as it is (the same spaces)."""

    compute_reward = ArmEnv.goal_reward
    compute_terminated = ArmEnv.goal_terminated
    compute_truncated = ArmEnv.goal_truncated


def arm_env_class(*, real: bool, goal: bool) -> type[ArmEnv]:
    """The arm env class of a side and an observation kind."""
    return (ArmRealGoalEnv if goal else ArmRealEnv) if real else (ArmSimGoalEnv if goal else ArmSimEnv)
