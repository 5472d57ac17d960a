"""The simulated IDs' Gymnasium ``vector_entry_point``: a batched vector env (one node, one request per step).

Each simulated ID is registered with ``vector_entry_point="rl_environments.vector_entry:<ID>"``;
``gymnasium.make_vec(ID, num_envs=N)`` (mode ``"vector_entry_point"``, Gymnasium's default for an
ID that has one) loads ``<ID>`` from this module and calls it with the env's keyword arguments and
optional ``vector_options`` (``autoreset_mode``, ``copy``, ``num_nodes``, ``spacing``,
``timeout_sec``, ...; see :func:`multiros.envs.vector_factory.make_batched_vector_env`).
"""

from __future__ import annotations

from typing import Any


class BatchedVectorEntryPoint:
    """``BatchedVectorEntryPoint(env_id)(num_envs, **kwargs)`` makes a batched vector env of ``env_id``."""

    def __init__(self, env_id: str) -> None:
        self.env_id = env_id

    def __call__(self, num_envs: int = 1, **kwargs: Any) -> Any:
        from multiros.envs.vector_factory import make_batched_vector_env

        return make_batched_vector_env(self.env_id, num_envs, **kwargs)

    def __repr__(self) -> str:
        return f"BatchedVectorEntryPoint({self.env_id!r})"


def __getattr__(name: str) -> BatchedVectorEntryPoint:
    from rl_environments.env_ids import ENV_SPECS

    if name in ENV_SPECS:
        return BatchedVectorEntryPoint(name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r} (batched vector entry points exist for "
                         f"{list(ENV_SPECS)})")
