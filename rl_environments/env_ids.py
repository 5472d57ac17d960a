"""The env IDs uniros registers, in one table, and their registration with gymnasium.

Every ID, the arm files' and the static ones (FRobs_RL's reacher, the RX200 observed through its
Zed2), is a row here: its entry point, its Real twin, whether it is goal-conditioned or a
manipulation task, and its episode length. The tables are dicts filled in place as arms are
registered and forgotten; ``rl_environments.ENV_IDS`` and the other ID tuples are computed from
them when read (nothing is rebound at import), and :mod:`rl_environments.arm_registry` adds an arm
file's rows here without going through the package.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

__all__ = ["ENV_MODULE", "ENV_SPECS", "EPISODE_STEPS", "MANIPULATION_EPISODE_STEPS", "MAX_EPISODE_STEPS",
           "REAL_ENV_SPECS", "SIM_TO_REAL", "VECTOR_ENTRY_MODULE", "forget_arm_ids", "id_tuple", "note_arm_ids",
           "register_envs"]

#: The module whose ``__getattr__`` builds an arm file's env classes (``<NAME><task>Env``, ``...RealEnv``).
ENV_MODULE = "rl_environments.arm_envs"
#: Gymnasium loads "<module>:<ID>" vector entry points by name (JSON-able specs); the module makes each ID's.
VECTOR_ENTRY_MODULE = "rl_environments.vector_entry"
#: Episode lengths: reach 100 steps; push and pick-and-place Fetch's 50 steps of 40 ms.
MAX_EPISODE_STEPS = 100
MANIPULATION_EPISODE_STEPS = 50

#: Simulated IDs -> entry points.
ENV_SPECS: dict[str, str] = {}
#: Real IDs -> entry points.
REAL_ENV_SPECS: dict[str, str] = {}
#: Each simulated ID's Real twin.
SIM_TO_REAL: dict[str, str] = {}
#: IDs whose episodes are not MAX_EPISODE_STEPS long.
EPISODE_STEPS: dict[str, int] = {}
_GOAL: dict[str, None] = {}  # goal-conditioned IDs, simulated and real, in registration order
_MANIPULATION: dict[str, None] = {}  # push and pick-and-place IDs (simulated)


def add_ids(specs: dict[str, str], *, goal: bool = False, manipulation: bool = False, steps: int | None = None,
            real: bool = False) -> None:
    """Rows of IDs -> entry points (simulated, or ``real``), with what they are."""
    (REAL_ENV_SPECS if real else ENV_SPECS).update(specs)
    for env_id in specs:
        if goal:
            _GOAL[env_id] = None
        if manipulation and not real:
            _MANIPULATION[env_id] = None
        if steps is not None:
            EPISODE_STEPS[env_id] = steps


def note_arm_ids(sim_id: str, real_id: str, *, goal: bool, manipulation: bool, steps: int) -> None:
    """Add an arm file's simulated ID and its Real twin (:func:`~rl_environments.arm_registry.register_arm`)."""
    name = sim_id.removesuffix("Sim-v0")
    add_ids({sim_id: f"{ENV_MODULE}:{name}Env"}, goal=goal, manipulation=manipulation, steps=steps)
    add_ids({real_id: f"{ENV_MODULE}:{name}RealEnv"}, goal=goal, steps=steps, real=True)
    SIM_TO_REAL[sim_id] = real_id


def forget_arm_ids(sim_id: str, real_id: str) -> None:
    """Remove an arm file's IDs (:func:`~rl_environments.arm_registry.unregister_arm`)."""
    for table in (ENV_SPECS, REAL_ENV_SPECS, SIM_TO_REAL, EPISODE_STEPS, _GOAL, _MANIPULATION):
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
            register(id=env_id, entry_point=entry_point,
                     vector_entry_point=f"{VECTOR_ENTRY_MODULE}:{env_id}" if env_id in ENV_SPECS else None,
                     max_episode_steps=EPISODE_STEPS.get(env_id, MAX_EPISODE_STEPS))
