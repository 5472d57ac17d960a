"""A worker process of a :class:`~multiros.envs.worker_vector.WorkerVectorEnv`: its share of the envs and its answers.

The parent starts a fresh Python on one end of a socket pair that runs :func:`_serve` (``python -c``,
see ``WorkerVectorEnv._start_worker``): it makes its share of the envs (:class:`_Share`, a batched
vector env on its own composed node), binds the shared arrays (:mod:`multiros.envs.shm_exchange`)
and answers the parent's requests (:func:`_worker_main`) until told to close or until the parent's
end of the socket closes. With ``in_parent`` the parent steps one :class:`_Share` itself, with no
socket between.

The requests: a step is the byte :data:`_STEP` (the actions are in the shared arrays already); the
others are pickled tuples (``"bind"``, ``"reset"``, ``"call"``, ``"set"``, ``"loads"``, ``"stats"``,
``"close"``). The answers are ``("ok", payload)`` or ``("error", (exception or None, traceback text))``
(:func:`_send_error`); a step's info may come as raw bytes instead (:class:`~multiros.envs.shm_exchange.InfoCodec`).
The worker learns the ID it makes from its registration, sent with the request
(:func:`_picklable_spec`, :func:`_registering_module`).
"""

from __future__ import annotations

import pickle
import signal
import time
import traceback
from multiprocessing.connection import Connection
from typing import Any

from multiros.envs.shm_exchange import InfoCodec, SharedArrays, shareable
from multiros.envs.spin_wait import QUEUED_TO_SPIN, RunQueueDelay, _poller, _spin
from multiros.ros.processes import configure_child_logging

#: The request to step (every other request is a pickled tuple)
_STEP = b"s"


def _picklable_spec(env_id: str) -> Any:
    """The ID's registration, for a worker to register an ID this process registered at run time
    (``None`` when it cannot travel: the worker then imports the module that registers it,
    :func:`_registering_module`)."""
    import gymnasium as gym

    spec = gym.spec(env_id)
    try:
        pickle.dumps(spec)
    except Exception:  # noqa: BLE001 - a lambda entry point, say
        return None
    return spec


def _registering_module(env_id: str) -> str | None:
    """The module of the ID's entry point: imported in a worker, it registers what the entry point needs
    (an upper layer's envs, an arm file's classes) without this layer naming that layer."""
    import gymnasium as gym

    entry = gym.spec(env_id).entry_point
    module = entry.partition(":")[0] if isinstance(entry, str) else getattr(entry, "__module__", None)
    return None if not module or module == "__main__" else module


def _serve(fd: int, log_level: str = "WARNING") -> None:
    """A worker process's life: its logging at the parent's level (:func:`owner_log_level`, as a node
    the parent's env starts gets it), its orders from the parent on socket ``fd``, then :func:`_worker_main`."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle (it closes us)
    configure_child_logging(log_level)
    conn = Connection(fd)
    try:
        args = conn.recv()
    except (EOFError, OSError):
        return
    except Exception:  # noqa: BLE001 - an order that does not unpickle here (a class of the parent's __main__)
        conn.send(("error", (None, traceback.format_exc())))
        return
    _worker_main(conn, *args)


class _Share:
    """One share of the N envs: its batched vector env on its own composed node, stepped on rows
    ``[start, stop)`` of the shared arrays, and its answers to the parent's requests. A worker process
    runs one (:func:`_worker_main`); with ``in_parent`` the parent runs one too, with no pipe between.

    Raises (constructor): what making the envs raises; ValueError for an observation space shared
    memory cannot carry.
    """

    def __init__(self, env_id: str, registration: tuple[Any, str | None], num_envs: int, autoreset_mode: str,
                 options: dict[str, Any], env_kwargs: dict[str, Any]) -> None:
        import importlib

        import gymnasium as gym

        from multiros.envs.batch import make_env_batch
        from multiros.envs.vector import BatchedVectorEnv

        spec, module = registration  # the ID's registration, and its entry point's module
        if module:  # the entry point's module: registers what its envs need (an upper layer's, an arm file's)
            importlib.import_module(module)
        if env_id not in gym.registry and spec is not None:
            gym.registry[env_id] = spec
        # The share's own batched vector env (the factory checked the options: the batch's only)
        batch = make_env_batch(env_id, num_envs, {**options, "num_nodes": options.get("num_nodes", 1)}, **env_kwargs)
        self.vec: Any = BatchedVectorEnv(batch, autoreset_mode=autoreset_mode, copy=False)
        self.shared: SharedArrays | None = None
        self.owns_shared = False
        self.start = self.stop = 0
        self.steps, self.busy = 0, 0.0
        self.answering = self.waiting = 0.0  # a worker's: sending its answers; blocked for its next order
        self.queued = RunQueueDelay()  # of the thread that steps it
        if not shareable(self.vec.single_observation_space):
            self.close()
            raise ValueError(f"observation space {self.vec.single_observation_space} cannot go through shared "
                             "memory: use workers=0 (in-process)")

    def spaces(self) -> tuple[Any, ...]:
        """What a worker answers once its envs are made: spaces, metadata, render mode, episode length."""
        vec = self.vec
        return (vec.single_observation_space, vec.single_action_space, dict(vec.metadata), vec.render_mode,
                vec.batch.max_episode_steps)

    def bind(self, shared: SharedArrays, start: int, stop: int, owns: bool = False) -> None:
        """Step rows ``[start, stop)`` of ``shared`` from now on (``owns``: close it with this share)."""
        self.shared, self.owns_shared, self.start, self.stop = shared, owns, start, stop
        self.vec.bind_observations(shared.observations(slice(start, stop)))

    def step(self) -> dict[str, Any]:
        """Step with the actions in the shared arrays; rewards and episode ends written there; the info back."""
        began = time.perf_counter()
        self.queued.sample()
        assert self.shared is not None, "a share steps once bound"
        a, start, stop = self.shared.arrays, self.start, self.stop
        _, rew, term, trunc, info = self.vec.step(a["act"][start:stop].copy())
        a["rew"][start:stop] = rew
        a["term"][start:stop] = term
        a["trunc"][start:stop] = trunc
        self.steps, self.busy = self.steps + 1, self.busy + time.perf_counter() - began
        return info

    def answer(self, message: tuple[Any, ...]) -> Any:
        """The answer to a request other than a step or a bind (``reset``, ``call``, ``set``, ``loads``, ``stats``)."""
        cmd, vec = message[0], self.vec
        if cmd == "reset":
            _, seeds, reset_options = message
            return vec.reset(seed=seeds, options=reset_options)[1]
        if cmd == "call":
            _, local, name, args, kwargs = message
            answer = []
            for j in local:
                value = getattr(vec.envs[j], name)
                answer.append(value(*args, **kwargs) if callable(value) else value)
            return answer
        if cmd == "set":
            _, pairs, name = message
            for j, value in pairs:
                setattr(vec.envs[j], name, value)
            return None
        if cmd == "loads":
            return vec.node_loads()
        if cmd == "stats":
            return {"steps": float(self.steps), "busy_seconds": self.busy, "answer_seconds": self.answering,
                    "wait_seconds": self.waiting, "queued_per_step": self.queued.per_step}
        raise ValueError(f"unknown worker request {cmd!r}")

    def close(self) -> None:
        """Close the envs (and the shared block when this share attached it)."""
        vec, self.vec = self.vec, None
        self.queued.close()
        if vec is not None:
            vec.close()
        if self.owns_shared and self.shared is not None:
            self.shared.close()
        self.shared = None


def _worker_main(conn: Connection, env_id: str, registration: tuple[Any, str | None], num_envs: int,
                 autoreset_mode: str, options: dict[str, Any], env_kwargs: dict[str, Any],
                 spin_wait_sec: float = 0.0) -> None:
    """A worker: make its share, bind the shared arrays, then answer requests until told to close
    or until the parent's end of the pipe closes (polling ``spin_wait_sec`` for each before it sleeps)."""
    share: _Share | None = None
    try:
        try:
            share = _Share(env_id, registration, num_envs, autoreset_mode, options, env_kwargs)
            conn.send(("ok", share.spaces()))
        except Exception as exc:  # noqa: BLE001 - the parent reports it
            conn.send(("error", (None, "".join(traceback.format_exception(exc)))))
            return
        poller, codec = _poller(conn), InfoCodec()
        while True:
            waited = time.perf_counter()
            if spin_wait_sec > 0 and share.queued.per_step < QUEUED_TO_SPIN:
                _spin(poller, spin_wait_sec)
            try:
                data = conn.recv_bytes()
            except (EOFError, OSError):
                return  # the parent is gone
            share.waiting += time.perf_counter() - waited
            if data == _STEP:
                try:
                    info = share.step()
                    answering = time.perf_counter()
                    packed = codec.pack(info)
                    if packed is None:
                        conn.send(("ok", info))
                        codec.learn(info)
                    else:
                        conn.send_bytes(packed)
                    share.answering += time.perf_counter() - answering
                except Exception as exc:  # noqa: BLE001 - the parent raises it
                    _send_error(conn, exc)
                continue
            message = pickle.loads(data)
            if message[0] == "close":
                return
            try:
                if message[0] == "bind":
                    _, name, layout, start, stop = message
                    share.bind(SharedArrays.attach(name, layout), start, stop, owns=True)
                    answer: Any = None
                else:
                    answer = share.answer(message)
                conn.send(("ok", answer))
            except Exception as exc:  # noqa: BLE001 - the parent raises it
                _send_error(conn, exc)
    finally:
        if share is not None:
            share.close()
        conn.close()


def _send_error(conn: Connection, exc: BaseException) -> None:
    text = "".join(traceback.format_exception(exc))
    try:
        pickle.dumps(exc)
        conn.send(("error", (exc, text)))
    except Exception:  # noqa: BLE001 - an exception that does not pickle: its text only
        conn.send(("error", (None, text)))
