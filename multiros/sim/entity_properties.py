"""An entity's physical properties set apart from its description: domain randomisation in the node.

A client (an env at reset, :mod:`rl_environments.randomization`) sends rows ``(target, name, property,
value)`` through ``~/set_entity_properties``; the world keeps them with the entity and applies them to
every model it compiles, until a ``restore`` puts the entity back as it was spawned:

=========  ====================================  ==================================================
target     property                              value
=========  ====================================  ==================================================
body       ``mass``                              scale of the body's mass and rotational inertia
joint      ``damping``, ``frictionloss``,        scale of the joint's value (of its degrees of
           ``armature``                          freedom)
geom       ``friction``                          scale of the sliding friction
geom       ``size``                              scale of the geom's size (and bounding radius)
geom       ``brightness``                        scale of its colour (red, green, blue; at most 1)
camera     ``x``, ``y``, ``z``                   metres the camera is moved from where it was spawned
camera     ``fovy``                              scale of its vertical field of view
actuator   ``gain``                              scale of the servo's gains (position and velocity)
command    ``latency``                           seconds from a command to its effect
command    ``jitter``                            seconds: each new command takes effect up to this
                                                 much later still (uniform, seeded)
command    ``time_constant``                     seconds of first-order lag of the joint's target
command    ``gain``, ``offset``                  the target is ``gain * command + offset`` (rad)
command    ``droop``                             rad the joint stops short of that target, on the side
                                                 it came from (a stiff servo under load)
command    ``seed``                              seeds the jitter (an integer, as a float)
=========  ====================================  ==================================================

``name`` is an element of the entity, unprefixed (a link, joint, geom, or an actuated joint for
``actuator`` and ``command``), or empty for every element of that kind. Scales apply to the value the
entity was spawned with, not to the current one: a row sent twice does not compound.

The command rows are :class:`CommandShaping`: how a robot's joints follow their position commands on
a real arm (a delay, a lag, a servo that settles short), modelled between the controllers and the
actuators. Off (no command row), the step path is untouched: nothing of this runs in it.

MuJoCo's own model editing (``MjSpec``) would recompile the world for each change; these are values
of the compiled model that MuJoCo reads at every step, so they are written in place (no recompile, no
state lost), and written again after any recompile (a spawn or delete elsewhere in the world).
"""

from __future__ import annotations

import collections
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from multiros.sim.controllers import JointMode
from multiros.sim.world_types import EntityRecord

__all__ = ["CommandShaping", "EntityProperties", "PropertyError", "PROPERTIES", "MAX_ROWS", "SHAPING_PERIOD",
           "apply_rows", "check_rows", "reapply"]

_POSITION = int(JointMode.POSITION)

#: target -> the properties it takes.
PROPERTIES: dict[str, tuple[str, ...]] = {
    "body": ("mass",),
    "joint": ("damping", "frictionloss", "armature"),
    "geom": ("friction", "size", "brightness"),
    "camera": ("x", "y", "z", "fovy"),
    "actuator": ("gain",),
    "command": ("latency", "jitter", "time_constant", "gain", "offset", "droop", "seed"),
}
#: Seconds between the shaping's updates of a robot whose controllers hold constant commands (the world
#: steps such a robot in chunks of this; time-varying controllers update at their own rate).
SHAPING_PERIOD = 0.01
#: Most rows one request may carry.
MAX_ROWS = 4096
#: Bounds of each value: scales (a factor of 100 either way is no robot) and command values.
_SCALE = (0.01, 100.0)
_SHIFT = (-1.0, 1.0)  # m, a camera moved from where it was spawned
_COMMAND_BOUNDS = {"latency": (0.0, 2.0), "jitter": (0.0, 1.0), "time_constant": (0.0, 5.0), "gain": (0.1, 10.0),
                   "offset": (-math.pi, math.pi), "droop": (0.0, 0.5), "seed": (0.0, 2.0 ** 32 - 1)}
#: Most commands one robot's latency queue holds (a 2 s latency at a 1 kHz controller: 2,000).
_MAX_QUEUE = 4096


class PropertyError(ValueError):
    """A row the entity cannot take (unknown target, property or element, a value out of bounds)."""


class CommandShaping:
    """How an entity's actuated joints follow their position commands: ``gain * u(t - latency) + offset``
    behind a first-order lag, per joint; velocity and effort commands pass unchanged.

    Time is the simulation's: :meth:`shape` may be called any number of times at one time (nothing
    advances); a clock that went back (a reset of time) starts it afresh, as :meth:`clear` does.
    """

    def __init__(self, n: int) -> None:
        self.latency = 0.0
        self.jitter = 0.0
        self.time_constant = np.zeros(n)
        self.gain = np.ones(n)
        self.offset = np.zeros(n)
        self.droop = np.zeros(n)
        self.rng = np.random.default_rng(0)
        self._queue: collections.deque[tuple[float, np.ndarray]] = collections.deque(maxlen=_MAX_QUEUE)
        self._due: np.ndarray | None = None
        self._target: np.ndarray | None = None
        self._last_key = b""
        self._t = -math.inf
        self._alpha, self._alpha_dt = np.ones(n), math.nan
        self._position, self._all_position, self._mode_key = np.zeros(n, dtype=bool), False, b""

    def clear(self) -> None:
        """Forget the commands in flight and the lag's state (a teleport, a reset)."""
        self._queue.clear()
        self._due = self._target = None
        self._last_key = b""
        self._t = -math.inf
        self._alpha_dt = math.nan

    def shape(self, command: np.ndarray, modes: np.ndarray, now: float) -> np.ndarray:
        """The actuators' targets at ``now`` for the controllers' ``command`` (do not keep the array).

        A command that differs from the last one joins a first-in, first-out queue, due ``latency`` (plus
        up to ``jitter``) after it came; the latest due one, through the gain and offset, is the goal the
        target lags toward. Called at every controller update of a shaped robot: kept to a few small numpy
        operations (the lag's factor is cached per interval, the command compared as bytes)."""
        if self._due is None or now < self._t:
            self.clear()
            self._due, self._target, self._t = command.copy(), self.gain * command + self.offset, now
        key = command.tobytes()
        if key != self._last_key:
            delay = self.latency + (float(self.rng.uniform(0.0, self.jitter)) if self.jitter > 0 else 0.0)
            self._queue.append((now + delay, command.copy()))
            self._last_key = key
        queue = self._queue
        while queue and queue[0][0] <= now:
            self._due = queue.popleft()[1]
        target = self._target
        assert target is not None and self._due is not None
        goal = self.gain * self._due + self.offset
        if self.droop.any():  # it heads for the nearest point within droop of the goal, and stays inside
            goal = goal - np.clip(goal - target, -self.droop, self.droop)
        dt = now - self._t
        if dt != self._alpha_dt:
            lag = self.time_constant > 0
            alpha = np.ones_like(goal)
            alpha[lag] = 1.0 - np.exp(-dt / self.time_constant[lag]) if dt > 0 else 0.0
            self._alpha, self._alpha_dt = alpha, dt
        target += self._alpha * (goal - target)
        self._t = now
        mode_key = modes.tobytes()
        if mode_key != self._mode_key:
            self._position, self._all_position, self._mode_key = modes == _POSITION, bool(np.all(modes == _POSITION)), \
                mode_key
        return target if self._all_position else np.where(self._position, target, command)


@dataclass
class EntityProperties:
    """The rows an entity was given (their latest value each), and the spawned values they scale."""

    scales: dict[tuple[str, str, str], float] = field(default_factory=dict)
    shaping: CommandShaping | None = None
    _nominal: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)
    _gains: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # the servo's spawned kp, kd, kv

    def forget_model(self) -> None:
        """A new model was compiled (its values are the spawned ones): the stash goes."""
        self._nominal.clear()

    def restore(self, m: mujoco.MjModel, ent: EntityRecord) -> None:
        """Write the spawned values back and drop every row."""
        for (array, index), value in self._nominal.items():
            getattr(m, array)[index] = value
        if self._gains is not None and ent.hw is not None:
            ent.hw.kp[:], ent.hw.kd[:], ent.hw.kv[:] = self._gains
            ent.hw.dirty = True
        self._nominal.clear()
        self._gains = None
        self.scales.clear()
        self.shaping = None

    def gains(self, ent: EntityRecord) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The servo's spawned gains (kept the first time they are asked for)."""
        assert ent.hw is not None
        if self._gains is None:
            self._gains = (ent.hw.kp.copy(), ent.hw.kd.copy(), ent.hw.kv.copy())
        return self._gains

    def stash(self, m: mujoco.MjModel, array: str, index: int) -> np.ndarray:
        """The spawned value of ``m.<array>[index]`` (kept the first time it is asked for)."""
        key = (array, index)
        if key not in self._nominal:
            self._nominal[key] = np.array(getattr(m, array)[index], copy=True)
        return self._nominal[key]

    def write(self, m: mujoco.MjModel, array: str, index: int, scale: float, part: slice | int | None = None) -> None:
        nominal = self.stash(m, array, index)
        target = getattr(m, array)
        if part is None:
            target[index] = nominal * scale
        else:
            value = nominal.copy()
            value[part] = nominal[part] * scale
            target[index] = value


def check_rows(targets: Sequence[str], names: Sequence[str], properties: Sequence[str],
               values: Sequence[float]) -> list[tuple[str, str, str, float]]:
    """The rows of a request, checked for shape and bounds (not yet against an entity)."""
    n = len(targets)
    if not (len(names) == len(properties) == len(values) == n):
        raise PropertyError(f"targets, names, properties and values must be as long as each other, got {n}, "
                            f"{len(names)}, {len(properties)}, {len(values)}")
    if n > MAX_ROWS:
        raise PropertyError(f"{n} rows; at most {MAX_ROWS} in one request")
    rows = []
    for target, name, prop, value in zip(targets, names, properties, values):
        target, name, prop = str(target), str(name), str(prop)
        if target not in PROPERTIES:
            raise PropertyError(f"target {target[:40]!r} is not one of {list(PROPERTIES)}")
        if prop not in PROPERTIES[target]:
            raise PropertyError(f"{target} has no property {prop[:40]!r}; it has {list(PROPERTIES[target])}")
        value = float(value)
        lo, hi = _COMMAND_BOUNDS[prop] if target == "command" else _SHIFT if prop in ("x", "y", "z") else _SCALE
        if not (math.isfinite(value) and lo <= value <= hi):
            kind = "value" if target == "command" else "shift (m)" if prop in ("x", "y", "z") else "scale"
            raise PropertyError(f"{target} {name[:60]!r} {prop}: {kind} {value!r} is outside [{lo:g}, {hi:g}]")
        if len(name) > 256:
            raise PropertyError(f"{target} name of {len(name)} characters; names are at most 256")
        rows.append((target, name, prop, value))
    return rows


# -- an entity's rows applied to a model ----------------------------------------------------------------
def _elements(m: mujoco.MjModel, ent: EntityRecord, target: str, name: str) -> np.ndarray:
    """Ids of the entity's elements of a kind: one by name, or all of them for an empty name."""
    if target in ("actuator", "command"):
        if not ent.actuated:
            raise PropertyError(f"entity '{ent.name}' has no actuated joints ({target} rows need a robot)")
        if not name:
            return np.arange(len(ent.actuated))
        if name not in ent.actuated:
            raise PropertyError(f"entity '{ent.name}' has no actuated joint {name[:60]!r}")
        return np.array([ent.actuated.index(name)])
    kind = {"body": mujoco.mjtObj.mjOBJ_BODY, "joint": mujoco.mjtObj.mjOBJ_JOINT,
            "geom": mujoco.mjtObj.mjOBJ_GEOM, "camera": mujoco.mjtObj.mjOBJ_CAMERA}[target]
    owner = {"body": None, "joint": m.jnt_bodyid, "geom": m.geom_bodyid, "camera": m.cam_bodyid}[target]
    if name:
        index = mujoco.mj_name2id(m, kind, ent.prefix + name)
        body = index if owner is None else (owner[index] if index >= 0 else -1)
        if index < 0 or body not in ent.body_ids:
            raise PropertyError(f"entity '{ent.name}' has no {target} {name[:60]!r}")
        return np.array([index])
    if owner is None:
        return ent.body_ids[m.body_mass[ent.body_ids] > 0]
    return np.flatnonzero(np.isin(owner, ent.body_ids))


def _write(m: mujoco.MjModel, ent: EntityRecord, props: EntityProperties, row: tuple[str, str, str, float]) -> int:
    target, name, prop, value = row
    ids = _elements(m, ent, target, name)
    if target == "body":
        for b in ids:
            props.write(m, "body_mass", int(b), value)
            props.write(m, "body_inertia", int(b), value)
    elif target == "joint":
        array = {"damping": "dof_damping", "frictionloss": "dof_frictionloss", "armature": "dof_armature"}[prop]
        for j in ids:
            width = {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3}.get(int(m.jnt_type[j]), 1)
            for dof in range(int(m.jnt_dofadr[j]), int(m.jnt_dofadr[j]) + width):
                props.write(m, array, dof, value)
    elif target == "geom":
        for g in ids:
            if prop == "friction":
                props.write(m, "geom_friction", int(g), value, part=0)
            elif prop == "brightness":  # the colour, lighter or darker (red, green and blue kept within 1)
                nominal = props.stash(m, "geom_rgba", int(g))
                m.geom_rgba[g, :3] = np.minimum(nominal[:3] * value, 1.0)
            else:
                props.write(m, "geom_size", int(g), value)
                props.write(m, "geom_rbound", int(g), value)
    elif target == "camera":
        for c in ids:
            if prop == "fovy":
                props.write(m, "cam_fovy", int(c), value)
            else:
                nominal = props.stash(m, "cam_pos", int(c))
                axis = "xyz".index(prop)
                m.cam_pos[c, axis] = nominal[axis] + value
    elif target == "actuator":
        if ent.hw is None:
            raise PropertyError(f"entity '{ent.name}' has no servos (actuator rows need a robot with controllers)")
        kp, kd, kv = props.gains(ent)
        ent.hw.kp[ids], ent.hw.kd[ids], ent.hw.kv[ids] = kp[ids] * value, kd[ids] * value, kv[ids] * value
        ent.hw.dirty = True
    else:
        if props.shaping is None:
            props.shaping = CommandShaping(len(ent.actuated))
        shaping = props.shaping
        if prop == "latency":
            shaping.latency = value
        elif prop == "jitter":
            shaping.jitter = value
        elif prop == "seed":
            shaping.rng = np.random.default_rng(int(value))
        else:
            getattr(shaping, prop)[ids] = value
        shaping.clear()
    return len(ids)


def apply_rows(m: mujoco.MjModel, ent: EntityRecord, rows: Sequence[tuple[str, str, str, float]], *,
               restore: bool = False) -> int:
    """Give the entity these rows (after a ``restore``, first, of its spawned values); the model values
    written. Every row is checked against the entity before any is applied: a bad one changes nothing."""
    for target, name, _prop, _value in rows:
        _elements(m, ent, target, name)
    if ent.properties is None:
        ent.properties = EntityProperties()
    props = ent.properties
    if restore:
        props.restore(m, ent)
    changed = 0
    for row in rows:
        changed += _write(m, ent, props, row)
        props.scales[row[:3]] = row[3]
    ent.shaping = props.shaping
    return changed


def reapply(m: mujoco.MjModel, ent: EntityRecord) -> None:
    """After a recompile (the new model holds the spawned values): the entity's rows written again."""
    props = ent.properties
    if props is None:
        return
    props.forget_model()
    for (target, name, prop), value in props.scales.items():
        if target not in ("actuator", "command"):
            _write(m, ent, props, (target, name, prop, value))
