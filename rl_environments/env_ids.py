"""The tasks of the arm envs and the env IDs uniros registers, in one table each, and their registration
with gymnasium.

:data:`TASKS` names every task an arm env can be made with (``ArmSimGoalEnv(arm="RX200", task="slide")``):
its class, the infix of the IDs it gives every arm, its episode length and whether it needs a gripper.
Every ID, the arm files' and the static ones (FRobs_RL's reacher), is a row of the ID table: its entry
point and keyword arguments, its Real twin, whether it is goal-conditioned or a task with an object, and
its episode length. The tables are dicts filled in place as arms are
registered and forgotten; ``rl_environments.ENV_IDS`` and the other ID tuples are computed from
them when read (nothing is rebound at import), and :mod:`rl_environments.arm_registry` adds an arm
file's rows here without going through the package.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from typing import Any

from gymnasium.envs.registration import register, registry

__all__ = ["ARM_ENV_MODULE", "ENV_KWARGS", "ENV_MODULE", "ENV_SPECS", "EPISODE_STEPS", "MANIPULATION_EPISODE_STEPS",
           "MAX_EPISODE_STEPS", "REAL_ENV_SPECS", "SIM_TO_REAL", "TASKS", "TaskRow", "VECTOR_ENTRY_MODULE",
           "arm_task_ids", "forget_arm_ids", "id_tuple", "note_arm_ids", "register_envs", "task_class"]


@dataclass(frozen=True)
class TaskRow:
    """A task of the arm envs.

    Attributes:
        task: its :class:`~rl_environments.arm_task.ArmTask` class, as ``"module:Class"``.
        infix: the IDs it gives every arm: ``<ARM><infix>Sim-v0``, ``<ARM><infix>GoalSim-v0`` and their
            ``Real`` twins (``None``: no IDs of its own per arm).
        steps: the episode length (env steps).
        gripper: only an arm with a gripper can do it.
        objects: an object on a table (scripted demonstrations can fill a replay buffer).
    """

    task: str
    infix: str | None
    steps: int
    gripper: bool = False
    objects: bool = False


#: Episode lengths: reach 100 steps; push, pick-and-place and slide Fetch's 50 steps of 40 ms.
MAX_EPISODE_STEPS = 100
MANIPULATION_EPISODE_STEPS = 50
#: The tasks of the arm envs, by name.
TASKS: dict[str, TaskRow] = {
    "reach": TaskRow("rl_environments.reach_task:ReachTask", "Reacher", MAX_EPISODE_STEPS),
    "push": TaskRow("rl_environments.manipulation_task:PushTask", "Push", MANIPULATION_EPISODE_STEPS, gripper=True,
                    objects=True),
    "pnp": TaskRow("rl_environments.manipulation_task:PickAndPlaceTask", "PnP", MANIPULATION_EPISODE_STEPS,
                   gripper=True, objects=True),
    "slide": TaskRow("rl_environments.slide_task:SlideTask", "Slide", MANIPULATION_EPISODE_STEPS, objects=True),
    "frobs_reach": TaskRow("rl_environments.frobs_reach:FrobsReachTask", None, MAX_EPISODE_STEPS),
}


def task_class(name: str) -> Any:
    """The :class:`~rl_environments.arm_task.ArmTask` class of the task ``name`` in :data:`TASKS`."""
    row = TASKS.get(name)
    if row is None:
        raise ValueError(f"no task {name!r}; tasks: {sorted(TASKS)}")
    module, _, cls = row.task.partition(":")
    return getattr(import_module(module), cls)


def arm_task_ids(name: str, *, gripper: bool) -> dict[str, tuple[str, bool, str]]:
    """The IDs the tasks give the arm ``name``: ``{sim ID: (task, goal-conditioned, real ID)}``."""
    out = {}
    for task, row in TASKS.items():
        if row.infix is None or (row.gripper and not gripper):
            continue
        for goal in (False, True):
            infix = row.infix + ("Goal" if goal else "")
            out[f"{name}{infix}Sim-v0"] = (task, goal, f"{name}{infix}Real-v0")
    return out


#: The arm envs' module (:mod:`rl_environments.arm_env`); the entry points of every arm ID are its classes.
ARM_ENV_MODULE = "rl_environments.arm_env"
#: The module that keeps the arm env class names of earlier releases (``<NAME><task>Env``, ``...RealEnv``).
ENV_MODULE = "rl_environments.arm_envs"
#: Gymnasium loads "<module>:<ID>" vector entry points by name (JSON-able specs); the module makes each ID's.
VECTOR_ENTRY_MODULE = "rl_environments.vector_entry"
#: Simulated IDs -> entry points.
ENV_SPECS: dict[str, str] = {}
#: Real IDs -> entry points.
REAL_ENV_SPECS: dict[str, str] = {}
#: Each simulated ID's Real twin.
SIM_TO_REAL: dict[str, str] = {}
#: IDs -> keyword arguments of their entry points.
ENV_KWARGS: dict[str, dict[str, Any]] = {}
#: IDs whose episodes are not MAX_EPISODE_STEPS long.
EPISODE_STEPS: dict[str, int] = {}
_GOAL: dict[str, None] = {}  # goal-conditioned IDs, simulated and real, in registration order
_MANIPULATION: dict[str, None] = {}  # push and pick-and-place IDs (simulated)


def add_ids(specs: dict[str, str], *, goal: bool = False, manipulation: bool = False, steps: int | None = None,
            real: bool = False, kwargs: dict[str, Any] | None = None) -> None:
    """Rows of IDs -> entry points (simulated, or ``real``), with what they are."""
    (REAL_ENV_SPECS if real else ENV_SPECS).update(specs)
    for env_id in specs:
        if kwargs:
            ENV_KWARGS[env_id] = dict(kwargs)
        if goal:
            _GOAL[env_id] = None
        if manipulation and not real:
            _MANIPULATION[env_id] = None
        if steps is not None:
            EPISODE_STEPS[env_id] = steps


def note_arm_ids(arm: str, sim_id: str, real_id: str, *, task: str, goal: bool) -> None:
    """Add an arm's simulated ID of ``task`` and its Real twin (:func:`~rl_environments.arm_registry.register_arm`)."""
    row = TASKS[task]
    kwargs = {"arm": arm, "task": task}
    cls = "ArmSimGoalEnv" if goal else "ArmSimEnv"
    add_ids({sim_id: f"{ARM_ENV_MODULE}:{cls}"}, goal=goal, manipulation=row.objects, steps=row.steps, kwargs=kwargs)
    add_ids({real_id: f"{ARM_ENV_MODULE}:{cls.replace('Sim', 'Real')}"}, goal=goal, steps=row.steps, real=True,
            kwargs=kwargs)
    SIM_TO_REAL[sim_id] = real_id


def forget_arm_ids(sim_id: str, real_id: str) -> None:
    """Remove an arm file's IDs (:func:`~rl_environments.arm_registry.unregister_arm`)."""
    for table in (ENV_SPECS, REAL_ENV_SPECS, SIM_TO_REAL, EPISODE_STEPS, _GOAL, _MANIPULATION, ENV_KWARGS):
        table.pop(sim_id, None)
        table.pop(real_id, None)


def id_tuple(name: str) -> tuple[str, ...]:
    """``ENV_IDS``, ``REAL_ENV_IDS``, ``GOAL_ENV_IDS``, ``REAL_GOAL_ENV_IDS`` or ``MANIPULATION_ENV_IDS``, now."""
    if name == "ENV_IDS":
        return tuple(ENV_SPECS)
    if name == "REAL_ENV_IDS":
        return tuple(REAL_ENV_SPECS)
    if name == "GOAL_ENV_IDS":
        return tuple(i for i in _GOAL if i in ENV_SPECS)
    if name == "REAL_GOAL_ENV_IDS":
        return tuple(i for i in _GOAL if i in REAL_ENV_SPECS)
    if name == "MANIPULATION_ENV_IDS":
        return tuple(_MANIPULATION)
    raise AttributeError(name)


def register_envs() -> None:
    """Register every uniros env ID with gymnasium (idempotent); simulated IDs get a batched vector entry point."""
    for env_id, entry_point in {**ENV_SPECS, **REAL_ENV_SPECS}.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, kwargs=dict(ENV_KWARGS.get(env_id, {})),
                     vector_entry_point=f"{VECTOR_ENTRY_MODULE}:{env_id}" if env_id in ENV_SPECS else None,
                     max_episode_steps=EPISODE_STEPS.get(env_id, MAX_EPISODE_STEPS))
