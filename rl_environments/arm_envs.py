"""The env classes of registered arm files, built on first use (``rl_environments.arm_envs:<Class>``).

For an arm ``NAME`` (``rl_environments.arm_registry``): ``NAME<task>Env`` on the simulation node
and ``NAME<task>RealEnv`` on the robot's driver, for each ``<task>`` of ``Reacher``, ``ReacherGoal``,
``Push``, ``PushGoal``, ``PnP``, ``PnPGoal``; ``NAMERobotEnv``, ``NAMERobotGoalEnv``,
``NAMERobotRealEnv`` and ``NAMERobotRealGoalEnv`` without a task. Each is three parts: the task
every arm shares (named in the class's docstring), the arm's constants from its file
(``ArmFileRobot``), and the robot env of its side (``rl_environments.arm_robot_envs``). A class is
made once per name and kept, so gymnasium's string entry points and pickle find the same class
every time.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

from multiros.envs import EnvError
from multiros.utils.kinematics import KinematicChain
from rl_environments.arm_file import ArmFile
from rl_environments.arm_ik import TopDownIK
from rl_environments.arm_manipulation import ArmGoalManipulationTask, ArmManipulationTask
from rl_environments.arm_reach import REACH_NUM_SIM_STEPS, ArmGoalReachTask, ArmReachTask
from rl_environments.arm_registry import chain_of, top_down_ik_of
from rl_environments.arm_robot import ArmRobot
from rl_environments.arm_robot_envs import ArmRobotEnv, ArmRobotGoalEnv, ArmRobotRealEnv, ArmRobotRealGoalEnv
from rl_environments.real_arm_kwargs import TaskJointLimits


class ArmFileRobot(ArmRobot):
    """The robot layer of an arm file: :class:`~rl_environments.arm_robot.ArmRobot` whose constants
    come from ``ARM_FILE``, its chain from the file's description URI and its task settings from
    the file's ``reach:`` and ``manipulation:`` sections."""

    ARM_FILE: ClassVar[ArmFile]

    @classmethod
    def description_files(cls) -> tuple[str, dict[str, str], str]:
        spec = cls.ARM_FILE  # XACRO_ARGS: the file's, unless a variant of the arm sets others (the RX200's Zed2)
        return spec.description_uri, dict(cls.XACRO_ARGS), spec.controllers_file

    @classmethod
    def kinematic_chain(cls) -> KinematicChain:
        return chain_of(cls.ARM_FILE)

    @classmethod
    def top_down_ik(cls, lower: Sequence[float], upper: Sequence[float]) -> TopDownIK:
        return top_down_ik_of(cls.ARM_FILE, lower, upper)

    @classmethod
    def scene_uri(cls, item: str) -> str:
        return cls.ARM_FILE.scene_files.get("object" if item == "cube" else item, "")

    @classmethod
    def scene_mjcf(cls, item: str) -> str:
        """The file's ``scene:`` MJCF when it names one, else made from its ``manipulation`` sizes."""
        key = "object" if item == "cube" else item
        if key in cls.ARM_FILE.scene_files or cls.ARM_FILE.manipulation is None:
            return ""
        from rl_environments.arm_scene import scene_mjcf

        return scene_mjcf(cls.ARM_FILE.robot_name, cls.ARM_FILE.manipulation, key)

    @classmethod
    def task_config(cls, task: str) -> Mapping[str, Any]:
        """The file's ``reach`` or ``manipulation`` settings (checked when the file was loaded)."""
        section = cls.ARM_FILE.reach if task == "reach" else cls.ARM_FILE.manipulation
        if section is None:
            raise EnvError(f"{cls.ARM_FILE.path}: the arm has no gripper, so no {task} task")
        return section


#: What each task does, for the env classes' docstrings (the ID pages show them).
_TASK_WORDS = {
    "Reacher": ("the {arm} reaches a random point", "arm_reach", "ArmReachTask"),
    "ReacherGoal": ("the goal-conditioned {arm} reach, for HER", "arm_reach", "ArmGoalReachTask"),
    "Push": ("the {arm} pushes a cube to a goal on the table", "arm_manipulation", "ArmManipulationTask"),
    "PushGoal": ("the goal-conditioned {arm} push, for HER", "arm_manipulation", "ArmGoalManipulationTask"),
    "PnP": ("the {arm} picks a cube and places it at a goal, on the table or in the air", "arm_manipulation",
            "ArmManipulationTask"),
    "PnPGoal": ("the goal-conditioned {arm} pick-and-place, for HER", "arm_manipulation", "ArmGoalManipulationTask"),
}


def _docstring(name: str, task: str, real: bool, source: str) -> str:
    words, module, cls = _TASK_WORDS[task]
    what = words.format(arm=name)
    ref = f"the task: :mod:`rl_environments.{module}`; arguments: :class:`~rl_environments.{module}.{cls}`"
    if not real:
        return f"``{name}{task}Sim-v0``: {what} ({ref}). The arm: ``{source}``."
    extra = (" The object's pose comes from a tracker (``geometry_msgs/PoseStamped``) and the gripper is "
             "commanded through its driver (:mod:`rl_environments.real_arm_kwargs`)." if module == "arm_manipulation"
             else "")
    return (f"``{name}{task}Real-v0``: ``{name}{task}Sim-v0``'s task on a real {name}: {what} ({ref}; robot and "
            f"loop knobs: :func:`~rl_environments.real_arm_kwargs.real_robot_kwargs`).{extra} "
            f"The arm: ``{source}``.")


_CLASSES: dict[str, type] = {}
_ROBOTS: dict[tuple[str, bool], type] = {}


def _robot(name: str, real: bool) -> type:
    """The arm's constants class (``NAMERobot``) or its real one (``NAMERealRobot``)."""
    from rl_environments.arm_registry import arm_of, real_constants, robot_constants

    key = (name, real)
    cls = _ROBOTS.get(key)
    if cls is None:
        spec = arm_of(name)
        sim = _ROBOTS.get((name, False))
        if sim is None:
            sim = _ROBOTS[(name, False)] = type(f"{name}Robot", (ArmFileRobot,), {
                **robot_constants(spec), "__module__": __name__,
                "__doc__": f"The {name} arm's constants, from {spec.path.name}."})
        cls = sim
        if real:
            cls = _ROBOTS[key] = type(f"{name}RealRobot", (sim,), {
                **real_constants(spec), "__module__": __name__,
                "__doc__": f"The {name} arm's real-robot constants, from {spec.path.name}."})
    return cls


def _build(class_name: str) -> type | None:
    from rl_environments.arm_registry import ARM_TASKS, registered_arms

    for name in registered_arms():
        if class_name in (f"{name}Robot", f"{name}RealRobot"):
            return _robot(name, class_name.endswith("RealRobot"))
        for real in (False, True):
            for goal in (False, True):
                if class_name == f"{name}Robot{'Real' if real else ''}{'Goal' if goal else ''}Env":
                    return robot_env_class(name, goal=goal, real=real)
        for task, (goal, kind) in ARM_TASKS.items():
            real = class_name == f"{name}{task}RealEnv"
            if not real and class_name != f"{name}{task}Env":
                continue
            robot = _robot(name, real)
            side = (ArmRobotRealGoalEnv if goal else ArmRobotRealEnv) if real else (
                ArmRobotGoalEnv if goal else ArmRobotEnv)
            task_cls = ((ArmGoalManipulationTask if goal else ArmManipulationTask) if kind
                        else (ArmGoalReachTask if goal else ArmReachTask))
            bases: tuple[type, ...] = (task_cls, robot, side)
            if real:
                bases = (TaskJointLimits, *bases)
            source = registered_arms()[name].path.name
            attrs: dict[str, Any] = {"__module__": __name__, "__qualname__": class_name,
                                     "__doc__": _docstring(name, task, real, source)}
            if kind:
                attrs["TASK"] = kind
            elif not real:
                attrs["NUM_SIM_STEPS"] = REACH_NUM_SIM_STEPS
            if registered_arms()[name].camera_defaults:  # a camera the arm observes through by default
                attrs["CAMERA_DEFAULTS"] = dict(registered_arms()[name].camera_defaults)
            return type(class_name, bases, attrs)
    return None


def robot_env_class(name: str, *, goal: bool = False, real: bool = False) -> type:
    """An arm's robot env without a task (``NAMERobotEnv``, ``NAMERobotGoalEnv``, ``NAMERobotRealEnv``,
    ``NAMERobotRealGoalEnv``): the base of a task env of your own on that arm (docs/create_env.md)."""
    class_name = f"{name}Robot{'Real' if real else ''}{'Goal' if goal else ''}Env"
    cls = _CLASSES.get(class_name)
    if cls is None:
        side = ((ArmRobotRealGoalEnv if goal else ArmRobotRealEnv) if real
                else (ArmRobotGoalEnv if goal else ArmRobotEnv))
        cls = _CLASSES[class_name] = type(class_name, (_robot(name, real), side), {
            "__module__": __name__, "__qualname__": class_name,
            "__doc__": f"The {name}'s robot layer for {'goal-conditioned' if goal else 'plain'} task envs "
                       f"{'on its real driver' if real else 'on the simulation node'}."})
    return cls


def forget_arm(name: str) -> None:
    """Drop every class built for arm ``name`` (it was unregistered; registering it again rebuilds them)."""
    built = [n for n, cls in _CLASSES.items() if getattr(getattr(cls, "ARM_FILE", None), "name", None) == name]
    for class_name in built:
        del _CLASSES[class_name]
    for key in [k for k in _ROBOTS if k[0] == name]:
        del _ROBOTS[key]


def __getattr__(class_name: str) -> type:
    cls = _CLASSES.get(class_name)
    if cls is None:
        built = _build(class_name)
        if built is None:
            raise AttributeError(f"module {__name__!r} has no env class {class_name!r}: no registered arm file "
                                 "gives it (uniros.register_arm(path) or UNIROS_ARMS)")
        cls = _CLASSES[class_name] = built
    return cls
