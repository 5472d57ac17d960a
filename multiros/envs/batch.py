"""A batch of envs whose robots share simulation nodes: one step call per node per step.

:class:`EnvBatch` holds N ordinary task-env instances spread over K simulation nodes (N/K robots
each). Each env spawns its robot in its own namespace and **world slot** (an offset far beyond an
arm's reach, so robots never touch, with frame positions reported relative to it: each env sees
exactly the numbers it would see alone). A step:

1. runs the envs' action hooks: for a task written batch-first (:mod:`multiros.envs.batch_task`)
   once for all N, on ``(N, ...)`` arrays; for envs with hooks of their own (a user's MultiROS
   env), env by env. Either way each env's commands wait in its connection;
2. steps every node's robots with one call per node (:class:`~multiros.sim.stepper.RobotStepper`:
   direct into a node composed in this process, the ``StepRobots`` service otherwise), all K at
   once: the physics of composed nodes runs on worker threads (``mj_step`` releases the GIL),
   calls to other processes or hosts go out on workers;
3. hands each env's connection its robot's state and scores the step, batch-first or env by env.

The batch drives the envs only through their public seam (``connection``, ``step_act``,
``step_result``, ``check_actions``, ``note_step_status``, ``reset``); it never reads their private state.

The vector envs on top (:class:`multiros.envs.vector.BatchedVectorEnv` for Gymnasium,
``uniros.vec_env.BatchedVecEnv`` for Stable-Baselines3) add the autoreset rules.

Faults: a robot that diverges, or whose commands the node refuses, ends its episode alone
(``truncated``, ``info["sim_error"]``; ``info["sim_diverged"]`` for divergence) and the others
step on. A node that dies or stops answering raises :class:`~multiros.sim.client.SimulationNodeError`
naming it, within the batch's ``timeout_sec`` (at once when its process is seen to exit).
"""

from __future__ import annotations

import concurrent.futures
import itertools
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from multiros.envs.base_env import end_on_fault
from multiros.envs.batch_task import StepResults, act_rows, batch_route, uses_own_hooks
from multiros.envs.errors import EnvError
from multiros.envs.sim_env import MujocoEnvCore
from multiros.robot_state import RobotStates
from multiros.sim.client import SimulationNodeError
from multiros.sim.stepper import PendingStep, RobotStepper, StepReply

__all__ = ["EnvBatch", "slot_offset", "make_env_batch", "env_creator", "batchable", "default_num_nodes",
           "BATCH_OPTIONS", "usable_cores"]

_batch_ids = itertools.count()


def slot_offset(index: int, count: int, spacing: float) -> tuple[float, float, float]:
    """World slot ``index`` of ``count``: a square grid in the x-y plane, ``spacing`` metres apart."""
    cols = max(1, math.ceil(math.sqrt(count)))
    return (float(index % cols) * spacing, float(index // cols) * spacing, 0.0)


def default_num_nodes(num_envs: int) -> int:
    """The number of composed simulation nodes a batch of ``num_envs`` uses unless told: one per
    core this process may run on (``os.sched_getaffinity``), at most one per env. Composed nodes step
    their physics at once on threads (``mj_step`` releases the GIL), so on a 2-core machine 8 envs
    step faster on 2 nodes than on 1 (``benchmarks/bench_vec.py``)."""
    return max(1, min(num_envs, usable_cores()))


def usable_cores() -> int:
    """The cores this process may run on (``os.sched_getaffinity``; the CPU count where the platform
    has no affinity)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


class EnvBatch:
    """N envs over K simulation nodes, stepped with one call per node (see the module docstring).

    Args:
        make_env: ``make_env(**kwargs)`` creates one env (a :class:`~multiros.envs.sim_env.MujocoEnvCore`
            task env); it is called with ``sim_connection``, ``world_slot``, ``robot_name`` and ``seed``.
        num_envs: N, the number of envs (robots).
        robot_name: base of the robots' entity names (each gets ``<base>_<batch>_<i>``, its namespace too).
        sim_mode: ``"composed"`` (nodes in this process), ``"process"`` (nodes in child processes, each
            behind its own private Zenoh router) or ``"existing"`` (running nodes named ``node_name``,
            shared with other clients; pass ``connect_kwargs={"context": ...}`` to reach them through a
            given ROS context).
        num_nodes: K nodes; env ``i`` lives on node ``i * K // N``. Default: composed, one per core
            (:func:`default_num_nodes`); in a child process or existing, one.
        spacing: metres between world slots (larger than twice the robot's reach).
        timeout_sec: bound on every request; a node that does not answer in time is named in the error.
        max_episode_steps: truncate episodes after this many steps (``None``: never).
        node_name: the simulation nodes' name (each behind its own router in process mode); with
            ``sim_mode="existing"`` a list of K names reaches K running nodes (e.g. on K hosts joined
            by a Zenoh router network), and ``num_nodes`` is its length.
        trusted_paths: folders of local robot files the nodes may read.
        connect_kwargs: more options for :func:`multiros.sim.launch.connect`.

    Raises:
        ValueError: bad counts, or ``num_envs`` beyond what the nodes accept (``max_robots``).
    """

    def __init__(
        self,
        make_env: Callable[..., Any],
        num_envs: int,
        *,
        robot_name: str = "robot",
        sim_mode: str = "composed",
        num_nodes: int | None = None,
        spacing: float = 2.0,
        timeout_sec: float = 10.0,
        max_episode_steps: int | None = None,
        node_name: str | Sequence[str] = "mujoco_sim",
        trusted_paths: Sequence[str] = (),
        connect_kwargs: Mapping[str, Any] | None = None,
    ) -> None:
        from multiros.sim.launch import connect  # the sim layer's launcher (DESIGN §2)

        names = [node_name] if isinstance(node_name, str) else list(node_name)
        if not isinstance(num_envs, int) or isinstance(num_envs, bool) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if not isinstance(node_name, str):
            if sim_mode != "existing" or not names:
                raise ValueError("a list of node names needs sim_mode='existing' and at least one name")
            num_nodes = len(names)
        if num_nodes is None:
            num_nodes = default_num_nodes(num_envs) if sim_mode == "composed" else 1
        if not isinstance(num_nodes, int) or isinstance(num_nodes, bool) or not 1 <= num_nodes <= num_envs:
            raise ValueError(f"num_nodes must be an integer from 1 to num_envs ({num_envs}), got {num_nodes!r}")
        if sim_mode not in ("composed", "process", "existing"):
            raise ValueError(f"sim_mode must be 'composed', 'process' or 'existing', got {sim_mode!r}")
        if sim_mode == "existing" and len(names) != num_nodes:
            raise ValueError(f"num_nodes={num_nodes} running nodes need {num_nodes} node names, got {names}")
        if not (math.isfinite(spacing) and spacing > 0):
            raise ValueError(f"spacing must be a positive number of metres, got {spacing!r}")
        self.num_envs = num_envs
        self.num_nodes = num_nodes
        self.timeout_sec = float(timeout_sec)
        self.max_episode_steps = max_episode_steps
        self.node_of = [i * num_nodes // num_envs for i in range(num_envs)]
        self.members: list[list[int]] = [[i for i in range(num_envs) if self.node_of[i] == k] for k in range(num_nodes)]
        self.connections: list[Any] = []
        self.steppers: list[RobotStepper] = []
        self.envs: list[Any] = []
        self.task: type | None = None
        self._elapsed = np.zeros(num_envs, dtype=np.int64)
        self._current: RobotStates | None = None  # every env's state as rows, while it stands
        self._executor: concurrent.futures.ThreadPoolExecutor | None = None
        tag = f"{os.getpid()}x{next(_batch_ids)}"
        try:
            for k in range(num_nodes):
                name = names[k] if sim_mode == "existing" else names[0]
                self.connections.append(connect(sim_mode, node_name=name, timeout_sec=max(self.timeout_sec, 30.0),
                                                 trusted_paths=trusted_paths, **dict(connect_kwargs or {})))
                self.steppers.append(self.connections[-1].stepper(self.timeout_sec))
            for k, conn in enumerate(self.connections):
                self._check_capacity(k, conn, len(self.members[k]))
            for i in range(num_envs):
                members = self.members[self.node_of[i]]
                env = make_env(sim_connection=self.connections[self.node_of[i]], robot_name=f"{robot_name}_{tag}_{i}",
                               world_slot=slot_offset(members.index(i), len(members), spacing))
                if not isinstance(env, MujocoEnvCore):
                    raise TypeError(f"a batched vector env needs uniros envs on the simulation node; got "
                                    f"{type(env).__name__}: use vectorization_mode='sync' or 'async' for it")
                self.envs.append(env)
                if env.step_config.mode != "lockstep":
                    raise ValueError(f"a batched vector env steps its robots in lockstep; env {i} has "
                                     f"step_mode={env.step_config.mode!r}")
            steps = {env.step_config.num_sim_steps for env in self.envs}
            if len(steps) != 1:
                raise ValueError(f"the envs of one batch must share num_sim_steps, got {sorted(steps)}")
            self.num_sim_steps = steps.pop()
            cls = type(self.envs[0])
            if all(type(env) is cls for env in self.envs) and batch_route(cls) is not None:
                self.task = cls  # its batch functions step all the envs at once
        except BaseException:
            self.close()
            raise

    def _check_capacity(self, k: int, conn: Any, share: int) -> None:
        load = conn.client.get_node_load()
        free = int(load["max_robots"]) - int(load["robots"])
        if share > free:
            raise ValueError(
                f"num_envs={self.num_envs} puts {share} robots on simulation node {self._node_label(k)}, which "
                f"accepts {free} more (max_robots={load['max_robots']}, documented in docs/simulation_node.md); "
                f"use num_nodes > 1 (more nodes) or fewer envs"
            )

    def _node_label(self, k: int) -> str:
        conn = self.connections[k]
        pid = f", pid {conn.pid}" if conn.pid is not None else ""
        return f"{k} of {self.num_nodes} ({conn.client.sim_node}{pid})"

    @property
    def hooks(self) -> type | None:
        """The env class whose batch-first task functions step these envs (``None``: env by env)."""
        return self.task

    # -- stepping -------------------------------------------------------------------------------
    def step_envs(self, indices: Sequence[int], actions: Any) -> StepResults:
        """Step envs ``indices`` with ``actions`` (one per index): one call per node, all nodes at once.

        Every env's action hooks run first (a bad action raises before any node steps). Robots of
        envs not in ``indices`` stay in the world and advance too (their controllers hold their
        last commands); such envs are about to be reset, which puts back their whole state.
        """
        indices = list(indices)
        envs = [self.envs[i] for i in indices]
        every = len(indices) == self.num_envs and indices == list(range(self.num_envs))
        task = self.task if self.task is not None and not any(map(uses_own_hooks, envs)) else None
        self._act(envs, actions, task, self._current if every else None)
        groups: dict[int, list[int]] = {}
        for j, i in enumerate(indices):
            groups.setdefault(self.node_of[i], []).append(j)
        stacked = self._advance(envs, groups)
        self._current = stacked if every else None
        if task is not None:
            states = stacked if stacked is not None else RobotStates.of([env.robot_state for env in envs])
            if states is None:
                raise EnvError(f"the robots of {type(envs[0]).__name__} report different joints; a batch-first task "
                               "needs robots alike")
            results = task.batch_results(envs, states)  # type: ignore[attr-defined]
        else:
            results = StepResults.of([env.step_result() for env in envs])
        end_on_fault(results)
        elapsed = self._elapsed
        for j, i in enumerate(indices):
            elapsed[i] += 1
            if self.max_episode_steps is not None and elapsed[i] >= self.max_episode_steps:
                results.truncated[j] = True
        return results

    def _act(self, envs: Sequence[Any], actions: Any, task: type | None, states: RobotStates | None) -> None:
        """The envs' action hooks: all at once for a batch-first task (``states``: the envs' current
        states as rows, when the batch holds them), else env by env (either way a bad action raises
        before anything is sent)."""
        if task is None:
            for env, action in zip(envs, actions):
                env.step_act(action)
            return
        checked = envs[0].check_actions(np.asarray(actions, dtype=np.float64))
        if states is None:
            states = RobotStates.of([env.robot_state for env in envs])
        if states is None:
            raise EnvError(f"the robots of {type(envs[0]).__name__} report different joints; a batch-first task "
                           "needs robots alike")
        act_rows(task, envs, checked, states)  # as one env's step acts (its connection's checks included)

    def _advance(self, envs: Sequence[Any], groups: Mapping[int, list[int]]) -> RobotStates | None:
        """One call per node for the envs of ``groups`` (node -> positions in ``envs``); hands each
        env its robot's state and status. Returns the states as rows in ``envs``' order when every
        node stacked its robots alike (one node: its own stack; several: concatenated)."""
        items = list(groups.items())
        if len(items) == 1:
            (k, group), = items
            reply = self._call(k, [envs[j] for j in group])
            return self._hand_out(envs, group, reply)
        replies = self._call_all(envs, items)
        stacks = [self._hand_out(envs, group, replies[k]) for k, group in items]
        if any(s is None for s in stacks):
            return None
        order = [j for _, group in items for j in group]
        parts: list[RobotStates] = [s for s in stacks if s is not None]
        if order != sorted(order) or any(p.names != parts[0].names or p.frame_positions.shape[1:] !=
                                         parts[0].frame_positions.shape[1:] for p in parts):
            return None
        return RobotStates(parts[0].sim_time, parts[0].names, *(np.concatenate([getattr(p, f) for p in parts]) for f in
                                                                 ("position", "velocity", "effort", "frame_positions",
                                                                  "frame_orientations")))

    def _hand_out(self, envs: Sequence[Any], group: Sequence[int], reply: StepReply) -> RobotStates | None:
        for j, pos in enumerate(group):
            env = envs[pos]
            env.note_step_status(env.connection.accept_reply(reply, j))
        return reply.stacked

    def _call(self, k: int, envs: Sequence[Any]) -> StepReply:
        """One call to node ``k`` for ``envs``' robots, on this thread."""
        try:
            return self.steppers[k].step([env.connection.step_spec() for env in envs], self.num_sim_steps)
        except SimulationNodeError as exc:
            raise SimulationNodeError(f"simulation node {self._node_label(k)} failed a vector step"
                                      f"{self._exit_note(k)}: {exc}") from exc

    def _call_all(self, envs: Sequence[Any], items: Sequence[tuple[int, list[int]]]) -> dict[int, StepReply]:
        """One call per node, at once: each call begins on this thread (a composed node's lock is taken
        and its commands applied there), its physics or request runs on a worker, except the last
        node's, which runs here; then each call finishes here, in order."""
        calls: dict[int, PendingStep] = {}
        futures: dict[int, concurrent.futures.Future] = {}
        done = False
        try:
            *others, (last, last_group) = items
            for k, group in others:
                calls[k] = self.steppers[k].begin([envs[j].connection.step_spec() for j in group], self.num_sim_steps)
                futures[k] = self._pool().submit(calls[k].advance)
            calls[last] = self.steppers[last].begin([envs[j].connection.step_spec() for j in last_group],
                                                    self.num_sim_steps)
            calls[last].advance()
            replies: dict[int, StepReply] = {}
            for k, _ in items:
                if k in futures:
                    self._wait(k, futures[k])
                try:
                    replies[k] = calls[k].finish()
                except SimulationNodeError as exc:
                    raise SimulationNodeError(f"simulation node {self._node_label(k)} failed a vector step"
                                              f"{self._exit_note(k)}: {exc}") from exc
            done = True
            return replies
        finally:
            if not done:  # an error: let the work under way end before the nodes' locks are released
                concurrent.futures.wait(list(futures.values()), timeout=self.timeout_sec)
            for call in calls.values():
                call.close()

    def _wait(self, k: int, future: concurrent.futures.Future) -> None:
        """Wait for node ``k``'s work on a worker, or raise an error naming the node if its process
        exits or it does not answer."""
        deadline = time.monotonic() + self.timeout_sec
        process = self.connections[k].process
        while True:
            try:
                future.result(timeout=0.05)
                return
            except concurrent.futures.TimeoutError:
                pass
            if process is not None and process.poll() is not None:
                raise SimulationNodeError(
                    f"simulation node {self._node_label(k)} exited with code {process.returncode} during a "
                    f"vector step; its robots are lost: close this vector env and make a new one"
                )
            if time.monotonic() >= deadline + 1.0:  # the call's own timeout should have fired
                raise SimulationNodeError(f"simulation node {self._node_label(k)} did not answer StepRobots "
                                          f"within {self.timeout_sec:g} s; is it alive and reachable?")

    def _pool(self) -> concurrent.futures.ThreadPoolExecutor:
        if self._executor is None:
            self._executor = concurrent.futures.ThreadPoolExecutor(self.num_nodes, thread_name_prefix="uniros-batch")
        return self._executor

    def _exit_note(self, k: int) -> str:
        process = self.connections[k].process
        code = process.poll() if process is not None else None
        return "" if code is None else f" (its process exited with code {code}; close this vector env)"

    # -- episodes ---------------------------------------------------------------------------------
    def reset_env(self, i: int, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        """Reset env ``i`` alone (its robot and its objects back to their spawn state, then its reset hooks)."""
        self._elapsed[i] = 0
        out = self.envs[i].reset(seed=seed, options=options)
        current = self._current
        if current is not None and not current.put_row(i, self.envs[i].robot_state):  # row i follows the reset
            self._current = None
        return out

    def node_loads(self) -> list[dict[str, Any]]:
        """Each node's ``GetNodeLoad`` answer (robots, physics steps/s, memory)."""
        return [conn.client.get_node_load() for conn in self.connections]

    def close(self) -> None:
        """Close the envs, then the nodes (stopping child processes by PID)."""
        envs, self.envs = self.envs, []
        for env in envs:
            env.close()
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        connections, self.connections = self.connections, []
        for conn in connections:
            conn.close()


BATCH_OPTIONS = ("num_nodes", "spacing", "timeout_sec", "node_name", "connect_kwargs")


def env_creator(env_id: str) -> Any:
    """What the registered Gymnasium ID ``env_id`` builds its env with (the env class, for uniros IDs)."""
    import gymnasium as gym

    entry = gym.spec(env_id).entry_point
    return entry if not isinstance(entry, str) else gym.envs.registration.load_env_creator(entry)


def batchable(creator: Any) -> bool:
    """Whether the envs an ID's ``creator`` (:func:`env_creator`) builds can share a simulation node
    in a batch: it is a :class:`~multiros.envs.sim_env.MujocoEnvCore` class (not a real robot's or another
    library's env). A creator that is a function is only known once it has built an env: ``True``
    here, checked then.
    """
    return not isinstance(creator, type) or issubclass(creator, MujocoEnvCore)


def make_env_batch(env_id: str, num_envs: int, batch_options: Mapping[str, Any] | None = None,
                   **kwargs: Any) -> EnvBatch:
    """The :class:`EnvBatch` of ``num_envs`` envs of the registered Gymnasium ID ``env_id``.

    ``batch_options`` are :class:`EnvBatch`'s (``BATCH_OPTIONS``); ``kwargs`` go to each env
    (``sim_mode`` and ``max_episode_steps`` to the batch: the registration's limit by default).
    """
    import gymnasium as gym

    from multiros.sim.launch import local_description_dirs  # the sim layer's launcher (DESIGN §2)

    options = dict(batch_options or {})
    unknown = sorted(set(options) - set(BATCH_OPTIONS))
    if unknown:
        raise TypeError(f"unknown batched vector env option(s) {unknown}; accepted: {list(BATCH_OPTIONS)} "
                        "and autoreset_mode, copy")
    for key in ("sim_connection", "world_slot", "sim_node_name"):
        if key in kwargs:
            raise TypeError(f"{key!r} is set by the batched vector env itself; do not pass it")
    spec = gym.spec(env_id)
    creator = env_creator(env_id)
    if not batchable(creator):
        raise TypeError(f"a batched vector env needs uniros envs on the simulation node; {env_id} is "
                        f"{creator.__name__}: use vectorization_mode='sync' or 'async' for it")
    sim_mode = kwargs.pop("sim_mode", "composed")
    max_steps = kwargs.pop("max_episode_steps", spec.max_episode_steps)
    env_kwargs = {**spec.kwargs, **kwargs}
    naming = getattr(creator, "entity_name", None)  # an env class that names its robot from its arguments
    base = env_kwargs.pop("robot_name", naming(env_kwargs) if callable(naming) else getattr(creator, "ROBOT_NAME",
                                                                                             "robot"))
    trusted = local_description_dirs(env_kwargs.get("robot_model_xml"), env_kwargs.get("controllers_file"))
    if env_kwargs.get("floor_color") is not None:  # the envs join the batch's nodes: they start with it
        options["connect_kwargs"] = {**dict(options.get("connect_kwargs") or {}),
                                     "floor_color": env_kwargs["floor_color"]}

    def make_env(**batch_kwargs: Any) -> Any:
        return creator(**env_kwargs, **batch_kwargs)

    return EnvBatch(make_env, num_envs, robot_name=base, sim_mode=sim_mode, max_episode_steps=max_steps,
                    trusted_paths=trusted, **options)
