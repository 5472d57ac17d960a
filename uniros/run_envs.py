"""The envs a run trains and evaluates on: from an env ID to the env.

An env ID is a registered ID, an arm file's (:func:`arm_file_of` names the file; a run records it
and :func:`register_run_arm` registers it again in another process), or gymnasium's ``module:ID``
form, whose module is imported (:func:`resolve_env_id`). :func:`make_env` and :func:`make_train_env`
make the env(s) of a :class:`~uniros.train_config.TrainingConfig`; :func:`check_env_id` and
:func:`check_n_envs` refuse an ID or an ``n_envs`` that cannot work, before anything is built, and
:func:`fit_learning_starts` fits HER's ``learning_starts`` to the env's episodes.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from multiros.envs.real.core import RealEnvCore
from rl_environments import ARM_TASKS
from uniros.train_config import TrainingConfig, TrainingConfigError, TrainingError


# -- env IDs ---------------------------------------------------------------------------------------
def resolve_env_id(env_id: str) -> str:
    """Import the module of a ``module:ID`` env ID (gymnasium's form) and return the bare ID.

    Raises:
        TrainingError: the module cannot be imported, or does not register the ID.
    """
    import gymnasium as gym

    module, sep, bare = env_id.rpartition(":")
    if not sep:
        return env_id
    if module not in sys.modules:
        try:
            _import_env_module(module)
        except ImportError as exc:
            raise TrainingError(
                f"cannot import {module!r} (from env ID {env_id!r}): {exc}. Install the package, or run from "
                "the directory that contains it"
            ) from exc
    if bare not in gym.registry:
        import difflib

        close = difflib.get_close_matches(bare, list(gym.registry), n=3)
        raise TrainingError(f"{module!r} was imported but did not register {bare!r}"
                            + (f"; close: {close}" if close else ""))
    return bare


def _import_env_module(module: str) -> None:
    """Import ``module``; if it is not found and the working directory holds it, from there.

    ``python -m`` puts the working directory on ``sys.path``, but an installed console script
    (``uniros``) puts its own ``bin`` directory there, so a user's ``my_pkg`` next to them would not
    import. The working directory is added (as uvicorn's ``--app-dir`` does by default) only when
    the top-level package or module is found in it.
    """
    try:
        importlib.import_module(module)
        return
    except ModuleNotFoundError as exc:
        top = module.split(".")[0]
        cwd = os.getcwd()
        local = os.path.isdir(os.path.join(cwd, top)) or os.path.isfile(os.path.join(cwd, top + ".py"))
        if exc.name != top or not local or cwd in sys.path or "" in sys.path:
            raise
    sys.path.insert(0, cwd)
    importlib.invalidate_caches()
    importlib.import_module(module)


def check_env_id(env_id: str) -> str:
    """The bare ID of a registered ID or an importable ``module:ID``.

    Raises:
        TrainingError: not registered (``unknown env ..., did you mean ...``) or not importable.
    """
    import difflib

    import gymnasium as gym

    bare = resolve_env_id(env_id)
    if bare not in gym.registry:
        close = difflib.get_close_matches(bare, list(gym.registry), n=3, cutoff=0.6)
        hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
        if _ARM_ID.match(bare):
            hint += (" (an arm file's ID is registered by its file: UNIROS_ARMS=FILE, or uniros.register_arm(FILE)"
                     " in Python)")
        raise TrainingError(f"unknown env {env_id!r}{hint} (`uniros list` shows the registered IDs; your own env: "
                            "my_pkg.my_module:MyEnv-v0)")
    return bare


#: An ID an arm file would register: ``<Arm><task>Sim-v0`` or ``<Arm><task>Real-v0``.
_ARM_ID = re.compile(r"[A-Za-z][A-Za-z0-9_]*(" + "|".join(sorted(ARM_TASKS, key=len, reverse=True))
                     + r")(Sim|Real)-v0\Z")


# -- arm files -------------------------------------------------------------------------------------
def arm_file_of(env_id: str) -> str | None:
    """The arm file, if not one uniros ships, that registered ``env_id`` (or its simulated twin):
    a run records it (``run.json``: ``arm_file``) so that ``uniros eval`` and ``--resume`` find the ID
    in a process that has not registered it."""
    from rl_environments.arm_registry import arm_env_ids, registered_arms

    bare = env_id.rpartition(":")[2]
    for spec in registered_arms().values():
        ids = arm_env_ids(spec)
        if bare in ids or bare in {real for _, _, real in ids.values()}:
            return None if _shipped(spec.path) else str(spec.path)
    return None


def _shipped(path: Path) -> bool:
    from rl_environments import shipped_arm_file

    shipped = shipped_arm_file(path.name)
    return shipped is not None and shipped.resolve() == path.resolve()


def register_run_arm(meta: dict[str, Any], where: str, note: Callable[[str], None] | None = None) -> None:
    """Register the arm file a run was trained with (``run.json``'s ``arm_file``) when its env ID is
    not registered in this process. ``where``: the ``run.json`` it came from; a relative ``arm_file`` is
    relative to the run's folder (the run moved with its arm file beside it), not to the working folder.

    Raises:
        TrainingError: the file is gone or no longer registers the ID.
    """
    import gymnasium as gym

    from rl_environments.arm_file import ArmFileError
    from rl_environments.arm_registry import register_arm, registered_arms, unregister_arm

    path, env_id = meta.get("arm_file"), str(meta.get("env_id", "")).rpartition(":")[2]
    if not isinstance(path, str) or not path or not env_id or env_id in gym.registry:
        return
    if not Path(path).is_absolute():
        path = str(Path(where).parent / path)
    fix = "put it back, or register the arm yourself (UNIROS_ARMS=FILE, or uniros.register_arm(FILE))"
    if not Path(path).is_file():
        raise TrainingError(f"{where}: the run's env {env_id} comes from the arm file {path}, which is gone: {fix}")
    try:
        ids = register_arm(Path(path))
    except ArmFileError as exc:
        raise TrainingError(f"{where}: the run's arm file no longer registers {env_id} ({exc}): {fix}") from None
    if env_id not in ids:  # the file names another arm now: take back what it registered
        for name, spec in list(registered_arms().items()):
            if spec.path == Path(path).resolve():
                unregister_arm(name)
        raise TrainingError(f"{where}: the run's arm file {path} no longer registers {env_id} (it registers "
                            f"{', '.join(ids[:2])}, ...): {fix}")
    if note is not None:
        note(f"registered the arm file {path} this run was trained with (run.json)")


# -- making the envs -------------------------------------------------------------------------------
def make_env(env_id: str, **kwargs: Any) -> Any:
    """``uniros.make`` for a registered ID or a ``module:ID``.

    Raises:
        TrainingError: the env does not take one of ``kwargs`` (the message names it), or the simulation
            refused to make its world (a scene that does not fit the robot: one line naming the arm file).
    """
    import re

    import uniros
    from multiros.sim.client import SimulationServiceError
    from uniros.factory import EnvKeywordError, did_you_mean

    try:
        return uniros.make(resolve_env_id(env_id), **kwargs)
    except SimulationServiceError as exc:
        raise TrainingError(f"{env_id} cannot be made: {str(exc).splitlines()[0]}{_arm_hint(env_id)}") from None
    except TypeError as exc:
        match = re.search(r"unexpected keyword argument\(?s?\)? \[?'([^']+)'", str(exc))
        if match is None or match[1] not in kwargs:
            raise
        accepted = str(exc).partition(" accepts: ")[2]
        hint = did_you_mean({match[1]: exc.suggestions[match[1]]}) if isinstance(exc, EnvKeywordError) \
            and match[1] in exc.suggestions else ""
        raise TrainingError(f"{env_id} does not take the env kwarg {match[1]!r}{hint} (env_kwargs of the config, e.g. "
                            "a shipped RX200 config's ee_action_type on another env): remove it"
                            + (f"; it accepts: {accepted}" if accepted else "")) from None


def _arm_hint(env_id: str) -> str:
    """For an arm file's ID: which file, and the command that tries it."""
    path = arm_file_of(env_id)
    return "" if path is None else f" (its arm file {path}: `uniros arm check {path}` tries its tasks)"


def make_train_env(env_id: str, config: TrainingConfig, factory: Callable[[], Any] | None = None) -> Any:
    """The env ``config`` trains on: one env, or with ``n_envs`` > 1 a batched vector env.

    ``n_envs`` envs ``env_id`` share one simulation node and one request per step
    (:func:`uniros.vec_env.make_batched_vec_env`, ``env_kwargs`` to each env). With ``factory`` (a
    baseline's own env builder) they are ``factory``'s envs in SB3's ``DummyVecEnv`` instead.

    Raises:
        TrainingConfigError: ``n_envs`` > 1 for an env that cannot be batched (a real robot's).
    """
    n = config.n_envs
    if n == 1:
        return factory() if factory is not None else make_env(env_id, **config.env_kwargs)
    if factory is not None:
        from stable_baselines3.common.vec_env import DummyVecEnv

        return DummyVecEnv([factory] * n)
    from multiros.envs.worker_vector import WorkerError
    from multiros.sim.client import SimulationServiceError
    from uniros.vec_env import make_batched_vec_env

    check_n_envs(env_id, config)
    try:
        return make_batched_vec_env(resolve_env_id(env_id), n, pin_workers=config.pin_workers, **config.env_kwargs)
    except SimulationServiceError as exc:  # the share stepped in this process
        raise TrainingError(f"{env_id} cannot be made: {str(exc).splitlines()[0]}{_arm_hint(env_id)}") from None
    except WorkerError as exc:  # a worker's: its traceback's last line says what the node refused
        refused = [line for line in str(exc).splitlines() if line.startswith(SimulationServiceError.__module__)]
        if not refused:
            raise
        reason = refused[-1].partition(": ")[2]
        raise TrainingError(f"{env_id} cannot be made: {reason}{_arm_hint(env_id)}") from None


def check_n_envs(env_id: str, config: TrainingConfig, origin: str | None = None) -> None:
    """Refuse an ``n_envs`` above 1 that cannot work, before anything is built or written.

    ``origin`` says where ``n_envs`` came from in the message (default: the config file).

    Raises:
        TrainingConfigError: the env cannot share a simulation node (a real robot's, or not a uniros
            env), or ``train_freq`` counts episodes (SB3 trains episodically with one env only).
    """
    import gymnasium as gym

    from multiros.envs.batch import batchable, env_creator

    n = config.n_envs
    if n == 1:
        return
    where = origin or f"{config.source}: n_envs: {n}"
    resolved = resolve_env_id(env_id)
    creator = env_creator(resolved) if resolved in gym.registry else None
    if creator is not None and not batchable(creator):
        kind = "drives a real robot" if issubclass(creator, RealEnvCore) else "is not a uniros simulated env"
        raise TrainingConfigError(f"{where} trains {n} envs of {env_id} in one simulation node, but {env_id} {kind}; "
                                  "train it with n_envs: 1")
    train_freq = config.algo_params.get("train_freq")
    if isinstance(train_freq, (tuple, list)) and len(train_freq) == 2 and str(train_freq[1]) == "episode":
        raise TrainingConfigError(f"{where}: train_freq counts episodes ({train_freq[0]}, episode), which SB3 does "
                                  "with one env only; count steps (train_freq: {freq: 1, unit: step}) or use n_envs: 1")


def fit_learning_starts(env_id: str | None, config: TrainingConfig, *, episode_steps: int | None = None) -> str | None:
    """Raise HER's ``learning_starts`` to ``n_envs`` episodes, so learning starts after an ended one.

    SB3's ``HerReplayBuffer`` samples only from ended episodes and raises before the first. One env
    ends its first episode (at the latest) after ``max_episode_steps`` steps; ``n_envs`` envs step
    together, so that takes ``n_envs * max_episode_steps`` env steps. The episode limit is
    ``episode_steps``, else the config's ``env_kwargs`` or ``env_id``'s registration. Returns what
    was changed, or ``None``.
    """
    import gymnasium as gym

    if not config.use_her or config.n_envs == 1:
        return None
    limit = episode_steps or config.env_kwargs.get("max_episode_steps")
    if limit is None and env_id is not None:
        resolved = resolve_env_id(env_id)
        limit = gym.spec(resolved).max_episode_steps if resolved in gym.registry else None
    starts = int(config.algo_params.get("learning_starts", 100))
    if limit is None or starts >= config.n_envs * int(limit):
        return None
    config.algo_params["learning_starts"] = config.n_envs * int(limit)
    return (f"learning_starts {starts} -> {config.n_envs * int(limit)}: HER samples only ended episodes, and "
            f"{config.n_envs} envs of {limit}-step episodes end their first after {config.n_envs} x {limit} steps")


def reports_success(env: Any, env_id: str | None = None) -> bool:
    """Whether ``env`` (or the sub-envs of an SB3 ``VecEnv``) puts ``is_success`` in its infos.

    ``env_id`` names the registered ID when the env has no ``spec`` (a batched vector env's envs).
    Sub-envs in other processes (``SubprocVecEnv``) are judged by their spec and their spaces.
    """
    import gymnasium as gym
    from gymnasium_robotics.core import GoalEnv
    from stable_baselines3.common.vec_env import VecEnv

    import rl_environments

    if isinstance(env, VecEnv) and not hasattr(env, "envs"):
        space = env.observation_space
        goal = isinstance(space, gym.spaces.Dict) and {"achieved_goal", "desired_goal"} <= set(space.spaces)
        spec = env.get_attr("spec", [0])[0]
        return goal or (spec.id if spec is not None else env_id) in rl_environments.ENV_IDS
    if isinstance(env, VecEnv):
        env = env.envs[0]
    spec = getattr(env, "spec", None)
    spec_id = spec.id if spec is not None else env_id
    return isinstance(getattr(env, "unwrapped", env), GoalEnv) or spec_id in rl_environments.ENV_IDS
