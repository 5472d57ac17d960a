"""How a worker vector env's N envs are laid out over worker processes: how many workers, which rows and cores.

:func:`default_layout` (``uniros.make_vec``'s default) puts a share of the envs on each core: this
process steps one and a worker process each of the others (:func:`default_workers`); in
``sim_mode="process"`` every node is a worker process of its own (:func:`process_mode_workers`,
:func:`_nodes_in_workers`). Worker ``k`` of K steps rows :func:`worker_rows` ``[k * N // K, (k + 1) * N // K)``;
with ``pin_workers`` (:func:`pin_option`) each runs on a core of its own (:func:`worker_cores`).
Plain arithmetic on counts, options and the cores this process may use: nothing here starts a process.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from multiros.envs.batch import default_num_nodes

__all__ = ["default_layout", "default_workers", "pin_option", "process_mode_workers", "worker_cores", "worker_rows"]

#: Batch options that place nodes by hand (a worker makes its own node)
_PLACING = ("node_name", "connect_kwargs")


def default_workers(num_envs: int, sim_mode: str = "composed", options: Mapping[str, Any] | None = None,
                    env_kwargs: Mapping[str, Any] | None = None) -> int:
    """The number of worker processes ``uniros.make_vec`` uses unless told.

    * Composed nodes, their layout left to the default: one per core this process may run on
      (``os.sched_getaffinity``), at most one per env; ``0`` (in this process) where that is one.
    * ``sim_mode="process"``: a worker per node, each node in a child process with its envs
      (:func:`process_mode_workers`): ``num_nodes`` of them, else one per core.
    * ``0`` where the nodes are elsewhere already (``"existing"``), placed by hand (``num_nodes`` of
      composed nodes, ``node_name``, ``connect_kwargs``), or where a process-mode node must be on a wire
      or show a viewer (``transport``, ``gui``).
    """
    options = options or {}
    if sim_mode == "process":
        return process_mode_workers(num_envs, options, env_kwargs)
    if sim_mode != "composed" or any(key in options for key in ("num_nodes", *_PLACING)):
        return 0
    k = default_num_nodes(num_envs)
    return k if k >= 2 else 0


def process_mode_workers(num_envs: int, options: Mapping[str, Any], env_kwargs: Mapping[str, Any] | None = None) -> int:
    """Worker processes for ``sim_mode="process"``: each node in a child process, as the mode says, and
    its envs' task code with it, the actions and observations through shared memory (no message per
    step). ``num_nodes`` nodes, else one per core (at most one per env). ``0`` (nodes in child processes
    reached over their private Zenoh router, one service call per node and step, the envs' code in
    this process) where the node must be on a wire of the caller's choice (``transport``) or show a
    viewer (``gui``), where it is placed by hand (``node_name``, ``connect_kwargs``), or where
    ``num_nodes`` is not a count of nodes (the batch then says why)."""
    if _wired(env_kwargs or {}) or any(key in options for key in _PLACING):
        return 0
    k = options.get("num_nodes")
    if k is None:
        return default_num_nodes(num_envs)
    return k if _count_up_to(k, num_envs) else 0


def _count_up_to(value: Any, most: int) -> bool:
    """Whether ``value`` is a count from 1 to ``most`` (an int, not a bool)."""
    return isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= most


def _wired(env_kwargs: Mapping[str, Any]) -> str | None:
    """The env keyword that asks for a node of its own process (a wire, a viewer), if any: a worker's
    node is composed in it, on no wire and with no viewer. ``$UNIROS_TRANSPORT`` naming a wire other
    than the private router's Zenoh counts as ``transport`` (process mode's node would take it)."""
    chosen = next((key for key in ("transport", "gui") if env_kwargs.get(key) not in (None, False)), None)
    if chosen is None and os.environ.get("UNIROS_TRANSPORT", "") not in ("", "zenoh", "inproc"):
        return "UNIROS_TRANSPORT"
    return chosen


def default_layout(num_envs: int, sim_mode: str = "composed", options: Mapping[str, Any] | None = None,
                   env_kwargs: Mapping[str, Any] | None = None) -> tuple[int, bool]:
    """``(workers, in_parent)`` of ``uniros.make_vec`` unless told: a share of the envs per core, one
    of them stepped by this process while the workers step theirs (:func:`default_workers` cores: one
    worker process fewer; a worker per core besides the parent left three processes on two cores, the
    parent's exchange taking turns with the workers' physics). ``(0, False)``: all in this process.
    ``sim_mode="process"``: every node in a worker process, none in this one."""
    k = default_workers(num_envs, sim_mode, options, env_kwargs)
    if sim_mode == "process":
        return k, False
    return (k - 1, True) if k >= 2 else (0, False)


def _nodes_in_workers(num_envs: int, workers: int | None, in_parent: bool, options: dict[str, Any],
                      env_kwargs: dict[str, Any]) -> int | None:
    """``sim_mode="process"`` with workers: each worker is the child process of its node, which it
    runs composed beside its envs (one node a worker). Rewrites ``options`` and ``env_kwargs`` for the
    workers (``num_nodes`` becomes the worker count, the mode ``"composed"`` inside them) and returns
    the number of workers. Other modes reach nodes elsewhere: refused."""
    mode = env_kwargs.get("sim_mode")
    if mode != "process":
        raise ValueError(f"worker processes run their envs' nodes in themselves; sim_mode={mode!r} reaches nodes "
                         "elsewhere: use workers=0")
    if in_parent:
        raise ValueError("sim_mode='process' puts every node in a child process; in_parent would step a share "
                         "(and its node) in this process")
    key = _wired(env_kwargs)
    if key is not None:
        value = env_kwargs.get(key, os.environ.get(key))
        raise ValueError(f"a worker runs its node composed, on no wire and with no viewer; {key}={value!r} "
                         "needs workers=0 (each node a process of its own)")
    placed = [key for key in _PLACING if key in options]
    if placed:
        raise ValueError(f"a worker makes its own node, composed; {placed} place nodes by hand: use workers=0")
    nodes = options.pop("num_nodes", None)  # in process mode: all the nodes, one a worker
    if nodes is not None and not _count_up_to(nodes, num_envs):
        raise ValueError(f"num_nodes must be an integer from 1 to num_envs ({num_envs}), got {nodes!r}")
    if workers is None:
        workers = nodes
    elif nodes is not None and nodes != workers:
        raise ValueError(f"sim_mode='process' with workers puts one node in each, so num_nodes counts all the "
                         f"nodes (composed workers take it per worker): num_nodes={nodes} and workers={workers} differ")
    env_kwargs["sim_mode"] = "composed"
    return workers


def worker_rows(num_envs: int, workers: int) -> list[tuple[int, int]]:
    """Rows ``[start, stop)`` of each of ``workers`` workers (the batch's node split: ``i * K // N``)."""
    return [(k * num_envs // workers, (k + 1) * num_envs // workers) for k in range(workers)]


def pin_option(value: Any) -> bool:
    """The ``pin_workers`` option checked: a bool (a YAML ``true``/``false``).

    Raises:
        ValueError: anything else.
    """
    if not isinstance(value, bool):
        raise ValueError(f"pin_workers must be true or false, got {value!r}")
    return value


def worker_cores(workers: int, in_parent: bool = False) -> list[int]:
    """The core each of ``workers`` pinned workers runs on: the cores this process may use
    (``os.sched_getaffinity``), in order, one a worker; with ``in_parent`` the first is left to this
    process's share (it is not pinned: it still moves where the scheduler finds room).

    Raises:
        ValueError: more shares than cores (two pinned workers would take turns on one), or a platform
            without CPU affinity.
    """
    if not hasattr(os, "sched_setaffinity"):
        raise ValueError("pin_workers needs CPU affinity (os.sched_setaffinity), which this platform lacks")
    cores = sorted(os.sched_getaffinity(0))
    first = int(bool(in_parent))
    if first + workers > len(cores):
        raise ValueError(f"pin_workers gives each worker a core of its own: {workers} worker(s)"
                         f"{' and this process' if in_parent else ''} need {first + workers} cores, and this process "
                         f"may use {len(cores)} ({cores}); use fewer workers or leave pin_workers off")
    return cores[first:first + workers]
