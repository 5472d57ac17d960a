"""Stable-Baselines3 ``VecEnv`` over a batch of uniros envs sharing simulation nodes.

:class:`BatchedVecEnv` follows SB3's ``DummyVecEnv`` conventions (an ended env resets in the same
step; ``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]``; seeds and
options given by :meth:`seed`/``set_options`` apply at the next :meth:`reset`), while one
``StepRobots`` request per node steps every robot. ``env_method("compute_reward", ...)`` reaches
the sub-envs, so SB3's ``HerReplayBuffer`` works with it.

:class:`WorkerVecEnv` is the same contract over a
:class:`~multiros.envs.worker_vector.WorkerVectorEnv` (a share of the envs per core: this process's and
worker processes', through shared memory), what :func:`make_batched_vec_env` builds by default.

    from uniros.vec_env import make_batched_vec_env
    venv = make_batched_vec_env("RX200ReacherGoalSim-v0", n_envs=8)          # a share per core
    venv = make_batched_vec_env("RX200ReacherGoalSim-v0", 8, workers=0)      # one node, this process
    venv = make_batched_vec_env("RX200ReacherGoalSim-v0", 8, sim_mode="process", num_nodes=2)
"""

from __future__ import annotations

from collections.abc import Sequence
from copy import deepcopy
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn
from stable_baselines3.common.vec_env.util import obs_space_info

from multiros.envs.batch import EnvBatch


class BatchedVecEnv(VecEnv):
    """SB3 ``VecEnv`` over an :class:`~multiros.envs.batch.EnvBatch` (closed with it)."""

    def __init__(self, batch: EnvBatch) -> None:
        self.batch = batch
        self.envs = batch.envs
        first = self.envs[0]
        super().__init__(batch.num_envs, first.observation_space, first.action_space)
        self.keys, shapes, dtypes = obs_space_info(self.observation_space)
        self.buf_obs = {k: np.zeros((self.num_envs, *tuple(shapes[k])), dtype=dtypes[k]) for k in self.keys}
        self.buf_rews = np.zeros(self.num_envs, dtype=np.float32)
        self.buf_dones = np.zeros(self.num_envs, dtype=bool)
        self.buf_infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        self.actions: np.ndarray | None = None
        self.metadata = first.metadata
        self.render_mode = first.render_mode

    def _save_obs(self, i: int, obs: Any) -> None:
        for key in self.keys:
            self.buf_obs[key][i] = obs if key is None else obs[key]

    def _obs_from_buf(self) -> VecEnvObs:
        if self.keys == [None]:
            return np.copy(self.buf_obs[None])
        return {k: np.copy(v) for k, v in self.buf_obs.items()}

    def reset(self) -> VecEnvObs:
        for i in range(self.num_envs):
            options = self._options[i] or None
            obs, self.reset_infos[i] = self.batch.reset_env(i, self._seeds[i], options)
            self._save_obs(i, obs)
        self._reset_seeds()
        self._reset_options()
        return self._obs_from_buf()

    def step_async(self, actions: np.ndarray) -> None:
        self.actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self.actions is None:
            raise RuntimeError("step_wait() called without step_async(actions)")
        res = self.batch.step_envs(range(self.num_envs), self.actions)
        for i in range(self.num_envs):
            info = res.infos[i]
            truncated, terminated = bool(res.truncated[i]), bool(res.terminated[i])
            self.buf_rews[i] = res.reward[i]
            self.buf_dones[i] = terminated or truncated
            info["TimeLimit.truncated"] = truncated and not terminated
            obs = res.obs_row(i)
            if self.buf_dones[i]:
                info["terminal_observation"] = {k: np.copy(v) for k, v in obs.items()} if isinstance(
                    obs, dict) else np.copy(obs)
                obs, self.reset_infos[i] = self.batch.reset_env(i)
            self.buf_infos[i] = info
            self._save_obs(i, obs)
        self.actions = None
        return self._obs_from_buf(), np.copy(self.buf_rews), np.copy(self.buf_dones), deepcopy(self.buf_infos)

    def close(self) -> None:
        self.batch.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [env.render() for env in self.envs]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self.envs[i], attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for i in self._get_indices(indices):
            setattr(self.envs[i], attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        return [getattr(self.envs[i], method_name)(*method_args, **method_kwargs) for i in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        # The sub-envs are bare uniros envs (the batch applies the time limit itself).
        return [False for _ in self._get_indices(indices)]

    def node_loads(self) -> list[dict[str, Any]]:
        """Each simulation node's load (see ``GetNodeLoad``)."""
        return self.batch.node_loads()


class WorkerVecEnv(VecEnv):
    """SB3 ``VecEnv`` over a :class:`~multiros.envs.worker_vector.WorkerVectorEnv` (SAME_STEP autoreset),
    with :class:`BatchedVecEnv`'s conventions; closed with it."""

    def __init__(self, venv: Any) -> None:
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self.actions: np.ndarray | None = None
        self.metadata = venv.metadata
        self.render_mode = venv.render_mode
        self.max_episode_steps: int | None = venv.max_episode_steps

    @property
    def pids(self) -> list[int]:
        """The worker processes' PIDs."""
        return list(self.venv.pids)

    def reset(self) -> VecEnvObs:
        options = [o or None for o in self._options]
        if any(o != options[0] for o in options):
            raise ValueError("envs in worker processes take one set of reset options for all: "
                             f"set_options() gave {options}")
        obs, infos = self.venv.reset(seed=list(self._seeds), options=options[0])
        self.reset_infos = split_infos(infos, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self.actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self.actions is None:
            raise RuntimeError("step_wait() called without step_async(actions)")
        obs, rewards, terminated, truncated, infos = self.venv.step(np.asarray(self.actions).reshape(
            self.num_envs, *self.action_space.shape))
        self.actions = None
        dones = terminated | truncated
        current = split_infos(infos, self.num_envs)
        ended = np.flatnonzero(dones)
        final_infos = split_infos(infos.get("final_info", {}), self.num_envs) if len(ended) else []
        final_obs = infos.get("final_obs")
        out: list[dict[str, Any]] = []
        for i in range(self.num_envs):
            if dones[i]:
                info = final_infos[i]
                info["terminal_observation"] = final_obs[i]
                self.reset_infos[i] = current[i]
            else:
                info = current[i]
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            out.append(info)
        return obs, rewards.astype(np.float32), dones, out

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return list(self.venv.call("render"))

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return self.venv.call_at(self._get_indices(indices), "__getattribute__", attr_name)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        indices = list(self._get_indices(indices))
        self.venv.set_attr_at(indices, attr_name, [value] * len(indices))

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        return self.venv.call_at(self._get_indices(indices), method_name, *method_args, **method_kwargs)

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def node_loads(self) -> list[dict[str, Any]]:
        """Each simulation node's load (see ``GetNodeLoad``)."""
        return self.venv.node_loads()


def split_infos(infos: dict[str, Any], num_envs: int) -> list[dict[str, Any]]:
    """Gymnasium's vector info (arrays with ``_key`` masks) as one dict per env, as each env returned it."""
    out: list[dict[str, Any]] = [{} for _ in range(num_envs)]
    for key, value in infos.items():
        mask = infos.get(f"_{key}")
        if mask is None or key in ("final_obs", "final_info"):
            continue
        nested = split_infos(value, num_envs) if isinstance(value, dict) else None
        for i in np.flatnonzero(mask):
            out[i][key] = nested[i] if nested is not None else value[i]
    return out


def make_batched_vec_env(env_id: str, n_envs: int = 1, *, sim_mode: str = "composed", num_nodes: int | None = None,
                         spacing: float = 2.0, timeout_sec: float = 10.0, workers: int | None = None,
                         pin_workers: bool = False, **env_kwargs: Any) -> VecEnv:
    """An SB3 ``VecEnv`` of ``n_envs`` envs ``env_id``.

    By default (``workers=None``) a share of the envs per core (at most one per env; a composed node
    each): this process steps one and a worker process each of the others, actions and observations
    through shared memory (:class:`WorkerVecEnv`); or all in this
    process (:class:`BatchedVecEnv`) where that is one core, with ``workers=0``, with ``num_nodes``
    (composed nodes in this process, stepped on threads) or with ``sim_mode="existing"``.
    ``sim_mode="process"``: ``num_nodes`` nodes (default: one per core) in as many child processes,
    each stepping its envs beside its node, through the same shared memory; ``workers=0`` puts the
    envs here and calls each node over its private Zenoh router instead. ``env_kwargs`` go to each env
    (``reward_type``, ``max_episode_steps``, ...). ``pin_workers=True`` pins each worker process to a core
    of its own (for a machine the run has to itself; no effect without workers).
    """
    from multiros.envs.worker_layout import default_layout, pin_option
    from multiros.envs.worker_vector import WorkerVectorEnv
    from uniros.factory import make, make_batch

    pin = pin_option(pin_workers)
    options: dict[str, Any] = {"spacing": spacing, "timeout_sec": timeout_sec}
    if num_nodes is not None:
        options["num_nodes"] = num_nodes
    in_parent = False
    if workers is None:
        workers, in_parent = default_layout(n_envs, sim_mode, options, env_kwargs)
    if workers >= 1:
        if env_id not in gym.registry:
            make(env_id)  # raises the helpful error
        from gymnasium.vector import AutoresetMode

        return WorkerVecEnv(WorkerVectorEnv(env_id, n_envs, workers=workers, in_parent=in_parent,
                                            autoreset_mode=AutoresetMode.SAME_STEP, batch_options=options,
                                            env_kwargs={**env_kwargs, "sim_mode": sim_mode},
                                            pin_workers=pin))
    options.setdefault("num_nodes", 1)
    batch = make_batch(env_id, n_envs, options, sim_mode=sim_mode, **env_kwargs)
    return BatchedVecEnv(batch)
