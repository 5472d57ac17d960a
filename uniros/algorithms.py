"""The algorithms uniros trains: one table, as rl-zoo3's ``ALGOS``.

``ALGOS`` maps a config's ``algorithm`` name to the class that implements it, by import path, so
that an algorithm is added in one line. Everything else (off-policy or not, whether it takes action
noise, gSDE, a ``MultiInputPolicy`` for goal envs) is read from the class itself, never from lists
kept beside the table. Stable-Baselines3's algorithms and sb3-contrib's (TQC, rl-zoo3's choice for
the Fetch tasks, CrossQ, TRPO, QR-DQN, ARS) are in the table, and uniros' ``drq_sac`` (SAC from
pixels, :mod:`uniros.pixel_sac`); sb3-contrib comes with the ``train``
extra (``pip install 'uniros[train]'``). RecurrentPPO is left out: its LSTM policies keep a hidden
state that uniros' evaluation and video code do not carry between steps.
"""

from __future__ import annotations

import functools
import importlib
import inspect
from collections.abc import Mapping
from typing import Any

from uniros.errors import TrainingConfigError

#: Algorithm name (a config's ``algorithm``) -> ``"module:Class"`` of its implementation.
ALGOS: dict[str, str] = {
    "sac": "stable_baselines3:SAC",
    "td3": "stable_baselines3:TD3",
    "ddpg": "stable_baselines3:DDPG",
    "ppo": "stable_baselines3:PPO",
    "a2c": "stable_baselines3:A2C",
    "dqn": "stable_baselines3:DQN",
    "tqc": "sb3_contrib:TQC",
    "crossq": "sb3_contrib:CrossQ",
    "trpo": "sb3_contrib:TRPO",
    "qrdqn": "sb3_contrib:QRDQN",
    "ars": "sb3_contrib:ARS",
    "drq_sac": "uniros.pixel_sac:DrQSAC",
}
#: The names of :data:`ALGOS`, in its order.
ALGORITHMS: tuple[str, ...] = tuple(ALGOS)


@functools.cache
def algorithm_class(name: str) -> Any:
    """The class of algorithm ``name`` (``sac``, ``tqc``, ...).

    Raises:
        TrainingConfigError: an unknown name, or its package is not installed (the message says
            which to install).
    """
    key = str(name).lower()
    if key not in ALGOS:
        raise TrainingConfigError(f"algorithm {name!r} is not one of {list(ALGOS)}")
    module, _, attr = ALGOS[key].partition(":")
    try:
        return getattr(importlib.import_module(module), attr)
    except ImportError as exc:
        dist = module.replace("_", "-")
        raise TrainingConfigError(f"algorithm {key!r} needs {dist}: pip install {dist} "
                                  f"(or pip install 'uniros[train]')") from exc


def _parameters(name: str) -> set[str]:
    return algorithm_keywords(algorithm_class(name))


def algorithm_keywords(cls: type) -> set[str]:
    """The keyword arguments ``cls`` takes: its ``__init__``'s, and, where that passes ``**kwargs`` on,
    its base classes' (``DrQSAC`` takes SAC's)."""
    names: set[str] = set()
    for klass in cls.__mro__:
        if "__init__" not in vars(klass):
            continue
        params = inspect.signature(klass.__init__).parameters
        names |= {n for n, p in params.items() if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}
        if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
            break
    return names


def is_off_policy(name: str) -> bool:
    """Whether ``name`` learns from a replay buffer (HER and demonstrations need one)."""
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

    return issubclass(algorithm_class(name), OffPolicyAlgorithm)


def takes_action_noise(name: str) -> bool:
    """Whether ``name`` takes SB3's ``action_noise`` (continuous off-policy algorithms)."""
    return "action_noise" in _parameters(name)


def takes_sde(name: str) -> bool:
    """Whether ``name`` supports gSDE (``use_sde``)."""
    return "use_sde" in _parameters(name)


def policy_names(name: str) -> tuple[str, ...]:
    """The policy aliases of ``name`` (``MlpPolicy``, ``MultiInputPolicy``, ...)."""
    return tuple(getattr(algorithm_class(name), "policy_aliases", {}))


def names_where(test: Any) -> list[str]:
    """Algorithms whose class is installed and passes ``test(name)`` (for messages)."""
    found = []
    for name in ALGOS:
        try:
            if test(name):
                found.append(name)
        except TrainingConfigError:
            continue
    return found


# Constructor parameters that are not saved as model attributes (or are uniros' to set).
_NOT_SAVED = {"self", "policy", "env", "verbose", "device", "_init_setup_model", "tensorboard_log", "policy_kwargs",
              "seed", "stats_window_size", "replay_buffer_class", "replay_buffer_kwargs", "rollout_buffer_class",
              "rollout_buffer_kwargs", "action_noise", "optimize_memory_usage", "use_sde_at_warmup"}


def algorithm_of_saved(policy_module: str, data: Mapping[str, Any]) -> str | None:
    """The algorithm of a saved model, from its policy class's module and its saved attributes.

    A policy module can serve several algorithms (PPO, A2C and TRPO share SB3's actor-critic
    policies; DDPG uses TD3's): among those, the one whose constructor parameters the model saved
    (DDPG is TD3 with ``policy_delay`` 1 and no target noise clip). ``None`` when nothing fits.
    """
    candidates = []
    for name in ALGOS:
        try:
            cls = algorithm_class(name)
        except TrainingConfigError:
            continue
        modules = {getattr(policy, "__module__", "") for policy in getattr(cls, "policy_aliases", {}).values()}
        if policy_module in modules:
            own = algorithm_keywords(cls) - _NOT_SAVED
            candidates.append((len(own - set(data)), -len(own), name))
    if not candidates:
        return None
    best = min(candidates)[2]
    if best in ("td3", "ddpg") and "ddpg" in ALGOS:
        ddpg_like = data.get("policy_delay") == 1 and not data.get("target_noise_clip")
        return "ddpg" if ddpg_like else "td3"
    return best


__all__ = [
    "ALGORITHMS",
    "ALGOS",
    "algorithm_class",
    "algorithm_of_saved",
    "is_off_policy",
    "names_where",
    "policy_names",
    "takes_action_noise",
    "takes_sde",
]
