"""Several envs behind one: UniROS' concurrent training (simulated and real robots, one agent).

:class:`MultiTaskEnv` holds several envs and runs one of them per episode (picked at ``reset``:
at random with the env's seed, round-robin, or with weights). When their spaces differ, observations
and actions are zero-padded to the largest size; a sub-env uses the first entries of an action and
ignores the rest. Every ``info`` carries ``info["task_id"]``, the index of the env that produced it.

:class:`MultiTaskGoalEnv` does the same for goal envs and routes the vectorised
``compute_reward`` / ``compute_terminated`` / ``compute_truncated`` of a HER batch, sample by
sample, to the sub-env each sample came from. The task id must therefore reach HER's stored
samples. SB3's ``HerReplayBuffer`` calls ``env.compute_reward(achieved, desired, infos)`` with
empty ``infos`` unless it was built with ``copy_info_dict=True``, so by default the task id also
travels as the **last entry of ``achieved_goal`` and ``desired_goal``**: HER relabels a desired
goal with an achieved goal of the same episode, hence of the same task, so the entry survives
relabelling. Routing uses ``info["task_id"]`` when the infos carry it, else that goal entry.
``task_id_in_goal=False`` keeps the goals as the sub-envs define them (UniROS' layout); HER then
needs the infos (``replay_buffer_kwargs={"copy_info_dict": True}`` in SB3), and a batch without
task ids raises an error that says so.

::

    import uniros
    env = uniros.MultiTaskGoalEnv(["RX200ReacherGoalSim-v0", "RX200ReacherGoalReal-v0"])
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium_robotics.core import GoalEnv

__all__ = ["MultiTaskEnv", "MultiTaskGoalEnv", "TASK_ID_KEY"]

#: The info key naming the sub-env of a step (UniROS' name).
TASK_ID_KEY = "task_id"
_SELECTIONS = ("random", "round_robin")
_GOAL_KEYS = ("observation", "achieved_goal", "desired_goal")

EnvSource = str | gym.Env | Callable[[], gym.Env]


def _union_box(boxes: Sequence[spaces.Box], what: str, extra: tuple[float, float] | None = None) -> spaces.Box:
    """The smallest Box holding every box's values zero-padded to the largest size (plus an
    ``extra`` trailing entry with these bounds)."""
    for box in boxes:
        if not isinstance(box, spaces.Box) or len(box.shape) != 1:
            raise TypeError(f"MultiTaskEnv pads flat Box spaces only; a sub-env's {what} space is {box}")
    if extra is None and all(b == boxes[0] for b in boxes[1:]):
        return boxes[0]
    size = max(b.shape[0] for b in boxes)
    dtype = np.result_type(*[b.dtype for b in boxes])
    low = np.full(size, np.inf)
    high = np.full(size, -np.inf)
    for b in boxes:
        n = b.shape[0]
        low[:n] = np.minimum(low[:n], b.low)
        high[:n] = np.maximum(high[:n], b.high)
        if n < size:  # zeros fill the rest for this env
            low[n:] = np.minimum(low[n:], 0.0)
            high[n:] = np.maximum(high[n:], 0.0)
    if extra is not None:
        low, high = np.append(low, extra[0]), np.append(high, extra[1])
    return spaces.Box(low.astype(dtype), high.astype(dtype), dtype=dtype)


def _pad(values: Any, size: int, dtype: Any, tail: float | None = None) -> np.ndarray:
    arr = np.asarray(values, dtype=dtype).reshape(-1)
    out = np.zeros(size, dtype=dtype)
    out[: arr.shape[0]] = arr
    if tail is not None:
        out[-1] = tail
    return out


class MultiTaskEnv(gym.Env):
    """Several envs, one per episode, behind one observation and action space.

    Args:
        envs: env IDs (made with :func:`uniros.make`), env instances, or callables returning envs.
            All of them are closed by :meth:`close`.
        env_kwargs: keyword arguments per env ID (one mapping per entry of ``envs``; ignored for
            instances).
        selection: ``"random"`` (with the env's ``np_random``, seeded by ``reset(seed=...)``) or
            ``"round_robin"`` (a seeded reset restarts the cycle at env 0, for reproducibility).
        weights: probabilities of the envs for ``"random"`` (normalised; default uniform).
        names: a name per env (default: its ID or class name), in ``info["task_name"]``.

    ``reset(options={"task_id": k})`` runs env ``k`` for that episode; other options go to the env.

    Raises:
        ValueError: no envs, an unknown selection, bad weights, mismatched ``env_kwargs``.
        TypeError: a space that cannot be padded (not a flat Box, or a Dict of them for goal envs).
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, envs: Sequence[EnvSource], env_kwargs: Sequence[Mapping[str, Any]] | None = None, *,
                 selection: str = "random", weights: Sequence[float] | None = None,
                 names: Sequence[str] | None = None) -> None:
        if not envs:
            raise ValueError("MultiTaskEnv needs at least one env (an ID, an instance or a callable)")
        if selection not in _SELECTIONS:
            raise ValueError(f"selection {selection!r} is not one of {_SELECTIONS}")
        if env_kwargs is not None and len(env_kwargs) != len(envs):
            raise ValueError(f"env_kwargs has {len(env_kwargs)} entries for {len(envs)} envs; give one per env")
        if names is not None and len(names) != len(envs):
            raise ValueError(f"names has {len(names)} entries for {len(envs)} envs")
        self.selection = selection
        self._weights = self._check_weights(weights, len(envs))
        self.envs: list[gym.Env] = []
        try:
            for i, source in enumerate(envs):
                self.envs.append(self._make(source, (env_kwargs or [{}] * len(envs))[i]))
        except BaseException:
            self.close()
            raise
        self.names = list(names) if names is not None else [
            src if isinstance(src, str) else type(env.unwrapped).__name__ for src, env in zip(envs, self.envs)]
        self.num_tasks = len(self.envs)
        self.task_id: int | None = None
        self._next_round_robin = 0
        self._closed = False
        try:
            self._build_spaces()
        except BaseException:
            self.close()
            raise

    # -- construction ------------------------------------------------------------------------
    @staticmethod
    def _check_weights(weights: Sequence[float] | None, n: int) -> np.ndarray | None:
        if weights is None:
            return None
        w = np.asarray(weights, dtype=float)
        if w.shape != (n,) or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
            raise ValueError(f"weights {list(weights)} must be {n} finite numbers >= 0 with a positive sum")
        return w / w.sum()

    @staticmethod
    def _make(source: EnvSource, kwargs: Mapping[str, Any]) -> gym.Env:
        if isinstance(source, str):
            from uniros.factory import make

            return make(source, **dict(kwargs))
        if isinstance(source, gym.Env):
            return source
        if callable(source):
            env = source()
            if not isinstance(env, gym.Env):
                raise TypeError(f"the env factory {source!r} returned {type(env).__name__}, not a gymnasium.Env")
            return env
        raise TypeError(f"an env must be an ID, a gymnasium.Env or a callable returning one, not {source!r}")

    def _build_spaces(self) -> None:
        self._obs_sizes = [e.observation_space.shape[0] if isinstance(e.observation_space, spaces.Box) else None
                           for e in self.envs]
        self.observation_space = _union_box([e.observation_space for e in self.envs], "observation")
        self._build_action_space()

    def _build_action_space(self) -> None:
        boxes = [e.action_space for e in self.envs]
        self.action_space = _union_box(boxes, "action")
        self._action_sizes = [b.shape[0] for b in boxes]

    # -- gymnasium API -----------------------------------------------------------------------
    @property
    def env(self) -> gym.Env:
        """The env running the current episode."""
        if self.task_id is None:
            raise RuntimeError("MultiTaskEnv: call reset() before step()")
        return self.envs[self.task_id]

    def _pick(self, options: dict[str, Any]) -> int:
        if TASK_ID_KEY in options:
            k = options.pop(TASK_ID_KEY)
            if not isinstance(k, (int, np.integer)) or not 0 <= int(k) < self.num_tasks:
                raise ValueError(f"options['task_id'] = {k!r} is not an env index in 0..{self.num_tasks - 1}")
            return int(k)
        if self.selection == "round_robin":
            k = self._next_round_robin
            self._next_round_robin = (k + 1) % self.num_tasks
            return k
        return int(self.np_random.choice(self.num_tasks, p=self._weights))

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        super().reset(seed=seed)
        if seed is not None:
            self._next_round_robin = 0
        options = dict(options or {})
        self.task_id = self._pick(options)
        # A seeded reset seeds the chosen env too (its own stream, derived from the seed).
        sub_seed = None if seed is None else int(np.random.SeedSequence([seed, self.task_id]).generate_state(1)[0])
        obs, info = self.env.reset(seed=sub_seed, options=options or None)
        return self._obs(obs), self._info(info)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        env = self.env
        n = self._action_sizes[self.task_id]
        sub_action = np.asarray(action, dtype=env.action_space.dtype).reshape(-1)[:n]
        sub_action = np.clip(sub_action, env.action_space.low, env.action_space.high)
        obs, reward, terminated, truncated, info = env.step(sub_action)
        return self._obs(obs), float(reward), bool(terminated), bool(truncated), self._info(info)

    def _obs(self, obs: Any) -> Any:
        return _pad(obs, self.observation_space.shape[0], self.observation_space.dtype)

    def _info(self, info: dict) -> dict:
        info = dict(info)
        info[TASK_ID_KEY] = self.task_id
        info["task_name"] = self.names[self.task_id]
        return info

    def render(self) -> Any:
        return self.env.render() if self.task_id is not None else None

    def close(self) -> None:
        """Close every env (each once; errors are raised after all were tried)."""
        if getattr(self, "_closed", False):
            return
        self._closed = True
        errors = []
        for env in getattr(self, "envs", []):
            try:
                env.close()
            except Exception as exc:  # noqa: BLE001 - close the others first
                errors.append(exc)
        if errors:
            raise RuntimeError(f"MultiTaskEnv.close: {len(errors)} env(s) failed to close: {errors}") from errors[0]

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.names} selection={self.selection}>"


class MultiTaskGoalEnv(MultiTaskEnv, GoalEnv):
    """:class:`MultiTaskEnv` for goal envs (Dict observations, HER-style ``compute_reward``).

    Args:
        task_id_in_goal: append the task id to ``achieved_goal`` and ``desired_goal`` so that HER
            batches route without infos (default; see the module docs). ``False``: route by
            ``info["task_id"]`` only.
        Others: as :class:`MultiTaskEnv`.
    """

    def __init__(self, envs: Sequence[EnvSource], env_kwargs: Sequence[Mapping[str, Any]] | None = None, *,
                 selection: str = "random", weights: Sequence[float] | None = None,
                 names: Sequence[str] | None = None, task_id_in_goal: bool = True) -> None:
        self.task_id_in_goal = bool(task_id_in_goal)
        super().__init__(envs, env_kwargs, selection=selection, weights=weights, names=names)

    def _build_spaces(self) -> None:
        subs = [e.observation_space for e in self.envs]
        for env, space in zip(self.envs, subs):
            if not isinstance(space, spaces.Dict) or set(space.spaces) != set(_GOAL_KEYS):
                raise TypeError(f"MultiTaskGoalEnv needs goal envs (Dict spaces with {_GOAL_KEYS}); "
                                f"{type(env.unwrapped).__name__} has {space}")
        extra = (0.0, float(self.num_tasks - 1)) if self.task_id_in_goal else None
        self.observation_space = spaces.Dict({
            key: _union_box([s[key] for s in subs], key, extra if key != "observation" else None)
            for key in _GOAL_KEYS
        })
        self._sizes = {key: [s[key].shape[0] for s in subs] for key in _GOAL_KEYS}
        self._build_action_space()

    def _obs(self, obs: Any) -> dict[str, np.ndarray]:
        out = {}
        for key in _GOAL_KEYS:
            space = self.observation_space[key]
            tail = float(self.task_id) if self.task_id_in_goal and key != "observation" else None
            out[key] = _pad(obs[key], space.shape[0], space.dtype, tail)
        return out

    # -- HER: route each sample to its env --------------------------------------------------------
    def _task_ids(self, achieved: np.ndarray, info: Any, n: int) -> np.ndarray:
        infos = [info] if isinstance(info, Mapping) else (list(info) if info is not None else [])
        ids = [i.get(TASK_ID_KEY) if isinstance(i, Mapping) else None for i in infos]
        if len(ids) == n and all(k is not None for k in ids):
            out = np.asarray(ids, dtype=np.int64)
        elif self.task_id_in_goal:
            out = np.rint(achieved[:, -1]).astype(np.int64)
        else:
            raise ValueError(
                "MultiTaskGoalEnv.compute_reward: the infos carry no 'task_id', so the samples cannot be routed "
                "to their envs. With SB3's HerReplayBuffer pass replay_buffer_kwargs={'copy_info_dict': True}, "
                "or build the env with task_id_in_goal=True")
        if np.any(out < 0) or np.any(out >= self.num_tasks):
            raise ValueError(f"task ids {sorted(set(out.tolist()))} are not env indices in 0..{self.num_tasks - 1}")
        return out

    def _route(self, method: str, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        achieved = np.asarray(achieved_goal)
        desired = np.asarray(desired_goal)
        single = achieved.ndim == 1
        ag, dg = np.atleast_2d(achieved), np.atleast_2d(desired)
        n = ag.shape[0]
        ids = self._task_ids(ag, info, n)
        infos = None if isinstance(info, Mapping) or info is None else list(info)
        result: np.ndarray | None = None
        for k in np.unique(ids):
            rows = np.nonzero(ids == k)[0]
            size = self._sizes["achieved_goal"][k]
            sub_info = info if infos is None else [infos[i] for i in rows]
            fn = self.envs[k].get_wrapper_attr(method)
            if single:
                value = fn(ag[0, :size], dg[0, :size], sub_info if infos is None else sub_info[0])
                return value
            value = np.asarray(fn(ag[rows, :size], dg[rows, :size], sub_info)).reshape(-1)
            if result is None:
                result = np.zeros(n, dtype=value.dtype if method != "compute_reward" else np.float64)
            result[rows] = value
        return result

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """Each sample's reward from the env it came from (vectorised over a leading batch axis)."""
        return self._route("compute_reward", achieved_goal, desired_goal, info)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return self._route("compute_terminated", achieved_goal, desired_goal, info)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        return self._route("compute_truncated", achieved_goal, desired_goal, info)
