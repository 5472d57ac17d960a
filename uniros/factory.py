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
    ``vector_kwargs`` takes ``num_nodes`` (K nodes in K processes, N/K robots each), ``spacing``
    (metres between world slots), ``autoreset_mode``, ``timeout_sec``, ``copy``. ``"sync"`` and
    ``"async"`` (Gymnasium's, one node per env) work as before. See ``docs/vector_envs.md``.

    Raises:
        ValueError: ``num_envs`` beyond the node's ``max_robots`` or bad batch options.
    """
    if env_id not in gym.registry:
        make(env_id)  # raises the helpful error
    if vectorization_mode != "batched":
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode=vectorization_mode,
                            vector_kwargs=vector_kwargs, **kwargs)
    from multiros.envs.vector import BatchedVectorEnv

    options = dict(vector_kwargs or {})
    autoreset = options.pop("autoreset_mode", gym.vector.AutoresetMode.NEXT_STEP)
    copy = options.pop("copy", True)
    return BatchedVectorEnv(make_batch(env_id, num_envs, options, **kwargs), autoreset_mode=autoreset, copy=copy)


_BATCH_OPTIONS = ("num_nodes", "spacing", "timeout_sec", "node_name", "connect_kwargs")


def make_batch(env_id: str, num_envs: int, batch_options: dict[str, Any] | None = None, **kwargs: Any) -> Any:
    """The :class:`~multiros.envs.batch.EnvBatch` of ``num_envs`` envs ``env_id`` (``kwargs`` go to each env)."""
    from multiros.envs.batch import EnvBatch
    from multiros.sim.launch import local_description_dirs

    if env_id not in gym.registry:
        make(env_id)
    options = dict(batch_options or {})
    unknown = sorted(set(options) - set(_BATCH_OPTIONS))
    if unknown:
        raise TypeError(f"unknown batched vector env option(s) {unknown}; accepted: {list(_BATCH_OPTIONS)} "
                        "and autoreset_mode, copy")
    for key in ("sim_connection", "world_slot", "sim_node_name"):
        if key in kwargs:
            raise TypeError(f"{key!r} is set by the batched vector env itself; do not pass it")
    spec = gym.spec(env_id)
    creator = spec.entry_point if not isinstance(spec.entry_point, str) else \
        gym.envs.registration.load_env_creator(spec.entry_point)
    sim_mode = kwargs.pop("sim_mode", "composed")
    max_steps = kwargs.pop("max_episode_steps", spec.max_episode_steps)
    base = kwargs.pop("robot_name", getattr(creator, "ROBOT_NAME", "robot"))
    env_kwargs = {**spec.kwargs, **kwargs}
    trusted = local_description_dirs(env_kwargs.get("robot_model_xml"), env_kwargs.get("controllers_file"))

    def make_env(**batch_kwargs: Any) -> Any:
        return creator(**env_kwargs, **batch_kwargs)

    return EnvBatch(make_env, num_envs, robot_name=base, sim_mode=sim_mode, max_episode_steps=max_steps,
                    trusted_paths=trusted, **options)
