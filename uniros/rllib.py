"""Ray RLlib env runners over uniros envs (the ``rllib`` extra; Ray pins its own gymnasium, so use a venv of its own).

:func:`register_envs` registers uniros IDs with Ray's env registry, so an RLlib config names them
like any env, and each env runner (a Ray actor in its own process, on any host of the cluster)
builds its own env with its own simulation node (composed in the runner's process by default)::

    import uniros.rllib
    from ray.rllib.algorithms.ppo import PPOConfig

    uniros.rllib.register_envs()
    config = (PPOConfig()
              .environment("RX200ReacherSim-v0", env_config={"reward_type": "dense"})
              .env_runners(num_env_runners=2, num_envs_per_env_runner=8,
                           gym_env_vectorize_mode="vector_entry_point"))

With ``gym_env_vectorize_mode="vector_entry_point"`` RLlib asks the creator for ``num_envs`` envs
at once and gets a batched vector env (one node holds the runner's robots, one request steps
them; ``env_config["vector_kwargs"]`` goes to it). Otherwise RLlib vectorises single envs itself.

Seeds: RLlib resets runner ``w`` with ``config.seed + w``; the batched env of a runner gives its env
``i`` the seed ``(config.seed + w) * num_envs + i``, so no two envs of the run share a seed (Gymnasium's
``seed + i`` would repeat seeds across runners). Without ``config.seed`` every env seeds itself from
the OS (all differ). See ``docs/vector_envs.md`` (Ray RLlib).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import gymnasium as gym
from gymnasium.vector import VectorEnv, VectorWrapper

import rl_environments

_INSTALL_HINT = ("uniros.rllib needs Ray RLlib: pip install 'uniros[rllib]' (Ray pins its own gymnasium, so put it "
                 "in a venv of its own; .ci/rllib makes one). See docs/vector_envs.md, Ray RLlib")


class RunnerSeeds(VectorWrapper):
    """A vector env whose int reset seed ``s`` gives env ``i`` the seed ``s * num_envs + i``.

    RLlib seeds env runner ``w`` with ``base + w``; Gymnasium's ``s + i`` would give runner ``w``'s env 1
    the seed of runner ``w + 1``'s env 0. With ``s * num_envs + i`` the seeds of all runners' envs differ.
    """

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        if isinstance(seed, int):
            seed = [seed * self.num_envs + i for i in range(self.num_envs)]
        return self.env.reset(seed=seed, options=options)


class EnvCreator:
    """Ray env creator for one uniros ID (picklable: Ray ships it to every env runner).

    Called with RLlib's env config (a mapping of ``uniros.make`` keyword arguments). Given
    ``num_envs`` (RLlib's ``vector_entry_point`` mode) it returns a batched vector env of that many
    envs (wrapped in :class:`RunnerSeeds`; ``vector_kwargs`` go to ``uniros.make_vec``), else one env.
    """

    def __init__(self, env_id: str) -> None:
        if env_id not in gym.registry:
            import uniros

            uniros.make(env_id)  # raises the error that lists the uniros IDs
        self.env_id = env_id

    def __call__(self, config: Mapping[str, Any] | None = None) -> gym.Env | VectorEnv:
        import uniros

        options = dict(config or {})
        num_envs = options.pop("num_envs", None)
        vector_kwargs = options.pop("vector_kwargs", None)
        if num_envs is None:
            if vector_kwargs is not None:
                raise ValueError("env_config['vector_kwargs'] needs RLlib's gym_env_vectorize_mode="
                                 "'vector_entry_point' (a batched vector env per env runner)")
            return uniros.make(self.env_id, **options)
        vec = uniros.make_vec(self.env_id, int(num_envs), vectorization_mode="batched",
                              vector_kwargs=vector_kwargs, **options)
        return RunnerSeeds(vec)

    def __repr__(self) -> str:
        return f"EnvCreator({self.env_id!r})"


def register_envs(env_ids: Iterable[str] | None = None, *, prefix: str = "") -> list[str]:
    """Register uniros IDs (default: every simulated one) with Ray's env registry; returns the names.

    Each is registered as ``prefix + env_id`` (``prefix="uniros/"`` gives ``"uniros/RX200ReacherSim-v0"``).
    Call it in the driver (before or after ``ray.init``): Ray hands the registry to every process.

    Raises:
        ImportError: Ray RLlib is not installed (the message says how to install it).
        gymnasium.error.Error: an ID that is not registered.
    """
    try:
        from ray.tune.registry import register_env
    except ImportError as exc:
        raise ImportError(_INSTALL_HINT) from exc
    names = []
    for env_id in rl_environments.ENV_IDS if env_ids is None else env_ids:
        register_env(prefix + env_id, EnvCreator(env_id))
        names.append(prefix + env_id)
    return names


__all__ = ["EnvCreator", "RunnerSeeds", "register_envs"]
