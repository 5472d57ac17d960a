"""The arm env class names of earlier releases, kept so that saved runs, pickles and code that import
them keep working: ``rl_environments.arm_envs.<NAME><task>Env`` and ``...<task>RealEnv`` for each
registered arm ``NAME`` and each ``<task>`` infix of the task table (``Reacher``, ``ReacherGoal``,
``Push``, ``PushGoal``, ``PnP``, ``PnPGoal``, ``Slide``, ``SlideGoal``).

Each is the arm env class of its side (:mod:`rl_environments.arm_env`) with the arm and the task set,
e.g. ``RX200PushGoalEnv()`` is ``ArmSimGoalEnv(arm="RX200", task="push")``. A class is made once per name
and kept, so pickle finds the same class every time. The registered IDs use the arm env classes
themselves, with keyword arguments.
"""

from __future__ import annotations

from rl_environments.arm_env import ArmEnv, arm_env_class

_CLASSES: dict[str, type[ArmEnv]] = {}


def _build(class_name: str) -> type[ArmEnv] | None:
    from rl_environments.arm_registry import registered_arms
    from rl_environments.env_ids import TASKS

    for name in registered_arms():
        for task, row in TASKS.items():
            if row.infix is None:
                continue
            for goal in (False, True):
                stem = f"{name}{row.infix}{'Goal' if goal else ''}"
                for real in (False, True):
                    if class_name == f"{stem}{'Real' if real else ''}Env":
                        base = arm_env_class(real=real, goal=goal)
                        side = "on a real robot's driver" if real else "on the simulation node"
                        return type(class_name, (base,), {
                            "__module__": __name__, "__qualname__": class_name, "ARM": name, "TASK": task,
                            "__doc__": f"``{base.__name__}(arm={name!r}, task={task!r})``: the {name}'s {task} "
                                       f"{side} (the ID ``{stem}{'Real' if real else 'Sim'}-v0``)."})
    return None


def __getattr__(class_name: str) -> type[ArmEnv]:
    cls = _CLASSES.get(class_name)
    if cls is None:
        built = _build(class_name)
        if built is None:
            hint = (" (an arm's robot env without a task is gone: compose the arm with a task of your own, "
                    "docs/create_env.md)" if "Robot" in class_name else "")
            raise AttributeError(f"module {__name__!r} has no env class {class_name!r}: no registered arm file "
                                 f"gives it (uniros.register_arm(path) or UNIROS_ARMS){hint}")
        cls = _CLASSES[class_name] = built
    return cls
