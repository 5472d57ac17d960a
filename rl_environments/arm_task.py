"""What a task of the arm envs is: an object per env that owns its episode's values, and class methods
that act on and score the rows of a batch.

An :class:`~rl_environments.arm_env.ArmEnv` is made of an arm (:class:`~rl_environments.arm.Arm`), a task
and a side (the simulation node or a robot's driver). The env builds the side's connection, then the
task (``task_class(host, arm, options, config)``), and steps every env, one alone or N in a batched
vector env, through the same two class methods:

* :meth:`ArmTask.act` turns the N rows of checked actions into commands on each env's connection;
* :meth:`ArmTask.results` turns the robots' states after the step into N observations, rewards, episode
  ends and infos (:class:`~multiros.envs.batch_task.StepResults`).

Each operation is the same row by row whatever N, so an env's numbers do not depend on the batch it is in
(``tests/envs/test_golden_trajectories.py``). A new task is a subclass of :class:`ArmTask` in a module of its
own and a row of the task table (:data:`rl_environments.env_ids.TASKS`); ``rl_environments/slide_task.py``
is one, written this way.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np
from gymnasium import spaces

from multiros.envs.batch_task import StepResults
from multiros.envs.connection import RobotConnection
from multiros.robot_state import RobotStates
from multiros.utils.ros_markers import goal_marker
from rl_environments.arm import Arm
from rl_environments.task_config import TaskConfigError, load_task_config

__all__ = ["ArmTask", "TaskHost", "TaskOptions", "column", "load_arm_task_config", "numbers", "row_norms", "rows"]

T = TypeVar("T", bound="ArmTask")


class TaskHost(Protocol):
    """What a task uses of its env: the robot's connection, the step's info, the env's random stream and
    its ROS node (goal markers)."""

    connection: RobotConnection
    info: dict[str, Any]
    np_random: np.random.Generator
    robot_name: str

    @property
    def node(self) -> Any: ...


@dataclasses.dataclass(frozen=True)
class TaskOptions:
    """The keyword arguments every task takes (a task's own options subclass it).

    Attributes:
        reward_type: ``"sparse"`` or ``"dense"`` (``None``: the task's default for its kind of env).
        ee_action_type: end-effector delta actions (through IK) rather than joint deltas.
        config_file: a task config of your own (file name in ``rl_environments.config`` or a path, keys under
            ``<robot name>:``); default the arm file's section.
    """

    reward_type: str | None = None
    ee_action_type: bool = False
    config_file: str | None = None

    @classmethod
    def take(cls, kwargs: dict[str, Any]) -> Any:
        """Pop this record's keywords from an env's ``kwargs`` (the rest go to the side and the cameras)."""
        names = [f.name for f in dataclasses.fields(cls)]
        return cls(**{name: kwargs.pop(name) for name in names if name in kwargs})


def rows(tasks: Sequence[ArmTask], name: str) -> np.ndarray:
    """The tasks' value ``name`` (arrays of one shape, or numbers) as rows of one array."""
    if len(tasks) == 1:
        return np.asarray(getattr(tasks[0], name))[None]
    return np.array([getattr(task, name) for task in tasks])


def column(tasks: Sequence[ArmTask], name: str) -> float | np.ndarray:
    """The tasks' number ``name`` as a column ``(N, 1)`` to scale rows with; the number itself for one task
    (it broadcasts alike, and costs no array)."""
    if len(tasks) == 1:
        return float(getattr(tasks[0], name))
    return np.array([getattr(task, name) for task in tasks], dtype=np.float64)[:, None]


def numbers(tasks: Sequence[ArmTask], name: str) -> float | np.ndarray:
    """The tasks' number ``name``: ``(N,)``, or the number itself for one task."""
    if len(tasks) == 1:
        return float(getattr(tasks[0], name))
    return np.array([getattr(task, name) for task in tasks], dtype=np.float64)


def row_norms(vectors: np.ndarray) -> np.ndarray:
    """``np.linalg.norm`` of each row (row by row: a batch's norms equal one env's, bit for bit)."""
    return np.array([np.linalg.norm(v) for v in vectors])


def load_arm_task_config(arm: Arm, section: str, schema: Any, config_file: str | None,
                         defaults: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """A task's config: the arm file's ``section`` (checked when it was loaded), or ``config_file``'s keys
    under ``<robot name>:``, checked against ``schema`` and the arm's joints."""
    if config_file is None:
        return arm.task_config(section)
    cfg = load_task_config(config_file, schema, section=arm.robot_name, defaults=defaults)
    joints = tuple(cfg["arm_joints"])
    if joints != arm.joints:
        raise TaskConfigError(f"{config_file}: arm_joints {list(joints)} are not the {arm.name}'s joints "
                              f"{list(arm.joints)} (in that order)")
    return cfg


class ArmTask:
    """A task of the arm envs (see the module docstring). Subclasses set the class attributes and
    implement the methods below.

    Attributes:
        NAME: the task's name in the task table (``reach``, ``push``, ``pnp``, ``slide``).
        OPTIONS: the record of its keyword arguments.
        SCENE: the task has a table and an object (a robot's side then takes the tracker's and the
            gripper's options).
        NUM_SIM_STEPS: physics steps per env step in simulation (``None``: the arm's 40 ms).
        host, arm, goal_conditioned: the env, its arm, and whether its observations are goal dicts.
        action_space, observation_space: the task's spaces (the state observation: cameras add images).
    """

    NAME: ClassVar[str]
    OPTIONS: ClassVar[type[TaskOptions]] = TaskOptions
    SCENE: ClassVar[bool] = False
    NUM_SIM_STEPS: ClassVar[int | None] = None
    action_space: spaces.Box
    observation_space: spaces.Space[Any]
    goal: np.ndarray
    tolerance: float
    min_joint_pos: np.ndarray  # the task's joint range (a robot's safety rules take it too)
    max_joint_pos: np.ndarray
    _goal_marker: Any = None

    def __init__(self, host: TaskHost, arm: Arm, options: TaskOptions, cfg: Mapping[str, Any], *,
                 goal_conditioned: bool) -> None:
        self.host, self.arm, self.options, self.cfg = host, arm, options, dict(cfg)
        self.goal_conditioned = goal_conditioned

    # -- before the side exists --------------------------------------------------------------------
    @classmethod
    def load_config(cls, arm: Arm, options: TaskOptions) -> dict[str, Any]:
        """The task's config for ``arm``."""
        raise NotImplementedError

    @classmethod
    def side_defaults(cls, cfg: Mapping[str, Any], kwargs: dict[str, Any]) -> None:
        """Set the side's keyword arguments the task decides unless the user did (the arm on its table)."""

    # -- the episode, one env at a time -------------------------------------------------------------
    def reset_pose(self) -> None:
        """Bring the robot to the episode's initial pose (a teleport in simulation, a slow move on a robot)."""
        raise NotImplementedError

    def start_episode(self, rng: np.random.Generator) -> None:
        """Sample the episode's goal (and put its object), from the env's random stream."""
        raise NotImplementedError

    # -- the step, rows of a batch ---------------------------------------------------------------------
    @classmethod
    def act(cls: type[T], tasks: Sequence[T], actions: np.ndarray, states: RobotStates) -> None:
        """Commands from the N checked ``actions`` (rows in ``tasks``' order; ``states`` the robots' now)."""
        raise NotImplementedError

    @classmethod
    def results(cls: type[T], tasks: Sequence[T], states: RobotStates) -> StepResults:
        """Observations, rewards, episode ends and infos of N envs from their robots' states after the step."""
        raise NotImplementedError

    def observe(self) -> Any:
        """This env's observation now (its row of :meth:`results`' observations)."""
        raise NotImplementedError

    # -- goal-conditioned envs: vectorised, read only their arguments (HER) -------------------------------
    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        raise NotImplementedError

    def is_success(self, achieved_goal: Any, desired_goal: Any) -> Any:
        raise NotImplementedError

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """Success ends the episode (a task that keeps going past it says otherwise)."""
        return self.is_success(achieved_goal, desired_goal)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        if np.ndim(achieved_goal) > 1:
            return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool)
        return False

    # -- scripted demonstrations and checks ------------------------------------------------------------
    def scene_entities(self) -> tuple[str, ...]:
        """The task's own entities a randomiser may change: its object's, then its table's (none here)."""
        return ()

    def tracked_frames(self) -> tuple[str, ...]:
        """Frames a robot's tracker would report (their readings get the tracker's noise; none here)."""
        return ()

    def scripted_policy(self) -> Any:
        """A policy that does the task from observations (``uniros arm check``, demonstrations)."""
        raise ValueError(f"no scripted policy for the task {self.NAME!r}")

    # -- shared by the tasks -----------------------------------------------------------------------------
    @property
    def connection(self) -> RobotConnection:
        return self.host.connection

    @property
    def info(self) -> dict[str, Any]:
        """The env's info of this step."""
        return self.host.info

    @property
    def base_position(self) -> np.ndarray:
        """World position of the robot base: its spawn position in simulation, ``base_position`` on a robot."""
        return self.host.connection.base_position

    def show_goal(self, position: np.ndarray, diameter: float, ns: str | None = None) -> None:
        """A sphere at the goal for rendered images, the viewer and RViz (once per episode, never from
        ``compute_reward``, which HER calls on batches)."""
        if self._goal_marker is None:
            node = self.host.node
            self._goal_marker = (goal_marker(node, position, diameter=diameter) if ns is None else
                                 goal_marker(node, position, diameter=diameter, ns=ns))
        else:
            self._goal_marker.update(position=position)

    def goal_spaces(self, obs_low: np.ndarray, obs_high: np.ndarray, achieved: slice,
                    goal_low: np.ndarray, goal_high: np.ndarray) -> spaces.Dict:
        """A goal env's Dict space: ``observation`` within its bounds, ``achieved_goal`` its ``achieved``
        slice, ``desired_goal`` the goal box."""
        f32 = np.float32
        return spaces.Dict({
            "observation": spaces.Box(np.asarray(obs_low, f32), np.asarray(obs_high, f32), dtype=f32),
            "achieved_goal": spaces.Box(np.asarray(obs_low, f32)[achieved], np.asarray(obs_high, f32)[achieved],
                                        dtype=f32),
            "desired_goal": spaces.Box(np.asarray(goal_low).astype(f32), np.asarray(goal_high).astype(f32), dtype=f32),
        })
