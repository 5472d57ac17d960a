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
from gymnasium.wrappers import PassiveEnvChecker

import rl_environments


class UnknownEnvError(gym_error.Error, LookupError):
    """The env ID is not registered."""


class EnvKeywordError(TypeError):
    """A keyword argument the env does not take; the message lists the accepted ones and the nearest.

    Attributes:
        unknown: the keywords not taken.
        accepted: every keyword the env takes.
        suggestions: the nearest accepted keyword per unknown one (where one is close).
    """

    def __init__(self, message: str, unknown: list[str], accepted: list[str], suggestions: dict[str, str]) -> None:
        super().__init__(message)
        self.unknown, self.accepted, self.suggestions = unknown, accepted, suggestions


#: Keywords ``gymnasium.make`` itself takes (the env never sees them).
_MAKE_KEYWORDS = ("max_episode_steps", "disable_env_checker", "render_mode")


def _accepted_kwargs(env_id: str) -> list[str]:
    """Every keyword ``make(env_id, ...)`` takes: the env classes' own, the core's knobs, the camera
    options of an env with camera observations, and ``gymnasium.make``'s."""
    from multiros.envs.sim_env import MujocoEnvCore

    spec = gym.spec(env_id)
    cls = spec.entry_point if not isinstance(spec.entry_point, str) else gym.envs.registration.load_env_creator(
        spec.entry_point
    )
    names: set[str] = set(_MAKE_KEYWORDS)
    positional_or_named = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    for klass in getattr(cls, "__mro__", [cls]):
        init = vars(klass).get("__init__")
        if init is not None:
            names |= {n for n, p in inspect.signature(init).parameters.items()
                      if n != "self" and p.kind in positional_or_named}
    names |= {n for n, p in inspect.signature(MujocoEnvCore._init_core).parameters.items()
              if n not in ("self", "legacy") and p.kind in positional_or_named}
    own = getattr(cls, "accepted_keywords", None)  # an env whose keywords depend on its arguments (its task's)
    if callable(own):
        names |= set(own(spec.kwargs))
    return sorted(names)


def _unknown_keywords(exc: TypeError, given: dict[str, Any]) -> list[str]:
    """The keywords of ``given`` that ``exc`` (an env constructor's TypeError) names. Gymnasium adds
    every keyword given to the message (``... was raised from the environment creator for ID with
    kwargs ({...})``): that part names them all, taken or not, so it is left out."""
    text = str(exc).split(" was raised from the environment creator", 1)[0]
    return [k for k in given if f"'{k}'" in text]


def did_you_mean(suggestions: dict[str, str]) -> str:
    """`` (did you mean 'x'?)`` for one suggestion, `` (did you mean 'x' for 'a', 'y' for 'b'?)`` for
    several; empty for none."""
    if not suggestions:
        return ""
    if len(suggestions) == 1:
        return f" (did you mean {next(iter(suggestions.values()))!r}?)"
    return " (did you mean " + ", ".join(f"{v!r} for {k!r}" for k, v in suggestions.items()) + "?)"


class _RetrySafeEnvChecker(PassiveEnvChecker):  # type: ignore[type-arg]
    """gymnasium's env checker, but a first reset that raises is checked again when retried.

    gymnasium's (1.4) marks its one-time reset check done before the reset runs, so after a first
    reset that raised (a robot not at its pose, a bad seed), the reset that succeeds records no
    data, and the first step then fails inside the checker (``TypeError: cannot unpack
    non-iterable NoneType object``) instead of stepping.
    """

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        first = not self.checked_reset
        try:
            return super().reset(seed=seed, options=options)
        except BaseException:
            if first:
                self.checked_reset = False
            raise


def _retry_safe_checker(env: gym.Env) -> gym.Env:
    """``env`` with its gymnasium env checker (if ``gym.make`` added one) made a :class:`_RetrySafeEnvChecker`."""
    layer: Any = env
    while isinstance(layer, gym.Wrapper):
        if type(layer) is PassiveEnvChecker:
            layer.__class__ = _RetrySafeEnvChecker  # the same object, one method more careful
        layer = layer.env
    return env


def make(env_id: str, **kwargs: Any) -> gym.Env:
    """Create a registered env, like ``gymnasium.make``.

    Raises:
        UnknownEnvError: ``env_id`` is not registered (the message lists the uniros IDs and close matches).
        EnvKeywordError: an unknown keyword argument (a ``TypeError``; the message names the nearest
            accepted keyword and lists them all).
    """
    if isinstance(env_id, str) and env_id not in gym.registry:
        from rl_environments.arm_registry import env_arm_errors

        close = difflib.get_close_matches(env_id, list(gym.registry), n=3)
        hint = f" Did you mean {close}?" if close else ""
        skipped = "".join(f" Not registered: {why}." for why in env_arm_errors())
        raise UnknownEnvError(f"no env {env_id!r}.{skipped}{hint} uniros envs: {list(rl_environments.ENV_IDS)}")
    try:
        return _retry_safe_checker(gym.make(env_id, **kwargs))
    except TypeError as exc:
        if isinstance(env_id, str) and env_id in rl_environments.ENV_IDS and "keyword argument" in str(exc):
            accepted = _accepted_kwargs(env_id)
            unknown = _unknown_keywords(exc, kwargs) or [k for k in kwargs if k not in accepted]
            suggestions = {}
            for key in unknown:
                close = difflib.get_close_matches(key, accepted, n=1, cutoff=0.6)
                if close:
                    suggestions[key] = close[0]
            raise EnvKeywordError(f"{env_id} got unexpected keyword argument(s) {unknown}{did_you_mean(suggestions)}; "
                                  f"{env_id} accepts: {accepted}", unknown, accepted, suggestions) from exc
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
    request steps them all. ``sim_mode="process"`` puts the nodes in child processes;
    ``vector_kwargs`` takes ``workers`` (K worker processes, N/K envs each on a composed node of
    their own, actions and observations through shared memory:
    :class:`~multiros.envs.worker_vector.WorkerVectorEnv`; ``0``: this process), ``num_nodes`` (K
    nodes, N/K robots each: composed in this process and stepped at once on threads, or in K
    processes with ``sim_mode="process"``), ``spacing`` (metres between world slots),
    ``autoreset_mode``, ``timeout_sec``, ``copy``, ``pin_workers`` (each worker process on a core of its
    own: for a machine the run has to itself). ``"sync"`` and ``"async"`` (Gymnasium's, one node
    per env) work as before. The default (``None``) picks the fastest form: ``"batched"`` for an ID
    whose env is a uniros simulated env (the shipped IDs, and yours built on
    ``MujocoBaseEnv``/``MujocoGoalEnv``), with a share of the envs per core: this process steps one and a
    worker process each other (all in this process where that is one, or where ``num_nodes`` or
    ``sim_mode="existing"`` place the nodes). With ``sim_mode="process"`` each of the K nodes (default:
    one per core) is a worker process stepping its envs beside it, through the same shared memory
    (no Zenoh call per step; ``workers=0``, or a ``transport`` or ``gui`` of the node's, keeps the
    envs here and calls the nodes over their private router). Else Gymnasium's default (the ID's
    ``vector_entry_point``, or ``"sync"``). An explicit ``"batched"`` runs in this process unless
    ``vector_kwargs`` names ``workers``. See ``docs/vector_envs.md``.

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
        elif vector_entry is None and _simulated(env_id) and kwargs.get("sim_mode", "composed") != "existing":
            vectorization_mode = "batched"  # a uniros simulated env of the user's: its robots share nodes
    if vectorization_mode != "batched":
        return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode=vectorization_mode,
                            vector_kwargs=vector_kwargs, **kwargs)
    from multiros.envs.vector_factory import make_batched_vector_env

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
