"""Robots and tasks for uniros, registered as gymnasium IDs on import.

Task envs (two layers each: a robot env and a task env):

==============================  ========================================================================
ID                              entry point
==============================  ========================================================================
``RX200ReacherSim-v0``          ``rl_environments.rx200.sim.task_envs.reach.rx200_reach_sim:RX200ReacherEnv``
``RX200ReacherGoalSim-v0``      ``...reach.rx200_reach_goal_sim:RX200ReacherGoalEnv``
``RX200PushSim-v0``             ``rl_environments.rx200.sim.task_envs.manipulation.rx200_push_sim:RX200PushEnv``
``RX200PushGoalSim-v0``         ``...manipulation.rx200_push_goal_sim:RX200PushGoalEnv``
``RX200PnPSim-v0``              ``...manipulation.rx200_pnp_sim:RX200PnPEnv``
``RX200PnPGoalSim-v0``          ``...manipulation.rx200_pnp_goal_sim:RX200PnPGoalEnv``
``ABBIRB120ReacherEnv-v0``      ``rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher:ABBIRB120ReacherEnv``
``ABBIRB120ReacherGoalEnv-v0``  ``...reacher.irb120_reacher_goal:ABBIRB120ReacherGoalEnv``
==============================  ========================================================================

Every arm's tasks (``rl_environments.arm_reach``, ``rl_environments.arm_manipulation``) on the
VX300S, UR5e and NED2 (``ARMS``): ``<ARM><task>Sim-v0`` for each ``<task>`` of ``ARM_TASKS``
(``Reacher``, ``ReacherGoal``, ``Push``, ``PushGoal``, ``PnP``, ``PnPGoal``), entry point
``rl_environments.<arm>.sim:<ARM><task>Env``; the RX200's six observed through a Zed2 camera,
``RX200Zed2<task>Sim-v0`` (``CAMERA_ENV_IDS``, ``rl_environments.rx200.sim.zed2``).

Real-robot twins (same task, same spaces; they need a robot or a stand-in, see ``docs/real_robots.md``):

====================================  ==================================================================
``RX200ReacherReal-v0``               ``rl_environments.rx200.real.task_envs.reach.rx200_reach_real:...``
``RX200ReacherGoalReal-v0``           ``...reach.rx200_reach_goal_real:RX200ReacherGoalRealEnv``
``ABBIRB120ReacherRealEnv-v0``        ``rl_environments.abb_irb120.real.task_envs.reacher.irb120_reacher_real:...``
``ABBIRB120ReacherGoalRealEnv-v0``    ``...reacher.irb120_reacher_goal_real:ABBIRB120ReacherGoalRealEnv``
====================================  ==================================================================

and the arms' twins ``<ARM><task>Real-v0`` (``rl_environments.<arm>.real:<ARM><task>RealEnv``).

``ENV_IDS``/``GOAL_ENV_IDS`` are the simulated envs (they run anywhere); ``REAL_ENV_IDS``/
``REAL_GOAL_ENV_IDS`` the real ones, and ``SIM_TO_REAL`` maps each simulated ID to its real twin.
The reach IDs have ``max_episode_steps=100``, push and pick-and-place (``MANIPULATION_ENV_IDS``) 50
(``EPISODE_STEPS``), their Real twins alike. Robot description packages (``rx200_description``,
``abb_irb120_description``, ``vx300s_description``, ``ur5e_description``, ``ned2_description``)
live in ``rl_environments.robots``.
"""

from __future__ import annotations

from pathlib import Path as _Path

from gymnasium.envs.registration import register, registry

from rl_environments._checkout import map_checkout_package as _map_checkout_package

# From a source checkout, config/ is not inside this package (an install maps it): map it.
_map_checkout_package("rl_environments.config", _Path(__file__).resolve().parent.parent / "config")

ENV_SPECS: dict[str, str] = {
    "RX200ReacherSim-v0": "rl_environments.rx200.sim.task_envs.reach.rx200_reach_sim:RX200ReacherEnv",
    "RX200ReacherGoalSim-v0": "rl_environments.rx200.sim.task_envs.reach.rx200_reach_goal_sim:RX200ReacherGoalEnv",
    "ABBIRB120ReacherEnv-v0": "rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher:ABBIRB120ReacherEnv",
    "ABBIRB120ReacherGoalEnv-v0": (
        "rl_environments.abb_irb120.sim.task_envs.reacher.irb120_reacher_goal:ABBIRB120ReacherGoalEnv"
    ),
    "RX200PushSim-v0": "rl_environments.rx200.sim.task_envs.manipulation.rx200_push_sim:RX200PushEnv",
    "RX200PushGoalSim-v0": "rl_environments.rx200.sim.task_envs.manipulation.rx200_push_goal_sim:RX200PushGoalEnv",
    "RX200PnPSim-v0": "rl_environments.rx200.sim.task_envs.manipulation.rx200_pnp_sim:RX200PnPEnv",
    "RX200PnPGoalSim-v0": "rl_environments.rx200.sim.task_envs.manipulation.rx200_pnp_goal_sim:RX200PnPGoalEnv",
}
#: The arms whose six tasks are every arm's (rl_environments.arm_reach, arm_manipulation): ID prefix -> package.
ARMS: dict[str, str] = {"VX300S": "vx300s", "UR5e": "ur5e", "NED2": "ned2"}
#: The six tasks of an arm: ID infix -> env class suffix (``<ARM><task>Sim-v0`` is ``<ARM><class>Env``).
ARM_TASKS: tuple[str, ...] = ("Reacher", "ReacherGoal", "Push", "PushGoal", "PnP", "PnPGoal")
for _arm, _pkg in ARMS.items():
    for _task in ARM_TASKS:
        ENV_SPECS[f"{_arm}{_task}Sim-v0"] = f"rl_environments.{_pkg}.sim:{_arm}{_task}Env"
#: The RX200's tasks observed through a Zed2 stereo camera (rl_environments.rx200.sim.zed2).
ZED2_TASKS: tuple[str, ...] = ARM_TASKS
for _task in ZED2_TASKS:
    ENV_SPECS[f"RX200Zed2{_task}Sim-v0"] = f"rl_environments.rx200.sim.zed2:RX200Zed2{_task}Env"
CAMERA_ENV_IDS: tuple[str, ...] = tuple(f"RX200Zed2{task}Sim-v0" for task in ZED2_TASKS)
ENV_IDS: tuple[str, ...] = tuple(ENV_SPECS)
GOAL_ENV_IDS: tuple[str, ...] = (
    "RX200ReacherGoalSim-v0", "ABBIRB120ReacherGoalEnv-v0", "RX200PushGoalSim-v0", "RX200PnPGoalSim-v0",
    *(f"{arm}{task}Sim-v0" for arm in ARMS for task in ARM_TASKS if task.endswith("Goal")),
    *(f"RX200Zed2{task}Sim-v0" for task in ZED2_TASKS if task.endswith("Goal")),
)
MANIPULATION_ENV_IDS: tuple[str, ...] = (
    "RX200PushSim-v0", "RX200PushGoalSim-v0", "RX200PnPSim-v0", "RX200PnPGoalSim-v0",
    *(f"{arm}{task}Sim-v0" for arm in (*ARMS, "RX200Zed2") for task in ARM_TASKS if task.startswith(("Push", "PnP"))),
)
MAX_EPISODE_STEPS = 100
# Push and pick-and-place: Fetch's 50 steps of 40 ms (see rx200_manipulation's docstring).
EPISODE_STEPS: dict[str, int] = dict.fromkeys(MANIPULATION_ENV_IDS, 50)
REAL_ENV_SPECS: dict[str, str] = {
    "RX200ReacherReal-v0": "rl_environments.rx200.real.task_envs.reach.rx200_reach_real:RX200ReacherRealEnv",
    "RX200ReacherGoalReal-v0": (
        "rl_environments.rx200.real.task_envs.reach.rx200_reach_goal_real:RX200ReacherGoalRealEnv"
    ),
    "ABBIRB120ReacherRealEnv-v0": (
        "rl_environments.abb_irb120.real.task_envs.reacher.irb120_reacher_real:ABBIRB120ReacherRealEnv"
    ),
    "ABBIRB120ReacherGoalRealEnv-v0": (
        "rl_environments.abb_irb120.real.task_envs.reacher.irb120_reacher_goal_real:ABBIRB120ReacherGoalRealEnv"
    ),
}
for _arm, _pkg in ARMS.items():
    for _task in ARM_TASKS:
        REAL_ENV_SPECS[f"{_arm}{_task}Real-v0"] = f"rl_environments.{_pkg}.real:{_arm}{_task}RealEnv"
REAL_ENV_IDS: tuple[str, ...] = tuple(REAL_ENV_SPECS)
REAL_GOAL_ENV_IDS: tuple[str, ...] = (
    "RX200ReacherGoalReal-v0", "ABBIRB120ReacherGoalRealEnv-v0",
    *(f"{arm}{task}Real-v0" for arm in ARMS for task in ARM_TASKS if task.endswith("Goal")),
)
SIM_TO_REAL: dict[str, str] = {
    "RX200ReacherSim-v0": "RX200ReacherReal-v0",
    "RX200ReacherGoalSim-v0": "RX200ReacherGoalReal-v0",
    "ABBIRB120ReacherEnv-v0": "ABBIRB120ReacherRealEnv-v0",
    "ABBIRB120ReacherGoalEnv-v0": "ABBIRB120ReacherGoalRealEnv-v0",
    **{f"{arm}{task}Sim-v0": f"{arm}{task}Real-v0" for arm in ARMS for task in ARM_TASKS},
}

# A Real twin's episodes are its simulated twin's.
EPISODE_STEPS.update({SIM_TO_REAL[i]: n for i, n in list(EPISODE_STEPS.items()) if i in SIM_TO_REAL})

# Gymnasium loads "<module>:<ID>" entry points by name (JSON-able specs); the module makes each ID's.
VECTOR_ENTRY_MODULE = "rl_environments.vector_entry"


def register_envs() -> None:
    """Register every uniros env ID with gymnasium (idempotent); simulated IDs get a batched vector entry point."""
    for env_id, entry_point in {**ENV_SPECS, **REAL_ENV_SPECS}.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point,
                     vector_entry_point=f"{VECTOR_ENTRY_MODULE}:{env_id}" if env_id in ENV_SPECS else None,
                     max_episode_steps=EPISODE_STEPS.get(env_id, MAX_EPISODE_STEPS))


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
    "REAL_ENV_IDS",
    "REAL_ENV_SPECS",
    "REAL_GOAL_ENV_IDS",
    "SIM_TO_REAL",
    "VECTOR_ENTRY_MODULE",
    "register_envs",
]
