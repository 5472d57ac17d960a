"""A batch of envs whose robots share simulation nodes: one ``StepRobots`` round trip per node per step.

:class:`EnvBatch` holds N ordinary task-env instances (the task logic is written once, in the task
env) spread over K simulation nodes (N/K robots each). Each env spawns its robot in its own
namespace and **world slot**: a spatial offset (a grid, ``spacing`` metres apart) far beyond an
arm's reach, so robots never touch, and frame positions reported relative to the slot, so each env
sees exactly the numbers it would see alone in its own world. A step runs each env's action hook
(its commands become pending), sends one ``uniros_interfaces/srv/StepRobots`` request per node
(all K at once), then hands each env its robot's state for its observation, reward and
termination hooks. A reset puts back only that env's robot (``RobotStep.reset``), never the world.
Where the task env class offers batched step hooks (``batch_step_hooks()``, e.g. the goal reach
tasks', :mod:`rl_environments.reach_batch`), the action and result hooks of all the envs run in one
numpy pass instead of N small ones, with the same results bit for bit.

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
from typing import Any, Protocol

import numpy as np

from multiros.envs.core import EnvError, MujocoEnvCore
from multiros.sim.client import RobotStepOutcome, RobotStepSpec, SimulationNodeError
from multiros.sim.node_stepping import LocalStepRobots
from multiros.sim.state_gather import StackedStates

StepResult = tuple[Any, float, bool, bool, dict]

_OK, _UNSTABLE = 0, 104
_batch_ids = itertools.count()


def slot_offset(index: int, count: int, spacing: float) -> tuple[float, float, float]:
    """World slot ``index`` of ``count``: a square grid in the x-y plane, ``spacing`` metres apart."""
    cols = max(1, math.ceil(math.sqrt(count)))
    return (float(index % cols) * spacing, float(index // cols) * spacing, 0.0)


class BatchStepHooks(Protocol):
    """A task's step hooks for many envs of one class at once (``batch_step_hooks()`` of the env
    class returns one, or ``None``). Each must give every env exactly what its own hooks would."""

    def act(self, envs: Sequence[Any], actions: Sequence[Any]) -> bool:
        """Each env's ``_step_act(action)``; False, changing nothing, to let the envs act one by one."""

    def results(self, envs: Sequence[Any], stacked: StackedStates | None) -> list[StepResult] | None:
        """Each env's ``_step_result()``; ``None`` to let the envs score themselves. ``stacked``, when
        given, holds the states the envs just accepted as rows of one array each (row ``j``: ``envs[j]``)."""


def batch_step_hooks(envs: Sequence[Any]) -> BatchStepHooks | None:
    """The batched step hooks of ``envs`` (all of one class), or ``None`` (each env runs its own)."""
    cls = type(envs[0])
    factory = getattr(cls, "batch_step_hooks", None)
    if factory is None or any(type(env) is not cls for env in envs):
        return None
    return factory()


class EnvBatch:
    """N envs over K simulation nodes, stepped with one ``StepRobots`` request per node.

    Args:
        make_env: ``make_env(**kwargs)`` creates one env (a :class:`~multiros.envs.core.MujocoEnvCore`
            task env); it is called with ``sim_connection``, ``world_slot``, ``robot_name`` and ``seed``.
        num_envs: N, the number of envs (robots).
        robot_name: base of the robots' entity names (each gets ``<base>_<batch>_<i>``, its namespace too).
        sim_mode: ``"composed"`` (one node in this process), ``"process"`` (nodes in child
            processes, each behind its own private Zenoh router) or ``"existing"`` (a running node
            named ``node_name``, shared with other clients; pass ``connect_kwargs={"context": ...}``
            to reach it through a given ROS context).
        num_nodes: K nodes; env ``i`` lives on node ``i * K // N``. Composed nodes share this
            process and step at once on threads (``mj_step`` releases the GIL).
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
        num_nodes: int = 1,
        spacing: float = 2.0,
        timeout_sec: float = 10.0,
        max_episode_steps: int | None = None,
        node_name: str | Sequence[str] = "mujoco_sim",
        trusted_paths: Sequence[str] = (),
        connect_kwargs: Mapping[str, Any] | None = None,
    ) -> None:
        from multiros.sim.launch import connect  # the sim layer's launcher (DESIGN §2)

        names = [node_name] if isinstance(node_name, str) else list(node_name)
        if not isinstance(node_name, str):
            if sim_mode != "existing" or not names:
                raise ValueError("a list of node names needs sim_mode='existing' and at least one name")
            num_nodes = len(names)
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if not isinstance(num_nodes, int) or not 1 <= num_nodes <= num_envs:
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
        self.connections: list[Any] = []
        self.envs: list[Any] = []
        self.hooks: BatchStepHooks | None = None
        self._elapsed = np.zeros(num_envs, dtype=np.int64)
        self._executor: concurrent.futures.ThreadPoolExecutor | None = None
        tag = f"{os.getpid()}x{next(_batch_ids)}"
        try:
            for k in range(num_nodes):
                name = names[k] if sim_mode == "existing" else names[0]
                self.connections.append(connect(sim_mode, node_name=name, timeout_sec=max(self.timeout_sec, 30.0),
                                                 trusted_paths=trusted_paths, **dict(connect_kwargs or {})))
            for k, conn in enumerate(self.connections):
                self._check_capacity(k, conn, self.node_of.count(k))
            for i in range(num_envs):
                k = self.node_of[i]
                members = [j for j in range(num_envs) if self.node_of[j] == k]
                env = make_env(sim_connection=self.connections[k], robot_name=f"{robot_name}_{tag}_{i}",
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
            self.hooks = batch_step_hooks(self.envs)
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

    # -- stepping -----------------------------------------------------------------------------
    def step_envs(self, indices: Sequence[int], actions: Sequence[Any]) -> list[StepResult]:
        """Step envs ``indices`` with ``actions``: one ``StepRobots`` request per node, all nodes at once.

        Every env's action hooks run first (a bad action raises before any node steps). With several
        nodes, their physics runs at once (``mj_step`` releases the GIL): requests to nodes in other
        processes or on other hosts go out on worker threads, and a node's results are handed to its
        envs while the others may still step; composed nodes are called without messages and only
        their physics runs on workers (:meth:`_step_composed`).

        Robots of envs not in ``indices`` stay in the world and advance too (their controllers
        hold their last commands); such envs are about to be reset, which puts back their whole state.
        """
        indices = list(indices)
        self._act(indices, actions)
        groups: dict[int, list[int]] = {}
        for i in indices:
            groups.setdefault(self.node_of[i], []).append(i)
        requests = {k: self._request(members) for k, members in groups.items()}
        if len(requests) == 1:  # one node: no thread
            (k, request), = requests.items()
            outcomes = dict(zip(groups[k], self._finish(groups[k], *self._call(k, request))))
            return [outcomes[i] for i in indices]
        if all(self.connections[k].sim_node is not None for k in requests):
            return self._step_composed(groups, requests, indices)
        pending = {k: self._pool().submit(self._call, k, request) for k, request in requests.items()}
        results: dict[int, StepResult] = {}
        for k, future in pending.items():
            results.update(zip(groups[k], self._finish(groups[k], *self._wait(k, future))))
        return [results[i] for i in indices]

    def _step_composed(self, groups: Mapping[int, Sequence[int]],
                       requests: Mapping[int, Sequence[RobotStepSpec]], indices: Sequence[int]) -> list[StepResult]:
        """Several composed nodes: this thread prepares each node (its lock, resets, commands) and
        hands its physics to a worker before preparing the next, steps the last node itself and reads
        its states (while the workers may still step), then the others'. Only the physics runs on
        the workers, so the nodes' Python never queues behind each other's on the GIL."""
        *others, last = list(requests)
        calls: dict[int, LocalStepRobots] = {}
        futures: dict[int, concurrent.futures.Future] = {}
        done = False
        try:
            for k in [*others, last]:
                calls[k] = LocalStepRobots(self.connections[k].sim_node, requests[k], self.num_sim_steps)
            for k in others:
                calls[k].prepare()
                futures[k] = self._pool().submit(calls[k].advance)
            calls[last].prepare()
            calls[last].advance()
            results: dict[int, StepResult] = {}
            for k in [last, *others]:  # the others' physics may still run meanwhile
                if k in futures:
                    self._wait(k, futures[k])
                outcomes = calls[k].finish()  # sets calls[k].stacked
                results.update(zip(groups[k], self._finish(groups[k], outcomes, calls[k].stacked)))
            done = True
            return [results[i] for i in indices]
        finally:
            if not done:  # an error: let the physics under way end before the nodes' locks are released
                concurrent.futures.wait(list(futures.values()), timeout=self.timeout_sec)
            for call in calls.values():
                call.close()

    def _act(self, indices: Sequence[int], actions: Sequence[Any]) -> None:
        """Run the envs' action hooks (their commands become pending): all at once through the
        task's batched hooks when it has them and takes the batch, else env by env."""
        envs = [self.envs[i] for i in indices]
        if self.hooks is None or not self.hooks.act(envs, actions):
            for env, action in zip(envs, actions):
                env._step_act(action)

    def _request(self, members: Sequence[int]) -> list[RobotStepSpec]:
        """The pending commands of envs ``members``: their robots' parts of a ``StepRobots`` call."""
        specs = []
        for i in members:
            env = self.envs[i]
            commands, env._pending_commands = env._pending_commands, {}
            specs.append(RobotStepSpec(env.robot_name, commands, env.frames))
        return specs

    def _wait(self, k: int, future: concurrent.futures.Future) -> Any:
        """The result of node ``k``'s call (what :meth:`_call` returns, or nothing for a composed node's physics),
        or an error naming the node if its process exits or it does not answer."""
        deadline = time.monotonic() + self.timeout_sec
        process = self.connections[k].process
        while True:
            try:
                return future.result(timeout=0.05)
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

    def _call(self, k: int, specs: Sequence[RobotStepSpec]) -> tuple[list[RobotStepOutcome], StackedStates | None]:
        """One ``StepRobots`` call to node ``k``: its outcomes and, from a composed node (called
        without messages, :class:`~multiros.sim.node_stepping.LocalStepRobots`), the robots' states
        stacked; others' over the service."""
        conn = self.connections[k]
        if conn.sim_node is not None:
            call = LocalStepRobots(conn.sim_node, specs, self.num_sim_steps)
            return call.run(), call.stacked
        client = conn.client
        request = client.step_robots_request(specs, self.num_sim_steps)
        try:
            response = client.step_robots_call(request, self.timeout_sec)
        except SimulationNodeError as exc:
            raise SimulationNodeError(f"simulation node {self._node_label(k)} failed a vector step"
                                      f"{self._exit_note(k)}: {exc}") from exc
        return client.step_robots_outcomes(request, response), None

    def _pool(self) -> concurrent.futures.ThreadPoolExecutor:
        if self._executor is None:
            self._executor = concurrent.futures.ThreadPoolExecutor(self.num_nodes,
                                                                   thread_name_prefix="uniros-batch")
        return self._executor

    def _exit_note(self, k: int) -> str:
        process = self.connections[k].process
        code = process.poll() if process is not None else None
        return "" if code is None else f" (its process exited with code {code}; close this vector env)"

    def _finish(self, members: Sequence[int], outcomes: Sequence[RobotStepOutcome],
                stacked: StackedStates | None = None) -> list[StepResult]:
        """Hand envs ``members`` their robots' states and run their result hooks (all at once through
        the task's batched hooks when it has them, which may read ``stacked``, the states as rows of
        one array each), then apply the batch's episode limit and faults."""
        envs = [self.envs[i] for i in members]
        for i, env, outcome in zip(members, envs, outcomes):
            if outcome.state is None:
                raise EnvError(f"env {i}: robot {outcome.entity!r} is gone from simulation node "
                               f"{self._node_label(self.node_of[i])}: {outcome.message}")
            env._accept_state(outcome.state)
        results = self.hooks.results(envs, stacked) if self.hooks is not None else None
        if results is None:
            results = [env._step_result() for env in envs]
        return [self._end(i, outcome, result) for i, outcome, result in zip(members, outcomes, results)]

    def _end(self, i: int, outcome: RobotStepOutcome, result: StepResult) -> StepResult:
        obs, reward, terminated, truncated, info = result
        self._elapsed[i] += 1
        if self.max_episode_steps is not None and self._elapsed[i] >= self.max_episode_steps:
            truncated = True
        if outcome.status != _OK:
            # This robot alone ends its episode; the vector env's autoreset puts it back.
            truncated = True
            info["sim_error"] = outcome.message
            info["sim_status"] = outcome.status
            if outcome.status == _UNSTABLE:
                info["sim_diverged"] = True
        return obs, reward, bool(terminated), bool(truncated), info

    def reset_env(self, i: int, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        """Reset env ``i`` alone (its robot back to its spawn state, then its reset hooks)."""
        self._elapsed[i] = 0
        return self.envs[i].reset(seed=seed, options=options)

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
    in a batch: it is a :class:`~multiros.envs.core.MujocoEnvCore` class (not a real robot's or another
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
    base = kwargs.pop("robot_name", getattr(creator, "ROBOT_NAME", "robot"))
    env_kwargs = {**spec.kwargs, **kwargs}
    trusted = local_description_dirs(env_kwargs.get("robot_model_xml"), env_kwargs.get("controllers_file"))

    def make_env(**batch_kwargs: Any) -> Any:
        return creator(**env_kwargs, **batch_kwargs)

    return EnvBatch(make_env, num_envs, robot_name=base, sim_mode=sim_mode, max_episode_steps=max_steps,
                    trusted_paths=trusted, **options)
