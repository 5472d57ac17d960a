"""The one env core: hooks, action checks, seeds, info and episodes, over a robot connection.

Every env of the library, simulated or real, plain or goal-conditioned, one alone or one of a
batch, runs its episodes here; what differs lives below, in its
:class:`~multiros.envs.connection.RobotConnection` (:class:`~multiros.envs.sim_env.MujocoEnvCore`
builds a simulation node's, :class:`~multiros.envs.real.core.RealEnvCore` a real robot's), and
above, in its hooks (a task env's MultiROS hooks, or a task written batch-first,
:mod:`multiros.envs.batch_task`).

A step is: :meth:`EnvCore.step_act` (the action checked, the action hook queues or sends
commands), :meth:`EnvCore.step_advance` (the connection steps the robot) and ``step_result``
(observation, reward and episode end from the hooks, :mod:`multiros.envs.base_env`). A vector env
runs the first and the last for each of its envs and advances all their robots in one call per
node.

Hooks (one canonical set; MultiROS and FRobs_RL spellings are accepted, see ``docs/envs.md``):

* robot layer: ``_check_connection_and_readiness()``, ``_set_episode_init_params()``,
  ``_check_if_done()``;
* task layer: ``_set_init_pose()``, ``_set_action(action)``, ``_get_obs()``, ``_check_if_done()``,
  ``_get_reward()`` (plain envs) or ``_compute_reward(achieved_goal, desired_goal, info)`` (goal envs).
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from multiros.envs.connection import RobotConnection, StepStatus
from multiros.envs.errors import EnvError, ResetError
from multiros.robot_state import RobotState

__all__ = ["EnvCore", "EnvError", "ResetError", "hook_name", "call_hook"]

_UNSTABLE = 104


_HOOK_NAMES: dict[tuple[type, type, tuple[str, ...]], str | None] = {}


def hook_name(cls: type, base: type, names: tuple[str, ...]) -> str | None:
    """Which of ``names`` (aliases of one hook) ``cls`` implements below ``base``.

    The most derived class that defines any alias wins, so a task env's MultiROS-named hook is not
    hidden by a robot env's canonically named one; within one class the canonical name wins.
    Classes are immutable for this purpose, so the answer is cached per class.
    """
    key = (cls, base, names)
    try:
        return _HOOK_NAMES[key]
    except KeyError:
        pass
    found = None
    for klass in cls.__mro__:
        if klass is base:
            break
        found = next((name for name in names if name in vars(klass)), None)
        if found is not None:
            break
    _HOOK_NAMES[key] = found
    return found


@functools.lru_cache(maxsize=1024)
def _positional_count(fn: Callable[..., Any]) -> int:
    """How many positional arguments ``fn`` takes (-1: any number)."""
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return -1
    if any(p.kind is p.VAR_POSITIONAL for p in params):
        return -1
    return sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params)


def call_hook(fn: Any, *args: Any) -> Any:
    """Call a hook with as many of ``args`` as its signature takes (MultiROS hooks take ``info``).

    The signature is read once per function (cached), not on every step.
    """
    target = getattr(fn, "__func__", None)
    if target is not None:  # a bound method: its function, less ``self``
        n = _positional_count(target)
        n = n if n < 0 else n - 1
    else:
        n = _positional_count(fn)
    return fn(*args) if n < 0 else fn(*args[:n])


class EnvCore:
    """What every env shares, over ``self.connection`` (see the module docstring).

    Subclasses set ``connection`` in their constructor and the class attributes below.

    Attributes:
        connection: the robot.
        info: the info dict of the current step (hooks add to it).
        out_of_range_action: ``"clip"`` (an action outside a Box action space is clipped into it) or
            ``"error"`` (it raises and nothing is sent: the real envs' default).
    """

    connection: RobotConnection
    info: dict[str, Any]
    robot_name: str
    render_mode: str | None = None
    out_of_range_action: str = "clip"
    #: The exception a refused action raises (a real robot's says nothing was sent).
    action_error: ClassVar[type[Exception]] = ValueError
    #: Whether the core drives a real robot: which construction options apply (a camera's topics or its
    #: place in a world). Behaviour never asks: it is the connection's.
    ON_ROBOT: ClassVar[bool] = False
    #: The concrete template class below which hooks are looked up (set by base_env and real.envs).
    _template: ClassVar[type]
    _pending_seed: int | None = None
    _action_bounds: tuple[Any, np.ndarray, np.ndarray] | None = None

    # -- state access for hooks -----------------------------------------------------------------
    @property
    def robot_state(self) -> RobotState:
        """The robot's state after the last step or reset."""
        return self.connection.state

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of all the robot's joints, in the order of the joint arrays."""
        return self.connection.state.names

    # -- joint arrays by name: all joints, or the ones named, in that order ------------------------
    _joint_index_cache: dict[tuple[tuple[str, ...], tuple[str, ...]], np.ndarray]

    def joint_positions(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Joint positions after the last step or reset (all joints, or ``names`` in that order)."""
        return self._select(self.robot_state.position, names)

    def joint_velocities(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Joint velocities after the last step or reset."""
        return self._select(self.robot_state.velocity, names)

    def joint_efforts(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Joint efforts after the last step or reset."""
        return self._select(self.robot_state.effort, names)

    def _select(self, values: np.ndarray, names: Sequence[str] | None) -> np.ndarray:
        if names is None:
            return values.copy()
        return values[self._joint_indices(names)]

    def _joint_indices(self, names: Sequence[str]) -> np.ndarray:
        """Where the joints ``names`` sit in the joint arrays (EnvError for an unknown joint); cached
        per order of the state's joints."""
        order = self.robot_state.names
        key = (order, tuple(names))
        cache = self.__dict__.get("_joint_index_cache")
        if cache is None:
            cache = self._joint_index_cache = {}
        idx = cache.get(key)
        if idx is None:
            where = {name: i for i, name in enumerate(order)}
            try:
                idx = np.array([where[n] for n in key[1]], dtype=np.intp)
            except KeyError as exc:
                raise EnvError(f"robot {self.robot_name!r} has no joint {exc.args[0]!r}; joints: {order}") from None
            if len(cache) >= 64:  # a few name lists per env; never grow without end
                cache.clear()
            cache[key] = idx
        return idx

    # -- acting ---------------------------------------------------------------------------------
    def send_command(self, controller: str, command: Sequence[float] | np.ndarray) -> None:
        """Command a controller of the robot (a simulated robot takes it with the next step)."""
        self.connection.command(controller, np.asarray(command, dtype=np.float64))

    def move_to_initial_pose(self, names: Sequence[str], positions: npt.ArrayLike, tolerance: float = 1e-3) -> None:
        """Bring joints to an episode's initial pose: a teleport, checked and retried, in simulation;
        a slow move within the safety rules on a robot.

        Raises:
            ResetError: the joints did not reach ``positions`` within ``tolerance``.
        """
        self.connection.move_to_initial_pose(names, positions, tolerance)

    def _check_action(self, action: Any) -> np.ndarray:
        """Refuse NaN/infinite values and wrong shapes; clip a Box action into its bounds (or refuse
        it, with ``out_of_range_action="error"``)."""
        space = self.action_space  # type: ignore[attr-defined]  # gymnasium.Env's, next in the MRO
        if isinstance(space, spaces.Box):
            return self.check_actions(np.asarray(action, dtype=np.float64)[None], single=True)[0]
        if not space.contains(action):
            raise self.action_error(f"action {action!r} is not in the action space {space}{self._nothing_sent}")
        return np.asarray(action)

    @property
    def _nothing_sent(self) -> str:
        return "; nothing was sent" if self.out_of_range_action == "error" else ""

    def check_actions(self, actions: np.ndarray, single: bool = False) -> np.ndarray:
        """``actions`` (a batch, ``(N, *shape)`` float64) checked against this env's Box action space:
        the shape, NaN and infinite values refused, values clipped into the bounds (or refused, with
        ``out_of_range_action="error"``). The one action check of every env, single and batched."""
        low, high = self._box_action_bounds()
        shape = low.shape
        if actions.shape[1:] != shape:
            got = actions.shape[1:] if single else actions.shape
            want = shape if single else (len(actions), *shape)
            raise self.action_error(f"action shape {got} does not match the action space {want}{self._nothing_sent}")
        flat = actions.ravel().tolist()
        if not all(map(math.isfinite, flat)):  # Python floats: a tenth of numpy's time for a few values
            raise self.action_error(f"action {actions[0].tolist() if single else actions.tolist()} contains NaN or "
                                    f"infinite values{self._nothing_sent}")
        if self.out_of_range_action == "error":
            slack = 1e-6 * np.maximum(1.0, np.abs(high - low))
            if np.any(actions < low - slack) or np.any(actions > high + slack):
                raise self.action_error(
                    f"action {np.round(actions[0] if single else actions, 6).tolist()} is outside the action space "
                    f"[{low.tolist()}, {high.tolist()}]; nothing was sent (out_of_range_action='clip' clips instead)")
        return np.minimum(np.maximum(actions, low), high)

    def _box_action_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The Box action space's bounds as float64 arrays (cached per space object)."""
        space = self.action_space  # type: ignore[attr-defined]
        bounds = self._action_bounds
        if bounds is None or bounds[0] is not space:  # the space may be replaced after __init__
            if not isinstance(space, spaces.Box):
                raise EnvError(f"{type(self).__name__}: a batched action check needs a Box action space, got {space}")
            bounds = self._action_bounds = (space, space.low.astype(np.float64), space.high.astype(np.float64))
        return bounds[1], bounds[2]

    # -- the three parts of a step (a vector env runs them for many envs) -------------------------
    def step_act(self, action: Any) -> None:
        """Check the action and run the action hook (its commands are queued or sent)."""
        action = self._check_action(action)
        self.info = {}
        self.connection.before_act()
        self._set_action_hook(self._template, action)

    def step_advance(self) -> None:
        """The connection steps the robot; a step that went wrong says so in ``info``."""
        self.note_step_status(self.connection.advance(self.info))

    def note_step_status(self, status: StepStatus) -> None:
        """Record in ``info`` a step that went wrong (the episode then ends, truncated):
        ``sim_error`` and ``sim_status``; ``sim_diverged`` when physics diverged (the robot was
        restored at rest); ``truncated_reason``."""
        if status.ok:
            return
        info = self.info
        info["sim_error"] = status.message
        info["sim_status"] = status.code
        if status.code == _UNSTABLE:
            info["sim_diverged"] = True
        info.setdefault("truncated_reason", "sim_diverged" if status.code == _UNSTABLE else "sim_error")

    # -- hook dispatch ----------------------------------------------------------------------------
    def _hook(self, base: type, *names: str) -> Any:
        """The bound hook a subclass implements under one of ``names`` (see :func:`hook_name`), or ``None``."""
        name = hook_name(type(self), base, names)
        return None if name is None else getattr(self, name)

    @classmethod
    def _hook_implemented(cls, base: type, *names: str) -> str | None:
        """Which of ``names`` (aliases of one hook) this class implements below ``base``, or ``None``."""
        return hook_name(cls, base, names)

    def _run_reset_hooks(self, base: type, options: dict[str, Any] | None) -> None:
        ready = self._hook(base, "_check_connection_and_readiness", "_check_subs_and_pubs_connection")
        if ready is not None and ready() is False:
            raise EnvError(f"{type(self).__name__}: the robot env reported it is not ready")
        init_pose = self._hook(base, "_set_init_pose")
        if init_pose is not None:
            init_pose()
        init_params = self._hook(base, "_set_episode_init_params")
        if init_params is not None:
            init_params()
        else:
            legacy = self._hook(base, "_set_init_params")
            if legacy is not None:
                legacy(options)

    def _set_action_hook(self, base: type, action: np.ndarray) -> None:
        hook = self._hook(base, "_set_action", "_send_action")
        if hook is None:
            raise NotImplementedError(f"{type(self).__name__} must implement _set_action(action)")
        hook(action)

    # -- episodes ---------------------------------------------------------------------------------
    def _take_seed(self, seed: int | None) -> int | None:
        """The seed of this reset: the one given, else the constructor's ``seed`` for the first reset."""
        if seed is None and self._pending_seed is not None:
            seed = self._pending_seed
        self._pending_seed = None
        return seed

    def _reset_episode(self, options: dict[str, Any] | None) -> None:
        """The episode's start below the observation: the connection's reset, the reset hooks, the first state."""
        self.info = {}
        self.connection.reset(self.info)
        self._run_reset_hooks(self._template, options)
        self.connection.start_episode(self.info)

    # -- closing ------------------------------------------------------------------------------------
    def close(self) -> None:
        """Release the robot connection (a composed node, a child process, a ROS context: whatever it started)."""
        connection = getattr(self, "connection", None)
        if connection is not None:
            connection.close()
