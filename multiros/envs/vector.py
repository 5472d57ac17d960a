"""``BatchedVectorEnv``: a Gymnasium ``VectorEnv`` over an :class:`~multiros.envs.batch.EnvBatch`.

One simulation node (or K of them) holds every sub-env's robot and one ``StepRobots`` request per
node steps them all: one round trip per vector step, not N. Seeds, spaces, autoreset modes,
``reset(options={"reset_mask": ...})`` and the info dicts behave as in Gymnasium's
``SyncVectorEnv``; ``call``/``get_attr``/``set_attr`` reach the sub-envs (``call("compute_reward",
...)`` for HER).

Autoreset (``autoreset_mode``, Gymnasium 1.x): ``NEXT_STEP`` (the default): the step after an
episode ended resets that env, ignores its action and returns its first observation with reward 0
and ``terminated = truncated = False``. ``SAME_STEP``: the env resets in the step that ended its
episode; ``info["final_obs"]`` and ``info["final_info"]`` hold the last observation and info.
``DISABLED``: reset ended envs yourself with ``reset(options={"reset_mask": mask})``.
"""

from __future__ import annotations

from copy import deepcopy
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array, iterate

from multiros.envs.batch import EnvBatch


def autoreset_mode_of(value: AutoresetMode | str) -> AutoresetMode:
    """Gymnasium's ``AutoresetMode`` from itself, its value (``"NextStep"``) or its name (``"NEXT_STEP"``),
    in any case, with or without ``_``.

    Raises:
        ValueError: not one of the modes (the message lists them).
    """
    if isinstance(value, AutoresetMode):
        return value
    if isinstance(value, str):
        key = value.replace("_", "").replace("-", "").lower()
        for mode in AutoresetMode:
            if key in (mode.name.replace("_", "").lower(), mode.value.lower()):
                return mode
    choices = ", ".join(f"{m.name!r}" for m in AutoresetMode)
    raise ValueError(f"autoreset_mode {value!r} is not one of {choices} (gymnasium.vector.AutoresetMode, or its "
                     "name or value as a string)")


class BatchedVectorEnv(VectorEnv):
    """N uniros envs whose robots share simulation nodes, stepped in one request per node.

    Args:
        batch: the envs (see :class:`~multiros.envs.batch.EnvBatch`); closed with this vector env.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (default), ``SAME_STEP`` or ``DISABLED``
            (or their names or values as strings: ``"SAME_STEP"``, ``"SameStep"``).
        copy: return copies of the observations (as ``SyncVectorEnv``).
        observations: arrays to keep the batch's observations in (an array of ``num_envs`` rows for a
            Box space, a dict of them for a Dict of Boxes), e.g. views of shared memory
            (:mod:`multiros.envs.worker_vector`); default: arrays of its own.
    """

    def __init__(self, batch: EnvBatch, *, autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 copy: bool = True, observations: Any = None) -> None:
        self.batch = batch
        self.envs = batch.envs
        self.num_envs = batch.num_envs
        self.autoreset_mode = autoreset_mode_of(autoreset_mode)
        self.copy = copy
        first = self.envs[0]
        self.metadata = dict(first.metadata)
        self.metadata["autoreset_mode"] = self.autoreset_mode
        self.render_mode = first.render_mode
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._observations: Any = create_empty_array(self.single_observation_space, self.num_envs, fn=np.zeros)
        self._env_obs: list[Any] = [None] * self.num_envs
        self._rewards = np.zeros(self.num_envs, dtype=np.float64)
        self._terminations = np.zeros(self.num_envs, dtype=np.bool_)
        self._truncations = np.zeros(self.num_envs, dtype=np.bool_)
        self._autoreset_envs = np.zeros(self.num_envs, dtype=np.bool_)
        # Box and Dict-of-Box observations (every uniros task) are stacked key by key, without
        # gymnasium's generic dispatch: it costs about 5 us per env step at N = 8.
        space = self.single_observation_space
        self._box_keys: tuple[Any, ...] | None = None
        if isinstance(space, spaces.Box):
            self._box_keys = ()
        elif isinstance(space, spaces.Dict) and all(isinstance(s, spaces.Box) for s in space.spaces.values()):
            self._box_keys = tuple(space.spaces)
        if observations is not None:
            self.bind_observations(observations)

    def bind_observations(self, observations: Any) -> None:
        """Keep the batch's observations in ``observations`` from now on (arrays of ``num_envs`` rows:
        one for a Box space, a dict of them for a Dict of Boxes), e.g. views of shared memory.

        Raises:
            ValueError: another space, or arrays of the wrong shape or dtype.
        """
        if self._box_keys is None:
            raise ValueError("observation arrays can be given for a Box or Dict-of-Box space only")
        expected = self._observations
        for key in self._box_keys or (None,):
            got, want = (observations, expected) if key is None else (observations[key], expected[key])
            if got.shape != want.shape or got.dtype != want.dtype:
                raise ValueError(f"observation array {key!r}: shape {got.shape} {got.dtype}, expected "
                                 f"{want.shape} {want.dtype}")
            got[...] = want
        self._observations = observations

    def _put(self, i: int, obs: Any) -> None:
        """Env ``i``'s observation into the batch buffer."""
        keys = self._box_keys
        if keys is None:
            self._env_obs[i] = obs
        elif not keys:
            self._observations[i] = obs
        else:
            out = self._observations
            for key in keys:
                out[key][i] = obs[key]

    def _put_rows(self, rows: list[int], stacked: Any) -> None:
        """Stacked observations (a step's, rows in the order of ``rows``) into the batch buffer at once."""
        keys = self._box_keys
        if keys is None:
            for j, i in enumerate(rows):
                self._env_obs[i] = {k: v[j] for k, v in stacked.items()} if isinstance(stacked, dict) else stacked[j]
            return
        where: Any = slice(None) if len(rows) == self.num_envs else rows  # all envs: one copy per key
        if not keys:
            self._observations[where] = stacked
        else:
            out = self._observations
            for key in keys:
                out[key][where] = stacked[key]

    def _batch_observations(self) -> Any:
        """The batch buffer (copied when ``copy`` is set); other spaces stacked by gymnasium's ``concatenate``."""
        keys = self._box_keys
        if keys is None:
            self._observations = concatenate(self.single_observation_space, self._env_obs, self._observations)
            return deepcopy(self._observations) if self.copy else self._observations
        if not keys:
            return self._observations.copy() if self.copy else self._observations
        out = self._observations
        return {key: out[key].copy() for key in keys} if self.copy else out

    # -- gymnasium API ----------------------------------------------------------------------
    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset every sub-env (or those in ``options["reset_mask"]``); an int seed gives ``seed + i``."""
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, int):
            seeds = [seed + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"{len(seeds)} seeds given for num_envs={self.num_envs}; give one per env or an int")
        options = dict(options) if options else None
        mask = np.ones(self.num_envs, dtype=np.bool_)
        if options is not None and "reset_mask" in options:
            mask = options.pop("reset_mask")
            if not isinstance(mask, np.ndarray) or mask.shape != (self.num_envs,) or mask.dtype != np.bool_:
                raise ValueError(f"options['reset_mask'] must be a bool numpy array of shape ({self.num_envs},)")
            if not mask.any():
                raise ValueError("options['reset_mask'] must hold at least one True value")
        infos: dict[str, Any] = {}
        for i in np.flatnonzero(mask):
            obs, info = self.batch.reset_env(int(i), seeds[i], options)
            self._put(int(i), obs)
            infos = self._add_info(infos, info, int(i))
        self._terminations[mask] = False
        self._truncations[mask] = False
        self._autoreset_envs[mask] = False
        return self._batch_observations(), infos

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every sub-env in one request per node, then reset the ones the autoreset mode says."""
        mode = self.autoreset_mode
        if mode == AutoresetMode.DISABLED and self._autoreset_envs.any():
            ended = np.flatnonzero(self._autoreset_envs).tolist()
            raise RuntimeError(f"envs {ended} ended their episodes and autoreset is disabled: reset them with "
                               "reset(options={'reset_mask': mask}) before stepping")
        acts = self._actions(actions)
        next_step = mode == AutoresetMode.NEXT_STEP
        resetting = self._autoreset_envs.tolist() if next_step else [False] * self.num_envs
        stepping = [i for i, reset in enumerate(resetting) if not reset]
        # Step first, reset after: a reset robot's state is put back whole, so the physics its
        # robot went through in this request does not matter, and it starts its episode unstepped.
        per_env: list[dict[str, Any] | None] = [None] * self.num_envs
        infos: dict[str, Any] = {}
        if stepping:
            if len(stepping) < self.num_envs:
                acts = acts[stepping] if isinstance(acts, np.ndarray) else [acts[i] for i in stepping]
            res = self.batch.step_envs(stepping, acts)
            self._put_rows(stepping, res.obs)
            for j, i in enumerate(stepping):
                per_env[i] = res.infos[j]
            self._rewards[stepping] = res.reward
            self._terminations[stepping] = res.terminated
            self._truncations[stepping] = res.truncated
            if mode == AutoresetMode.SAME_STEP:
                for j, i in enumerate(stepping):
                    if res.terminated[j] or res.truncated[j]:
                        infos = self._add_info(infos, {"final_obs": res.obs_row(j), "final_info": res.infos[j]}, i)
                        obs, per_env[i] = self.batch.reset_env(i)
                        self._put(i, obs)
        for i in (i for i, reset in enumerate(resetting) if reset):
            obs, per_env[i] = self.batch.reset_env(i)
            self._put(i, obs)
            self._rewards[i] = 0.0
            self._terminations[i] = self._truncations[i] = False
        merged = None if infos else _merge_plain_infos(per_env, self.num_envs)
        if merged is not None:
            infos = merged
        else:
            for i, info in enumerate(per_env):
                infos = self._add_info(infos, info or {}, i)
        self._autoreset_envs = np.logical_or(self._terminations, self._truncations)
        obs = self._batch_observations()
        return obs, np.copy(self._rewards), np.copy(self._terminations), np.copy(self._truncations), infos

    def _actions(self, actions: Any) -> Any:
        """The batch of actions as one array per env row (a Box space's), or gymnasium's iteration.

        Raises:
            ValueError: not one action per sub-env, or of the wrong shape.
        """
        space = self.single_action_space
        if isinstance(space, spaces.Box):
            arr = np.asarray(actions)
            if arr.shape != (self.num_envs, *space.shape):
                raise ValueError(f"actions of shape {arr.shape} for {self.num_envs} envs with action space "
                                 f"{space.shape}: give an array of shape {(self.num_envs, *space.shape)}")
            return arr
        acts = list(iterate(self.action_space, actions))
        if len(acts) != self.num_envs:
            raise ValueError(f"{len(acts)} actions for {self.num_envs} envs")
        return acts

    # -- sub-env access ---------------------------------------------------------------------
    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call a method of every sub-env (or read an attribute) and return the results in order."""
        out = []
        for env in self.envs:
            value = getattr(env, name)
            out.append(value(*args, **kwargs) if callable(value) else value)
        return tuple(out)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """An attribute of every sub-env."""
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """Set an attribute of every sub-env (one value for all, or one per env)."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"{len(values)} values for num_envs={self.num_envs}")
        for env, value in zip(self.envs, values):
            setattr(env, name, value)

    def render(self) -> tuple[Any, ...] | None:
        """Each sub-env's render (the images show the whole shared world, from each env's camera)."""
        return self.call("render")

    def node_loads(self) -> list[dict[str, Any]]:
        """Each simulation node's load (see ``GetNodeLoad``)."""
        return self.batch.node_loads()

    def close_extras(self, **kwargs: Any) -> None:
        self.batch.close()


_PLAIN_TYPES = (bool, int, float)


def _merge_plain_infos(per_env: list[dict[str, Any] | None], num_envs: int) -> dict[str, Any] | None:
    """The vector info of the sub-envs' infos, as ``VectorEnv._add_info`` env by env makes it
    (same keys in the same order, same arrays and masks), when every value is a Python bool, int or
    float or a numpy number (a step's usual ``is_success``); ``None`` for any other info.

    ``_add_info`` costs about 1.5 us per env step at N = 8; this builds each key's arrays once.
    """
    columns: dict[str, tuple[list[int], list[Any]]] = {}
    for i, info in enumerate(per_env):
        if not info:
            continue
        for key, value in info.items():
            kind = type(value)
            if key == "final_obs" or not (kind in _PLAIN_TYPES or issubclass(kind, np.number)):
                return None
            column = columns.get(key)
            if column is None:
                column = columns[key] = ([], [])
            column[0].append(i)
            column[1].append(value)
    infos: dict[str, Any] = {}
    for key, (rows, values) in columns.items():
        kind = type(values[0])  # the array's type is the first env's, as _add_info makes it
        if len(rows) == num_envs and all(type(value) is kind for value in values):
            array, mask = np.array(values, dtype=kind), np.ones(num_envs, dtype=np.bool_)
        else:  # value by value, converted into the first one's type as _add_info converts them
            array, mask = np.zeros(num_envs, dtype=kind), np.zeros(num_envs, dtype=np.bool_)
            for row, value in zip(rows, values):
                array[row] = value
            mask[rows] = True
        infos[key], infos[f"_{key}"] = array, mask
    return infos
