"""``make_batched_vector_env``: the batched vector env of an ID, in this process or in worker processes.

The one factory of both kinds (``uniros.make_vec`` and the IDs' Gymnasium ``vector_entry_point`` call
it): a :class:`~multiros.envs.vector.BatchedVectorEnv` over this process's batch of envs, or a
:class:`~multiros.envs.worker_vector.WorkerVectorEnv` whose worker processes each step a batched vector
env of their own. It stands above both, so neither imports the other's builder.
"""

from __future__ import annotations

from typing import Any

from gymnasium.vector import AutoresetMode, VectorEnv

from multiros.envs.batch import BATCH_OPTIONS, make_env_batch
from multiros.envs.vector import BatchedVectorEnv
from multiros.envs.worker_layout import default_layout, pin_option
from multiros.envs.worker_vector import WorkerVectorEnv

__all__ = ["make_batched_vector_env"]


def make_batched_vector_env(env_id: str, num_envs: int = 1, *, vector_options: dict[str, Any] | None = None,
                            **kwargs: Any) -> VectorEnv:
    """A batched vector env of ``num_envs`` envs of the registered ID ``env_id``.

    ``vector_options`` holds ``autoreset_mode``, ``copy``, ``workers`` and the batch's options
    (``num_nodes``, ``spacing``, ``timeout_sec``, ``node_name``, ``connect_kwargs``); ``kwargs`` go to
    each env. ``workers=K`` (K >= 1) steps the envs in K worker processes, one composed node each,
    exchanging actions and observations through shared memory
    (:class:`~multiros.envs.worker_vector.WorkerVectorEnv`), and ``in_parent=True`` makes this process
    step one more share itself meanwhile; with ``sim_mode="process"`` those workers are the nodes' child
    processes. ``pin_workers=True`` pins each worker process to a core of its own (none with no workers);
    ``spin_wait_sec`` is how long both sides poll for each other's message before they sleep
    (:class:`~multiros.envs.worker_vector.WorkerVectorEnv`).
    ``workers=0`` (the default here) keeps the envs in this process (:class:`BatchedVectorEnv`),
    process-mode nodes called over Zenoh. This is what ``uniros.make_vec`` (which by default puts a share
    on each core: this process and a worker per other core, :func:`~multiros.envs.worker_layout.default_layout`)
    and the IDs' Gymnasium ``vector_entry_point`` build.
    """
    options = dict(vector_options or {})
    autoreset = options.pop("autoreset_mode", AutoresetMode.NEXT_STEP)
    copy = options.pop("copy", True)
    workers = options.pop("workers", 0)
    in_parent = bool(options.pop("in_parent", False))
    pin_workers = pin_option(options.pop("pin_workers", False))
    spin_wait_sec = options.pop("spin_wait_sec", None)
    if workers is None:
        workers, in_parent = default_layout(num_envs, kwargs.get("sim_mode", "composed"), options, kwargs)
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 0:
        raise ValueError(f"workers must be 0 (this process) or a number of worker processes, got {workers!r}")
    if workers >= 1:
        unknown = sorted(set(options) - set(BATCH_OPTIONS))
        if unknown:
            raise TypeError(f"unknown batched vector env option(s) {unknown}; accepted: {list(BATCH_OPTIONS)} "
                            "and autoreset_mode, copy, workers, in_parent, pin_workers, spin_wait_sec")
        return WorkerVectorEnv(env_id, num_envs, workers=workers, in_parent=in_parent, autoreset_mode=autoreset,
                               copy=copy, batch_options=options, env_kwargs=kwargs, pin_workers=pin_workers,
                               spin_wait_sec=spin_wait_sec)
    return BatchedVectorEnv(make_env_batch(env_id, num_envs, options, **kwargs), autoreset_mode=autoreset, copy=copy)
