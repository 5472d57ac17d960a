"""``uniros.make``: gymnasium's ``make`` for the library's envs, with errors that say what exists.

Extra keyword arguments go to the env's constructor; the ones every uniros env accepts choose how
the simulation node runs (``sim_mode="composed" | "process" | "existing"``, ``sim_node_name``,
``transport="inproc" | "zenoh"``, ``gui``, ``render_mode``, ``seed``, ...).
"""

from __future__ import annotations

import difflib
import inspect
from typing import Any

import gymnasium as gym
from gymnasium import error as gym_error

import rl_environments


class UnknownEnvError(gym_error.Error, LookupError):
    """The env ID is not registered."""


def _accepted_kwargs(env_id: str) -> list[str]:
    from multiros.envs.core import MujocoEnvCore

    spec = gym.spec(env_id)
    cls = spec.entry_point if not isinstance(spec.entry_point, str) else gym.envs.registration.load_env_creator(
        spec.entry_point
    )
    names: set[str] = set()
    for klass in getattr(cls, "__mro__", [cls]):
        init = vars(klass).get("__init__")
        if init is not None:
            names |= {p for p in inspect.signature(init).parameters if p not in ("self", "kwargs")}
    names |= {p for p in inspect.signature(MujocoEnvCore._init_core).parameters if p not in ("self", "legacy")}
    return sorted(names)


def make(env_id: str, **kwargs: Any) -> gym.Env:
    """Create a registered env, like ``gymnasium.make``.

    Raises:
        UnknownEnvError: ``env_id`` is not registered (the message lists the uniros IDs and close matches).
        TypeError: an unknown keyword argument (the message lists the accepted ones).
    """
    if isinstance(env_id, str) and env_id not in gym.registry:
        close = difflib.get_close_matches(env_id, list(gym.registry), n=3)
        hint = f" Did you mean {close}?" if close else ""
        raise UnknownEnvError(f"no env {env_id!r}.{hint} uniros envs: {list(rl_environments.ENV_IDS)}")
    try:
        return gym.make(env_id, **kwargs)
    except TypeError as exc:
        if isinstance(env_id, str) and env_id in rl_environments.ENV_IDS and "keyword argument" in str(exc):
            raise TypeError(f"{exc}. {env_id} accepts: {_accepted_kwargs(env_id)}") from exc
        raise


def make_vec(
    env_id: str,
    num_envs: int = 1,
    vectorization_mode: str | None = None,
    vector_kwargs: dict[str, Any] | None = None,
    **kwargs: Any,
) -> gym.vector.VectorEnv:
    """``gymnasium.make_vec`` for uniros IDs, plus the ``"batched"`` mode.

    ``vectorization_mode="batched"`` returns a :class:`~multiros.envs.vector.BatchedVectorEnv`: one
    simulation node holds all ``num_envs`` robots (each in its own namespace and world slot) and one
    request steps them all. ``sim_mode="process"`` puts the node in a child process;
    ``vector_kwargs`` takes ``workers`` (K worker processes, N/K envs each on a composed node of
    their own, actions and observations through shared memory:
    :class:`~multiros.envs.worker_vector.WorkerVectorEnv`; ``0``: this process), ``num_nodes`` (K
    nodes, N/K robots each: composed in this process and stepped at once on threads, or in K
    processes with ``sim_mode="process"``), ``spacing`` (metres between world slots),
    ``autoreset_mode``, ``timeout_sec``, ``copy``. ``"sync"`` and ``"async"`` (Gymnasium's, one node
    per env) work as before. The default (``None``) picks the fastest form: ``"batched"`` for an ID
    whose env is a uniros simulated env (the shipped IDs, and yours built on
    ``MujocoBaseEnv``/``MujocoGoalEnv``), with one worker process per core (in this process where
    that is one, or where ``num_nodes`` or ``sim_mode`` place the nodes); else Gymnasium's default
    (the ID's ``vector_entry_point``, or ``"sync"``). An explicit ``"batched"`` runs in this process
    unless ``vector_kwargs`` names ``workers``. See ``docs/vector_envs.md``.

    Raises:
        ValueError: ``num_envs`` beyond the node's ``max_robots`` or bad batch options.
    """
    if env_id not in gym.registry:
        make(env_id)  # raises the helpful error
    vector_entry = gym.spec(env_id).vector_entry_point
    defaults = vectorization_mode is None
    if vectorization_mode is None:
        if isinstance(vector_entry, str) and vector_entry.startswith(rl_environments.VECTOR_ENTRY_MODULE + ":"):
            vectorization_mode = "batched"  # the ID's own vector entry point (see rl_environments.vector_entry)
        elif vector_entry is None and _simulated(env_id) and kwargs.get("sim_mode", "composed") == "composed":
            vectorization_mode = "batched"  # a uniros simulated env of the user's: its robots share nodes
    if vectorization_mode != "batched":
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode=vectorization_mode,
                            vector_kwargs=vector_kwargs, **kwargs)
    from multiros.envs.vector import make_batched_vector_env

    options = dict(vector_kwargs or {})
    options.setdefault("workers", None if defaults else 0)
    return make_batched_vector_env(env_id, num_envs, vector_options=options, **kwargs)


def _simulated(env_id: str) -> bool:
    """Whether the ID builds a uniros simulated env (known from its class, without making one)."""
    from multiros.envs.batch import env_creator
    from multiros.envs.sim_env import MujocoEnvCore

    try:
        creator = env_creator(env_id)
    except Exception:  # noqa: BLE001 - an entry point that does not load: gymnasium's make_vec says why
        return False
    return isinstance(creator, type) and issubclass(creator, MujocoEnvCore)


def make_batch(env_id: str, num_envs: int, batch_options: dict[str, Any] | None = None, **kwargs: Any) -> Any:
    """The :class:`~multiros.envs.batch.EnvBatch` of ``num_envs`` envs ``env_id`` (``kwargs`` go to each env)."""
    from multiros.envs.batch import make_env_batch

    if env_id not in gym.registry:
        make(env_id)  # raises the helpful error
    return make_env_batch(env_id, num_envs, batch_options, **kwargs)
