"""Robots and tasks for uniros, registered as gymnasium IDs on import.

Arms are data: one arm file each (:mod:`rl_environments.arm_file`; the shipped ones in
``config/arms/``: the RX200, VX300S, UR5e, NED2 and IRB120; yours through ``uniros.register_arm`` or
``UNIROS_ARMS``). Each gives ``<ARM><task>Sim-v0`` for each ``<task>`` of ``ARM_TASKS``
(``Reacher``, ``ReacherGoal``, ``Push``, ``PushGoal``, ``PnP``, ``PnPGoal``, ``Slide``, ``SlideGoal``:
the task table, :data:`rl_environments.env_ids.TASKS`; push and pick-and-place only for an arm with a
gripper) and each one's ``<ARM><task>Real-v0`` twin. Every arm ID is an arm env of its side made with
keyword arguments (:mod:`rl_environments.arm_env`: ``RX200PushGoalSim-v0`` is
``ArmSimGoalEnv(arm="RX200", task="push")``); the class names of earlier releases stay in
:mod:`rl_environments.arm_envs`.

Besides: FRobs_RL's reacher on the IRB120's arm file, ``ABBIRB120ReacherEnv-v0`` and
``ABBIRB120ReacherGoalEnv-v0`` (the task ``frobs_reach``, :mod:`rl_environments.frobs_reach`) with their Real
twins ``ABBIRB120ReacherRealEnv-v0`` and ``ABBIRB120ReacherGoalRealEnv-v0``; and the RX200's eight tasks
observed through a Zed2 camera, ``RX200Zed2<task>Sim-v0`` (``CAMERA_ENV_IDS``: the arm file
``rx200_zed2.yaml``, which extends the RX200's).

``ENV_IDS``/``GOAL_ENV_IDS`` are the simulated envs (they run anywhere); ``REAL_ENV_IDS``/
``REAL_GOAL_ENV_IDS`` the real ones (they need a robot or a stand-in, see ``docs/real_robots.md``),
and ``SIM_TO_REAL`` maps each simulated ID to its real twin. The reach IDs have
``max_episode_steps=100``, push, pick-and-place and slide (``MANIPULATION_ENV_IDS``: the tasks with an object,
whose scripted demonstrations fill replay buffers) 50 (``EPISODE_STEPS``), their Real twins alike. Robot
description packages (``rx200_description``, ``abb_irb120_description``, ``vx300s_description``,
``ur5e_description``, ``ned2_description``) live in ``rl_environments.robots``.
"""

from __future__ import annotations

from pathlib import Path as _Path

from rl_environments._checkout import map_checkout_package as _map_checkout_package
from rl_environments.env_ids import (
    ENV_SPECS,
    EPISODE_STEPS,
    MANIPULATION_EPISODE_STEPS,
    MAX_EPISODE_STEPS,
    REAL_ENV_SPECS,
    SIM_TO_REAL,
    TASKS,
    VECTOR_ENTRY_MODULE,
    add_ids,
    forget_arm_ids,
    id_tuple,
    note_arm_ids,
    register_envs,
)

# From a source checkout, config/ is not inside this package (an install maps it): map it.
_map_checkout_package("rl_environments.config", _Path(__file__).resolve().parent.parent / "config")

#: The arms whose IDs come from arm files (:mod:`rl_environments.arm_registry`): ID prefix -> robot name.
ARMS: dict[str, str] = {}
#: The tasks of an arm: ``<ARM><task>Sim-v0`` (push and pick-and-place only for an arm with a gripper), from the
#: task table (:data:`rl_environments.env_ids.TASKS`).
ARM_TASKS: tuple[str, ...] = tuple(f"{row.infix}{goal}" for row in TASKS.values() if row.infix for goal in ("", "Goal"))
#: The shipped arm files (in ``rl_environments.config``, ``config/arms/`` of a checkout).
SHIPPED_ARM_FILES: tuple[str, ...] = ("rx200.yaml", "vx300s.yaml", "ur5e.yaml", "ned2.yaml", "irb120.yaml",
                                      "rx200_zed2.yaml")
#: The RX200's tasks observed through a Zed2 stereo camera (its arm file ``rx200_zed2.yaml`` extends the RX200's).
ZED2_TASKS: tuple[str, ...] = ARM_TASKS
CAMERA_ENV_IDS: tuple[str, ...] = tuple(f"RX200Zed2{task}Sim-v0" for task in ZED2_TASKS)


def __getattr__(name: str) -> tuple[str, ...]:
    """``ENV_IDS``, ``REAL_ENV_IDS``, ``GOAL_ENV_IDS``, ``REAL_GOAL_ENV_IDS``, ``MANIPULATION_ENV_IDS``: the
    ID table's (:mod:`rl_environments.env_ids`) as they are when read, arm files registered since included."""
    try:
        return id_tuple(name)
    except AttributeError:
        raise AttributeError(f"module 'rl_environments' has no attribute {name!r}") from None


def shipped_arm_file(name: str) -> _Path | None:
    """The shipped arm file ``name`` (``"ur5e.yaml"``, one of :data:`SHIPPED_ARM_FILES`), else ``None``."""
    if name not in SHIPPED_ARM_FILES:
        return None
    from importlib import resources

    return _Path(str(resources.files("rl_environments.config").joinpath("arms", name)))


def _register_arm_files() -> None:
    from rl_environments.arm_registry import register_arm, register_env_arms, registered_arms

    for name in SHIPPED_ARM_FILES:
        path = shipped_arm_file(name)
        assert path is not None  # a name of SHIPPED_ARM_FILES
        register_arm(path, check_chain=False, tell_children=False)
    for arm, spec in registered_arms().items():
        ARMS[arm] = spec.robot_name
    register_env_arms(strict=False)  # a broken entry: one line logged, the others registered
    for arm, spec in registered_arms().items():
        ARMS[arm] = spec.robot_name


_register_arm_files()
# The static IDs, after the arm files' (ENV_IDS lists the arms' first).
_FROBS = {"arm": "IRB120", "task": "frobs_reach"}
add_ids({"ABBIRB120ReacherEnv-v0": "rl_environments.arm_env:ArmSimEnv"}, kwargs=_FROBS)
add_ids({"ABBIRB120ReacherGoalEnv-v0": "rl_environments.arm_env:ArmSimGoalEnv"}, goal=True, kwargs=_FROBS)
add_ids({"ABBIRB120ReacherRealEnv-v0": "rl_environments.arm_env:ArmRealEnv"}, real=True, kwargs=_FROBS)
add_ids({"ABBIRB120ReacherGoalRealEnv-v0": "rl_environments.arm_env:ArmRealGoalEnv"}, goal=True, real=True,
        kwargs=_FROBS)
SIM_TO_REAL.update({"ABBIRB120ReacherEnv-v0": "ABBIRB120ReacherRealEnv-v0",
                    "ABBIRB120ReacherGoalEnv-v0": "ABBIRB120ReacherGoalRealEnv-v0"})
register_envs()

__all__ = [
    "ARMS",
    "ARM_TASKS",
    "CAMERA_ENV_IDS",
    "ENV_IDS",
    "ENV_SPECS",
    "EPISODE_STEPS",
    "GOAL_ENV_IDS",
    "MANIPULATION_ENV_IDS",
    "MANIPULATION_EPISODE_STEPS",
    "MAX_EPISODE_STEPS",
    "REAL_ENV_IDS",
    "REAL_ENV_SPECS",
    "REAL_GOAL_ENV_IDS",
    "SIM_TO_REAL",
    "VECTOR_ENTRY_MODULE",
    "forget_arm_ids",
    "note_arm_ids",
    "register_envs",
    "shipped_arm_file",
]
