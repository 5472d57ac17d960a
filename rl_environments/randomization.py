"""Domain randomisation of the arm envs: a ``randomization:`` mapping drawn afresh at every reset.

Give it as the env option ``randomization`` (``uniros.make(ID, randomization={...})``, or a training
config's ``env_kwargs``; the shipped ones are ``config/training/sim2real/``). Every key is optional; a
range is ``[low, high]`` (uniform) or one number (fixed). docs/sim_to_real.md lists them:

physics (scales of the values the description gives)
    ``link_mass``, ``joint_damping``, ``joint_friction`` (friction loss), ``joint_armature``,
    ``actuator_gain`` (the servos' gains); with an object: ``object_mass``, ``object_friction``,
    ``object_size``, ``table_friction``.
timing
    ``action_latency``: ``[low, high]`` whole control periods a command waits before it acts (added to
    the arm file's ``dynamics.latency``); ``control_jitter``: fraction of a control period each command
    may come later still; ``lag``: seconds of first-order lag of the joints (default the arm file's
    ``dynamics.time_constant``); ``command_offset`` (rad): each arm joint settles up to this far from its
    target, drawn per episode in ``[-v, v]`` (a servo drooping under load; added to ``dynamics.offset``);
    ``droop`` (rad, ``[low, high]``): each arm joint's dead band, drawn per episode: the joint stops that
    far short of its target on the side it came from, and a command within it of where the joint stands
    does not move it (a stiff servo under load, or stiction: the fake robot's ``droop``; added to
    ``dynamics.droop``).
sensing
    ``joint_noise`` (rad, standard deviation per reading), ``joint_offset`` (rad: each arm joint's
    calibration error, drawn per episode in ``[-v, v]``), ``object_position_noise`` (m, standard
    deviation of the tracker's reading of the object), ``object_position_latency`` (s, ``[low, high]``:
    how old the tracker's reading of the object is, drawn per episode).
cameras and colours (pixel observations)
    ``camera_position`` (m: the observation camera moved up to this far along each axis, per episode),
    ``camera_fovy`` (scale of its field of view), ``colour`` (each of the robot's, the object's and the
    table's colours lighter or darker by up to this fraction, per episode). The lights are the world's,
    not an entity's, and stay as they are.

The arm file's ``dynamics:`` (``uniros sysid`` writes it) is the centre: with no ``randomization`` the
simulated joints follow commands as it says, every episode. Physics and timing are values of the
simulation node's world the env sets at reset (:mod:`multiros.sim.entity_properties`: the node applies
them in its step, for one env and a batch alike); sensing is applied where the node's state enters the env
(:mod:`multiros.envs.sensing`). The draws come from a generator of their own, seeded from the env's seed:
a seeded env draws the same worlds, and randomisation does not change the task's own random stream.
On a Real env the option is ignored (with a warning): the robot's gap is real.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rl_environments.arm import Arm

__all__ = ["Randomization", "RandomizationError", "RANDOMIZATION_KEYS"]

#: Scales of physics values (a factor the description's value is multiplied by).
_SCALES = ("link_mass", "joint_damping", "joint_friction", "joint_armature", "actuator_gain", "object_mass",
           "object_friction", "object_size", "table_friction")
#: Every key, with its unit (for errors and docs).
RANDOMIZATION_KEYS: dict[str, str] = {
    **dict.fromkeys(_SCALES, "scale"),
    "action_latency": "control periods", "control_jitter": "fraction of a control period", "lag": "s",
    "command_offset": "rad", "droop": "rad", "camera_position": "m", "camera_fovy": "scale", "colour": "fraction",
    "joint_noise": "rad", "joint_offset": "rad", "object_position_noise": "m",
    "object_position_latency": "s",
}
_BOUNDS: dict[str, tuple[float, float]] = {
    **dict.fromkeys(_SCALES, (0.05, 20.0)),
    "action_latency": (0, 20), "control_jitter": (0.0, 1.0), "lag": (0.0, 2.0), "command_offset": (0.0, 0.2),
    "droop": (0.0, 0.2),
    "joint_noise": (0.0, 0.1), "joint_offset": (0.0, 0.1), "object_position_noise": (0.0, 0.1),
    "object_position_latency": (0.0, 1.0),
    "camera_position": (0.0, 0.2), "camera_fovy": (0.5, 2.0), "colour": (0.0, 0.9),
}
_SINGLE = ("control_jitter", "command_offset", "joint_noise", "joint_offset", "object_position_noise",
           "camera_position", "colour")
_SEED_TAG = 0x52414E44  # mixed into the env's seed: the randomiser's stream is not the task's


class RandomizationError(ValueError):
    """A ``randomization`` mapping the env cannot take (one line: the key and why)."""


@dataclass(frozen=True)
class Randomization:
    """A checked ``randomization`` mapping: ranges by key (see the module docstring)."""

    ranges: Mapping[str, tuple[float, float]]

    @classmethod
    def from_mapping(cls, data: Any, source: str = "randomization") -> Randomization:
        if data is None:
            return cls({})
        if not isinstance(data, Mapping):
            raise RandomizationError(f"{source} must be a mapping of keys to ranges, got {type(data).__name__}")
        ranges: dict[str, tuple[float, float]] = {}
        for key, value in data.items():
            if key not in RANDOMIZATION_KEYS:
                close = difflib.get_close_matches(str(key), list(RANDOMIZATION_KEYS), n=1, cutoff=0.6)
                hint = f"did you mean {close[0]!r}?" if close else f"keys: {', '.join(RANDOMIZATION_KEYS)}"
                raise RandomizationError(f"{source}: {str(key)[:60]!r} is not a randomisation key; {hint}")
            ranges[key] = _range(key, value, source)
        return cls(ranges)

    def __bool__(self) -> bool:
        return bool(self.ranges)

    # -- one episode's world -----------------------------------------------------------------------------
    def draw(self, rng: np.random.Generator, arm: Arm, *, period: float, objects: Sequence[str] = (),
             camera: tuple[str, str] | None = None, robot_entity: str = "") -> EpisodeWorld:
        """This episode's world: rows for the robot (physics, command timing) and the task's entities
        (``objects``: the object's entity name, then the table's, those the task has; ``camera``: the
        observation camera's entity and name in it, ``""`` for its only one), and the sensing."""
        joints = arm.joints
        n = len(joints)
        dyn = arm.file.dynamics
        r = self.ranges

        def scale(key: str) -> float | None:
            return float(rng.uniform(*r[key])) if key in r else None

        robot: list[tuple[str, str, str, float]] = []
        for key, target, prop in (("link_mass", "body", "mass"), ("joint_damping", "joint", "damping"),
                                  ("joint_friction", "joint", "frictionloss"),
                                  ("joint_armature", "joint", "armature"), ("actuator_gain", "actuator", "gain")):
            value = scale(key)
            if value is not None:
                robot.append((target, "", prop, value))
        latency = dyn.latency
        if "action_latency" in r:
            lo, hi = r["action_latency"]
            latency += int(rng.integers(int(lo), int(hi) + 1)) * period
        tc = np.array(dyn.time_constant or (0.0,) * n, dtype=np.float64)
        if "lag" in r:
            tc = rng.uniform(*r["lag"], n)
        gain = np.array(dyn.gain or (1.0,) * n, dtype=np.float64)
        offset = np.array(dyn.offset or (0.0,) * n, dtype=np.float64)
        if "command_offset" in r:
            offset = offset + rng.uniform(-r["command_offset"][1], r["command_offset"][1], n)
        calibration = np.zeros(n)
        if "joint_offset" in r:
            calibration = rng.uniform(-r["joint_offset"][1], r["joint_offset"][1], n)
        jitter = r["control_jitter"][1] * period if "control_jitter" in r else 0.0
        droop = np.array(dyn.droop or (0.0,) * n, dtype=np.float64)
        if "droop" in r:
            droop = droop + rng.uniform(*r["droop"], n)
        shaped = latency > 0 or jitter > 0 or np.any(tc > 0) or np.any(gain != 1) or np.any(offset) or np.any(droop)
        if shaped:
            robot += [("command", "", "latency", float(latency)), ("command", "", "jitter", float(jitter)),
                      ("command", "", "seed", float(rng.integers(0, 2 ** 32 - 1)))]
            for j, name in enumerate(joints):
                robot += [("command", name, "time_constant", float(tc[j])), ("command", name, "gain", float(gain[j])),
                          ("command", name, "offset", float(offset[j])), ("command", name, "droop", float(droop[j]))]
        entities: dict[str, list[tuple[str, str, str, float]]] = {}
        if objects:
            rows = [(t, "", p, v) for key, t, p in (("object_mass", "body", "mass"),
                                                    ("object_friction", "geom", "friction"),
                                                    ("object_size", "geom", "size"))
                    if (v := scale(key)) is not None]
            if rows:
                entities[objects[0]] = rows
            table = scale("table_friction")
            if table is not None and len(objects) > 1:
                entities[objects[1]] = [("geom", "", "friction", table)]
        if "colour" in r:
            v = r["colour"][1]
            robot.append(("geom", "", "brightness", float(rng.uniform(1 - v, 1 + v))))
            for entity in objects:
                entities.setdefault(entity, []).append(("geom", "", "brightness", float(rng.uniform(1 - v, 1 + v))))
        if camera is not None and ("camera_position" in r or "camera_fovy" in r):
            entity, name = camera
            rows = entities.setdefault(entity, []) if entity != robot_entity else robot
            if "camera_position" in r:
                v = r["camera_position"][1]
                rows += [("camera", name, axis, float(rng.uniform(-v, v))) for axis in "xyz"]
            if "camera_fovy" in r:
                rows.append(("camera", name, "fovy", float(rng.uniform(*r["camera_fovy"]))))
        noise = r["joint_noise"][1] if "joint_noise" in r else 0.0
        tracker = r["object_position_noise"][1] if "object_position_noise" in r else 0.0
        # drawn last: a config without it draws every other value as before
        tracker_latency = float(rng.uniform(*r["object_position_latency"])) if "object_position_latency" in r else 0.0
        return EpisodeWorld(robot, entities, calibration, noise, tracker, tracker_latency)


@dataclass(frozen=True)
class EpisodeWorld:
    """One episode's draw: the node's rows per entity and the sensors' offsets and noise."""

    robot: list[tuple[str, str, str, float]]
    entities: Mapping[str, list[tuple[str, str, str, float]]]
    calibration: np.ndarray
    joint_noise: float
    object_noise: float
    object_latency: float = 0.0


def _range(key: str, value: Any, source: str) -> tuple[float, float]:
    lo_b, hi_b = _BOUNDS[key]
    unit = RANDOMIZATION_KEYS[key]
    where = f"{source}.{key}"
    if key in _SINGLE:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise RandomizationError(f"{where} must be one number ({unit}), got {str(value)[:60]!r}")
        values = [float(value), float(value)]
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        values = [float(value), float(value)]
    elif isinstance(value, Sequence) and not isinstance(value, str) and len(value) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        values = [float(value[0]), float(value[1])]
    else:
        raise RandomizationError(f"{where} must be [low, high] or one number ({unit}), got {str(value)[:60]!r}")
    lo, hi = values
    if not all(math.isfinite(v) and lo_b <= v <= hi_b for v in values):
        raise RandomizationError(f"{where} is {values}: each value must be in [{lo_b:g}, {hi_b:g}] ({unit})")
    if lo > hi:
        raise RandomizationError(f"{where} is {values}: low is above high")
    if key == "action_latency" and not (lo.is_integer() and hi.is_integer()):
        raise RandomizationError(f"{where} is {values}: whole control periods")
    return lo, hi


def randomizer_rng(seed: int | None) -> np.random.Generator:
    """The randomiser's generator for an env seeded with ``seed`` (fresh entropy for ``None``)."""
    return np.random.default_rng(None if seed is None else [int(seed) & (2 ** 63 - 1), _SEED_TAG])


class WorldRandomizer:
    """An env's randomiser: at each reset, the episode's world drawn and given to the node and the sensors.

    Made by :meth:`for_env` only when there is something to do (a ``randomization`` mapping, or an arm file
    whose ``dynamics:`` is not exact); a Real env gets none (the option is ignored there, with a warning).
    """

    def __init__(self, randomization: Randomization, arm: Arm, connection: Any, objects: Sequence[str],
                 object_frames: Sequence[int], period: float, camera: tuple[str, str] | None = None) -> None:
        self.randomization, self.arm, self.connection = randomization, arm, connection
        self.objects, self.object_frames, self.period = tuple(objects), tuple(object_frames), float(period)
        self.camera = camera
        self.rng = randomizer_rng(None)
        self._touched: set[str] = set()

    @classmethod
    def for_env(cls, env: Any, data: Any) -> WorldRandomizer | None:
        randomization = Randomization.from_mapping(data, f"{type(env).__name__} option 'randomization'")
        if env.ON_ROBOT:
            if randomization:
                import warnings

                warnings.warn(f"{type(env).__name__}: 'randomization' is ignored on a robot (its gap is real)",
                              stacklevel=3)
            return None
        if not randomization and env.arm.file.dynamics.nominal:
            return None
        task = env.task
        objects = task.scene_entities()
        frames = [env.connection.frame_index(f) for f in task.tracked_frames()]
        camera = None
        if env.cameras is not None and env.cameras.source:
            entity, _, name = env.cameras.source.partition("/")
            camera = (entity, "" if entity != env.connection.robot_name else name)
        return cls(randomization, env.arm, env.connection, objects, frames, env.connection.control_period, camera)

    def apply(self, seed: int | None) -> None:
        """This episode's world: drawn (a ``seed`` restarts the draws), set in the node, given to the sensors."""
        from multiros.envs.sensing import SensorModel

        if seed is not None:
            self.rng = randomizer_rng(seed)
        world = self.randomization.draw(self.rng, self.arm, period=self.period, objects=self.objects,
                                        camera=self.camera, robot_entity=self.connection.robot_name)
        connection = self.connection
        connection.set_entity_properties(connection.robot_name, world.robot, restore=True)
        for entity in set(world.entities) | self._touched:
            connection.set_entity_properties(entity, world.entities.get(entity, []), restore=True)
        self._touched = set(world.entities)
        if world.joint_noise > 0 or world.object_noise > 0 or world.object_latency > 0 or np.any(world.calibration):
            index = self.arm.arm_index(connection.states.names)
            joints = np.arange(len(connection.states.names))[index]
            connection.sensors = SensorModel(joints, world.calibration, world.joint_noise, self.object_frames,
                                             world.object_noise, self.rng, world.object_latency)
        else:
            connection.sensors = None
