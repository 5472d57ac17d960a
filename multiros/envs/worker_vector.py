"""``WorkerVectorEnv``: a batched vector env whose N envs step in K worker processes, one core each.

Composed simulation nodes in one process stop scaling past a core or two: ``mj_step`` releases the
GIL, but each node's Python (the task, the client, the vector env) holds it. Here each of K worker
processes runs a :class:`~multiros.envs.vector.BatchedVectorEnv` of its share of the N envs (rows
``k * N // K`` up to ``(k + 1) * N // K``) on its own composed node, and the parent exchanges
actions, observations, rewards, terminations and truncations with them through shared memory
(:mod:`multiros.envs.shm_exchange`): a vector step writes the actions, wakes every worker with a
byte on its pipe, and waits for each worker's answer, which carries that step's info dict only.
With ``in_parent`` the parent steps one more share itself (rows first) while the workers step
theirs, with no pipe between: K cores then run K shares
(:func:`~multiros.envs.worker_layout.default_layout`, ``uniros.make_vec``'s default), where a worker
per core left the parent's exchange taking turns with their physics.

``sim_mode="process"`` (nodes in child processes) is this form with no share in the parent: each
worker is its node's child process, running the node composed beside its envs, so process mode
exchanges through the same shared memory instead of a Zenoh service call per node and step
(:func:`~multiros.envs.worker_layout.process_mode_workers`; ``workers=0`` keeps those calls, for a
node on a wire of the caller's).

Semantics are the in-process batched env's: the same spaces, seeds (an int seed gives env ``i``
``seed + i`` whatever K is, so env ``i`` runs the same trajectory), autoreset modes and infos.
Every wait has a timeout and watches the worker's process: a worker that dies or hangs raises
:class:`WorkerError` naming it. Workers are stopped by PID on :meth:`close`, when the env is
garbage-collected and at interpreter exit; they also exit when the parent's end of their pipe closes.
"""

from __future__ import annotations

import json
import pickle
import socket
import subprocess
import sys
import time
import weakref
from collections.abc import Callable, Mapping, Sequence
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from multiros.envs.batch import default_num_nodes
from multiros.envs.shm_exchange import PLAIN_INFO, InfoCodec, SharedArrays, layout_for, merge_infos
from multiros.envs.spin_wait import QUEUED_TO_SPIN, _poller, _spin, _spin_wait, _wait_for
from multiros.envs.vector import autoreset_mode_of
from multiros.envs.worker_layout import _count_up_to, _nodes_in_workers, pin_option, worker_cores, worker_rows
from multiros.envs.worker_process import _STEP, _picklable_spec, _registering_module, _Share
from multiros.ros.processes import owner_log_level

__all__ = ["WorkerVectorEnv", "WorkerError", "default_layout", "default_workers", "pin_option", "process_mode_workers",
           "worker_cores", "worker_rows", "QUEUED_TO_SPIN", "SPIN_WAIT_SEC", "RunQueueDelay"]

# Re-exported: these names lived in this module until it was split (issue 50), and user code and the
# docs import them from here. Their homes now: worker_layout (how many workers, which rows and cores:
# default_layout, default_workers, pin_option, process_mode_workers, worker_cores, worker_rows) and
# spin_wait (how each side waits for the other: QUEUED_TO_SPIN, SPIN_WAIT_SEC, RunQueueDelay).
from multiros.envs.spin_wait import SPIN_WAIT_SEC, RunQueueDelay
from multiros.envs.worker_layout import default_layout, default_workers, process_mode_workers


class WorkerError(RuntimeError):
    """A worker process of a :class:`WorkerVectorEnv` exited or did not answer in time."""


class _Workers:
    """The worker processes, their pipes and the shared block: what :meth:`stop` must end, kept apart
    from the env so a finalizer can stop them without holding the env alive."""

    def __init__(self) -> None:
        self.procs: list[Any] = []
        self.conns: list[Connection] = []
        self.shared: SharedArrays | None = None
        self.local: _Share | None = None  # the share this process steps itself

    def stop(self, timeout: float = 5.0) -> None:
        """Ask each worker to close, then stop any that is still running by its PID; close the share
        stepped here; free the block."""
        if self.local is not None:
            self.local.close()
            self.local = None
        for conn in self.conns:
            try:
                conn.send(("close",))
            except (OSError, ValueError):
                pass
        deadline = time.monotonic() + timeout  # one bound for all: they close at once
        for proc, conn in zip(self.procs, self.conns):
            try:
                proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()  # SIGKILL to this worker's PID
                proc.wait(timeout)
            conn.close()
        self.procs, self.conns = [], []
        if self.shared is not None:
            self.shared.close()
            self.shared = None


class WorkerVectorEnv(VectorEnv):
    """N envs of the registered ID ``env_id`` in K worker processes (see the module docstring).

    Args:
        env_id: a registered ID whose envs batch (a uniros simulated env).
        num_envs: N.
        workers: K worker processes, at least 1 and at most N (one fewer with ``in_parent``); default:
            one per core (:func:`~multiros.envs.worker_layout.default_workers`), less this process's share
            with ``in_parent``.
        in_parent: this process steps a share of the envs too (the first rows, :attr:`local_rows`).
        autoreset_mode: as :class:`~multiros.envs.vector.BatchedVectorEnv`'s.
        copy: return copies of the observations; ``False`` returns views of shared memory, overwritten
            by the next step.
        batch_options: each worker's batch options (``spacing``, ``timeout_sec``, ``num_nodes`` per
            worker, ...; see :data:`~multiros.envs.batch.BATCH_OPTIONS`).
        env_kwargs: keyword arguments of each env.
        start_timeout_sec: bound on a worker's start (its envs made); default 120 s + 4 s per env (a
            loaded machine makes an env in about 0.25 s a core, ten times that under heavy load).
        spin_wait_sec: how long this process and each worker poll for the other's next message before
            they sleep. By default :data:`~multiros.envs.spin_wait.SPIN_WAIT_SEC` for the workers where the
            shares are no more than the cores, and for this process where it also steps a share; else 0
            (sleep at once). A process that steps a share spins only while it seldom waits for a core
            (:data:`~multiros.envs.spin_wait.QUEUED_TO_SPIN`): beside other programs it sleeps at once. On
            2 cores it gains about 10 % at N = 8 (docs/vector_envs.md); a process still sleeps after it.
        pin_workers: pin each worker process (every thread of it) to a core of its own
            (:func:`~multiros.envs.worker_layout.worker_cores`), as Sample Factory does with its workers;
            this process stays free to move. Off by default: on a machine of its own it steadies the
            lockstep, beside other programs that pin theirs it costs. A worker of several composed nodes
            (``num_nodes``) then steps their physics on its one core.

    Raises:
        WorkerError: a worker that failed to start (its error is in the message).
        ValueError: bad counts, spaces that shared memory cannot carry, or ``pin_workers`` with more
            shares than cores.
    """

    def __init__(self, env_id: str, num_envs: int, *, workers: int | None = None, in_parent: bool = False,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, copy: bool = True,
                 batch_options: Mapping[str, Any] | None = None, env_kwargs: Mapping[str, Any] | None = None,
                 start_timeout_sec: float | None = None, pin_workers: bool = False,
                 spin_wait_sec: float | None = None) -> None:
        if not isinstance(num_envs, int) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        options = dict(batch_options or {})
        env_kwargs = dict(env_kwargs or {})
        if env_kwargs.get("sim_mode", "composed") != "composed":
            workers = _nodes_in_workers(num_envs, workers, in_parent, options, env_kwargs)
        if workers is None:
            workers = max(1, default_num_nodes(num_envs) - int(bool(in_parent)))
        most = num_envs - int(bool(in_parent))
        if not _count_up_to(workers, most):
            raise ValueError(f"workers must be an integer from 1 to num_envs ({num_envs})"
                             f"{' less one (this process steps a share: in_parent)' if in_parent else ''}, "
                             f"got {workers!r}")
        shares = workers + int(bool(in_parent))
        pinned = pin_option(pin_workers)
        cores: list[int | None] = list(worker_cores(workers, bool(in_parent))) if pinned else [None] * workers
        self.worker_cores = cores
        """The core each worker is pinned to (``pin_workers``), in worker order; ``None``: not pinned."""
        self.spin_wait_sec = _spin_wait(spin_wait_sec, shares, bool(in_parent))
        """Seconds this process polls for a worker's answer before it sleeps (see the constructor)."""
        self.worker_spin_wait_sec = _spin_wait(spin_wait_sec, shares, True)
        """Seconds each worker polls for this process's next order before it sleeps."""
        self.num_envs = num_envs
        self.num_workers = workers
        self.autoreset_mode = autoreset_mode_of(autoreset_mode)
        self.copy = copy
        rows = worker_rows(num_envs, shares)
        self.local_rows: tuple[int, int] | None = rows[0] if in_parent else None
        """The envs this process steps itself (``in_parent``), ``[start, stop)``; ``None``: none."""
        self.rows = rows[1:] if in_parent else rows
        self.timeout_sec = float(options.get("timeout_sec", 10.0)) + 5.0  # the worker's own bound fires first
        self._workers = _Workers()
        self._finalizer = weakref.finalize(self, self._workers.stop)
        self._broken: str | None = None
        self._pollers: dict[int, Any] = {}
        self._codecs = [InfoCodec() for _ in self.rows]  # each worker's step infos (shm_exchange.InfoCodec)
        spec = (_picklable_spec(env_id), _registering_module(env_id))  # how a worker registers the ID
        try:
            for k, (start, stop) in enumerate(self.rows):
                self._start_worker(cores[k])
                self._send(k, (env_id, spec, stop - start, self.autoreset_mode.value, options, env_kwargs,
                               self.worker_spin_wait_sec))
            if self.local_rows is not None:  # made while the workers make theirs
                start, stop = self.local_rows
                self._workers.local = _Share(env_id, spec, stop - start, self.autoreset_mode.value, options,
                                             env_kwargs)
            answers = [self._recv(k, start_timeout_sec or 120.0 + 4.0 * (stop - start), "start")
                       for k, (start, stop) in enumerate(self.rows)]  # an error here closes them all
            if self._workers.local is not None:
                answers.insert(0, self._workers.local.spaces())
            obs_space, act_space, metadata, render_mode, max_steps = answers[0]
            for k, answer in enumerate(answers[1:], 1):
                if answer[0] != obs_space or answer[1] != act_space:
                    raise ValueError(f"worker {k} made envs with other spaces than worker 0's: {answer[:2]} vs "
                                     f"{(obs_space, act_space)}")
            self._workers.shared = shared = SharedArrays.create(layout_for(num_envs, obs_space, act_space))
            for k, (start, stop) in enumerate(self.rows):
                self._send(k, ("bind", shared.name, shared.layout, start, stop))
            if self._workers.local is not None:
                self._workers.local.bind(shared, *self.local_rows)  # type: ignore[misc]
            for k in range(workers):
                self._recv(k, self.timeout_sec, "bind")
        except BaseException:
            self._finalizer()
            raise
        self._arrays = shared.arrays
        self._obs = shared.observations()
        self.single_observation_space = obs_space
        self.single_action_space = act_space
        self.observation_space = batch_space(obs_space, num_envs)
        self.action_space = batch_space(act_space, num_envs)
        self.metadata = dict(metadata)
        self.metadata["autoreset_mode"] = self.autoreset_mode
        self.render_mode = render_mode
        self.max_episode_steps: int | None = max_steps  # the envs' truncation (``None``: never)
        self.shared_memory_name: str = shared.name
        """The POSIX shared-memory block the workers exchange through (``/dev/shm/<name>`` on Linux);
        :meth:`close` unlinks it."""

    @property
    def num_shares(self) -> int:
        """The shares the envs are split into: one per worker, and this process's (``in_parent``)."""
        return self.num_workers + int(self.local_rows is not None)

    @property
    def pids(self) -> list[int]:
        """The worker processes' PIDs, in worker order (empty once closed)."""
        return [int(proc.pid) for proc in self._workers.procs]

    def _start_worker(self, core: int | None = None) -> None:
        """A fresh Python running :func:`~multiros.envs.worker_process._serve` on one end of a socket
        pair, pinned to ``core`` (if given) before it imports anything: numpy's BLAS starts its threads
        at import, and a thread inherits the affinity of the thread that starts it. Not
        ``multiprocessing``'s spawn: that runs the parent's main script again in the child (a script
        without a ``__main__`` guard would make envs there), and fork copies a process that may run threads."""
        ours, theirs = socket.socketpair()
        try:
            fd = theirs.fileno()
            boot = ("import os, sys; sys.argv[4] and os.sched_setaffinity(0, {int(sys.argv[4])}); "
                    "import json; sys.path[:0] = json.loads(sys.argv[2]); "
                    "from multiros.envs.worker_process import _serve; _serve(int(sys.argv[1]), sys.argv[3])")
            proc = subprocess.Popen([sys.executable, "-c", boot, str(fd), json.dumps([p for p in sys.path if p]),
                                     owner_log_level(), "" if core is None else str(core)],
                                    pass_fds=(fd,), stdin=subprocess.DEVNULL)
        finally:
            theirs.close()
        self._workers.procs.append(proc)
        self._workers.conns.append(Connection(ours.detach()))

    # -- the exchange -----------------------------------------------------------------------------
    def _send(self, k: int, message: Any) -> None:
        try:
            self._workers.conns[k].send(message)
        except (OSError, ValueError) as exc:
            raise self._dead(k, "a request") from exc

    def _gather(self, ks: Sequence[int], timeout: float, what: str, step: bool = False) -> list[Any]:
        """The answers of workers ``ks`` to ``what`` (``step``: to a step); every answer is read before
        a worker's error is raised, so the next request's answers are the next request's."""
        answers, error = [], None
        for k in ks:
            try:
                answers.append(self._recv(k, timeout, what, step))
            except WorkerError:
                raise
            except Exception as exc:  # noqa: BLE001 - raised once the others have answered
                answers.append(None)
                error = error or exc
        if error is not None:
            raise error
        return answers

    def _recv(self, k: int, timeout: float, what: str, step: bool = False) -> Any:
        """Worker ``k``'s answer to ``what``, within ``timeout`` seconds; its error re-raised here.
        ``step``: the answer to a step, whose info may come as raw bytes (:class:`InfoCodec`)."""
        conn, proc = self._workers.conns[k], self._workers.procs[k]
        ready, local = False, self._workers.local
        poller = self._pollers.get(k)
        if poller is None:
            poller = self._pollers[k] = _poller(conn)
        if self.spin_wait_sec > 0 and (local is None or local.queued.per_step < QUEUED_TO_SPIN):
            ready = _spin(poller, self.spin_wait_sec)
        if ready or _wait_for(poller, timeout):  # an answer, or the end of the socket: the worker exited
            try:
                data = conn.recv_bytes()
            except (EOFError, OSError) as exc:
                raise self._dead(k, what) from exc
            if step and data[:1] == PLAIN_INFO:
                try:
                    return self._codecs[k].unpack(data)
                except ValueError as exc:
                    self._broken = f"worker {k} (pid {proc.pid}) sent a step answer this process cannot read ({exc})"
                    raise WorkerError(f"vector env {self._broken}; close this vector env") from exc
            status, payload = pickle.loads(data)
            if step and status == "ok":
                self._codecs[k].learn(payload)
        else:
            self._broken = f"worker {k} (pid {proc.pid}) did not answer {what} within {timeout:g} s"
            raise WorkerError(f"vector env {self._broken}; is the machine overloaded? close this vector env")
        if status == "error":
            error, text = payload
            if what in ("start", "bind"):
                last = text.strip().splitlines()[-1] if text.strip() else "no message"
                raise WorkerError(f"vector env worker {k} (pid {proc.pid}) failed to {what}: {last} (vector_kwargs="
                                  f"{{'workers': 0}} keeps the envs in this process); its traceback:\n{text}")
            if isinstance(error, BaseException):
                first, last = self.rows[k][0], self.rows[k][1] - 1
                if hasattr(error, "add_note"):  # Python 3.11+
                    error.add_note(f"in vector env worker {k} (pid {proc.pid}, envs {first} to {last}):\n{text}")
                raise error
            raise WorkerError(f"vector env worker {k} (pid {proc.pid}) failed {what}:\n{text}")
        return payload

    def _dead(self, k: int, what: str) -> WorkerError:
        proc = self._workers.procs[k]
        try:
            code: Any = proc.wait(1.0)
        except subprocess.TimeoutExpired:
            code = "unknown (its pipe closed)"
        self._broken = f"worker {k} (pid {proc.pid}, envs {self.rows[k][0]} to {self.rows[k][1] - 1}) exited " \
                       f"with code {code} during {what}"
        return WorkerError(f"vector env {self._broken}; its envs are lost: close this vector env and make a new one")

    def _interrupted(self, exc: BaseException, what: str) -> None:
        """An exchange left by ``exc``: not an error (those are raised once every answer is read) but
        Ctrl-C or an exit, with answers unread or orders unsent. The workers are out of step: refuse
        the next request rather than read the wrong answer."""
        if not isinstance(exc, Exception):
            self._broken = f"was interrupted ({type(exc).__name__}) during {what}, with the workers' answers unread"

    def _check(self) -> None:
        if self._broken is not None:
            raise WorkerError(f"vector env {self._broken}; close this vector env and make a new one")
        if not self._workers.procs:
            raise WorkerError("this vector env is closed")

    def _all(self, messages: Sequence[Any | None], what: str, local: Any | None = None) -> list[Any]:
        """Send each worker its message (``None``: none); the share stepped here answers ``local``
        meanwhile; then gather the answers in worker order (that share's first, when it has one).
        An error of that share is raised once the workers have answered."""
        self._check()
        share = self._workers.local
        try:
            for k, message in enumerate(messages):
                if message is not None:
                    self._send(k, message)
            sent = [k for k, message in enumerate(messages) if message is not None]
            mine, gathered = self._beside(sent, what, None if share is None or local is None else
                                          lambda: share.answer(local))
        except BaseException as exc:
            self._interrupted(exc, what)
            raise
        answers = dict(zip(sent, gathered))
        found = [answers.get(k) for k in range(len(messages))]
        return [mine, *found] if share is not None else found

    def _beside(self, ks: Sequence[int], what: str, mine: Callable[[], Any] | None,
                step: bool = False) -> tuple[Any, list[Any]]:
        """This process's part (``mine``, if any) while workers ``ks`` do theirs, then their answers
        (:meth:`_gather`). An error of this process's part is raised once they have all answered, so the
        next request's answers are the next request's; a worker's error then goes unraised (a dead worker
        is still named by the next call)."""
        result, error = None, None
        if mine is not None:
            try:
                result = mine()
            except Exception as exc:  # noqa: BLE001 - raised below, once the workers have answered
                error = exc
        try:
            answers = self._gather(ks, self.timeout_sec, what, step)
        except Exception:
            if error is None:
                raise
            answers = []
        if error is not None:
            raise error
        return result, answers

    def _each(self, messages: Sequence[Any | None], what: str) -> list[Any]:
        """One message per share (:meth:`_shares` order; ``None``: none) and the answers in that order."""
        if self.local_rows is not None:
            return self._all(messages[1:], what, local=messages[0])
        return self._all(messages, what)

    def _shares(self) -> list[tuple[int, int]]:
        """Every share's rows, in the order :meth:`_all` answers: this process's first, then the workers'."""
        return ([self.local_rows] if self.local_rows is not None else []) + list(self.rows)

    def _observations(self) -> Any:
        obs = self._obs
        if not self.copy:
            return obs
        return {key: arr.copy() for key, arr in obs.items()} if isinstance(obs, dict) else obs.copy()

    # -- gymnasium API ----------------------------------------------------------------------------
    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset every env (or those in ``options["reset_mask"]``); an int seed gives env ``i`` ``seed + i``."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int):
            seeds = [seed + i for i in range(n)]
        else:
            seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(f"{len(seeds)} seeds given for num_envs={n}; give one per env or an int")
        options = dict(options) if options else {}
        mask = options.pop("reset_mask", None)
        if mask is not None:
            if not isinstance(mask, np.ndarray) or mask.shape != (n,) or mask.dtype != np.bool_:
                raise ValueError(f"options['reset_mask'] must be a bool numpy array of shape ({n},)")
            if not mask.any():
                raise ValueError("options['reset_mask'] must hold at least one True value")
        messages: list[Any] = []
        for start, stop in self._shares():
            sub = dict(options)
            if mask is not None:
                if not mask[start:stop].any():
                    messages.append(None)
                    continue
                sub["reset_mask"] = mask[start:stop].copy()
            messages.append(("reset", seeds[start:stop], sub or None))
        infos = self._each(messages, "a reset")
        parts = [(start, info) for (start, _), info in zip(self._shares(), infos) if info is not None]
        return self._observations(), merge_infos(parts, n) if parts else {}

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env: the actions into shared memory, a byte to each worker, its info back."""
        self._check()
        act = self._arrays["act"]
        arr = np.asarray(actions)
        if arr.shape != act.shape:
            raise ValueError(f"actions of shape {arr.shape} for {self.num_envs} envs with action space "
                             f"{self.single_action_space.shape}: give an array of shape {act.shape}")
        act[...] = arr
        conns = self._workers.conns
        share = self._workers.local  # steps its envs while the workers step theirs
        began, busy = time.perf_counter(), 0.0 if share is None else share.busy
        try:
            for k in range(self.num_workers):
                try:
                    conns[k].send_bytes(_STEP)
                except (OSError, ValueError) as exc:
                    raise self._dead(k, "a step") from exc
            mine, infos = self._beside(range(self.num_workers), "a step", None if share is None else share.step,
                                       step=True)
        except BaseException as exc:
            self._interrupted(exc, "a step")
            raise
        if share is not None:  # the time after its own share this process waited for the workers' answers
            share.waiting += time.perf_counter() - began - (share.busy - busy)
        parts = [(start, info) for (start, _), info in zip(self._shares(), [mine, *infos] if share else infos)]
        a = self._arrays
        return (self._observations(), a["rew"].copy(), a["term"].copy(), a["trunc"].copy(),
                merge_infos(parts, self.num_envs))

    # -- sub-env access ---------------------------------------------------------------------------
    def call_at(self, indices: Sequence[int], name: str, *args: Any, **kwargs: Any) -> list[Any]:
        """``call`` for the envs ``indices`` only (in that order)."""
        wanted = [int(i) for i in indices]
        for i in wanted:
            if not 0 <= i < self.num_envs:
                raise IndexError(f"env index {i} out of range for num_envs={self.num_envs}")
        messages: list[Any] = []
        for start, stop in self._shares():
            local = [i - start for i in wanted if start <= i < stop]
            messages.append(("call", local, name, args, kwargs) if local else None)
        answers = self._each(messages, f"call({name!r})")
        by_env: dict[int, Any] = {}
        for (start, stop), answer in zip(self._shares(), answers):
            if answer is not None:
                local = [i - start for i in wanted if start <= i < stop]
                by_env.update({start + j: value for j, value in zip(local, answer)})
        return [by_env[i] for i in wanted]

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call a method of every env (or read an attribute) and return the results in order."""
        return tuple(self.call_at(range(self.num_envs), name, *args, **kwargs))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """An attribute of every env."""
        return tuple(self.call_at(range(self.num_envs), "__getattribute__", name))

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """Set an attribute of every env (one value for all, or one per env)."""
        self.set_attr_at(range(self.num_envs), name, values)

    def set_attr_at(self, indices: Sequence[int], name: str, values: Any) -> None:
        """Set an attribute of the envs ``indices`` (one value for all, or one per index)."""
        wanted = [int(i) for i in indices]
        if not isinstance(values, (list, tuple)):
            values = [values] * len(wanted)
        if len(values) != len(wanted):
            raise ValueError(f"{len(values)} values for {len(wanted)} envs")
        messages: list[Any] = []
        for start, stop in self._shares():
            pairs = [(i - start, v) for i, v in zip(wanted, values) if start <= i < stop]
            messages.append(("set", pairs, name) if pairs else None)
        self._each(messages, f"set_attr({name!r})")

    def render(self) -> tuple[Any, ...] | None:
        """Each env's render."""
        return self.call("render")

    def worker_stats(self) -> list[dict[str, float]]:
        """Per share (this process's first, with ``in_parent``; then each worker's), since it started:
        ``steps`` (vector steps of its envs), ``busy_seconds`` (time in them, exchange excluded),
        ``answer_seconds`` (a worker's sending its answers; 0 for this process's share) and
        ``wait_seconds`` (a worker's waiting for its next order, which holds this process's turn
        between two steps and the wake-up; this process's: waiting for the workers' answers after its
        own share), and ``queued_per_step`` (a running mean of the seconds its thread waited for a
        core per vector step, :class:`~multiros.envs.spin_wait.RunQueueDelay`: above
        :data:`~multiros.envs.spin_wait.QUEUED_TO_SPIN` it sleeps at once while it waits). Between two
        calls, each seconds figure over the wall seconds is how the time went (benchmarks/bench_scaling.py)."""
        return self._each([("stats",)] * len(self._shares()), "stats")

    def node_loads(self) -> list[dict[str, Any]]:
        """Each share's simulation nodes' loads (see ``GetNodeLoad``): this process's first
        (``in_parent``), then the workers'."""
        return [load for loads in self._each([("loads",)] * len(self._shares()), "node_loads()") for load in loads]

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the workers (asked first, then by PID) and free the shared memory."""
        self._obs = self._arrays = {}  # type: ignore[assignment]
        self._finalizer()
