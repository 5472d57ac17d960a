"""A measurable reality gap for the fake robot: what a real arm does that a perfect follower does not.

``uniros-fake-robot --gap PROFILE`` makes its joints and its ``joint_states`` imperfect in known,
seeded amounts, so a policy or a Real env can be tried against a gap of a chosen size before a
robot, and a tool (``uniros sysid``) can be checked against the values it should recover. A
:class:`GapProfile` is the value (seconds, radians, fractions); the shipped ones are :data:`PROFILES`
(``none``, ``mild``, ``hard``) and :func:`load_gap_profile` also reads a YAML file of the same keys.

The model, in the order a command meets it:

* ``latency``: the hardware command interface takes effect ``latency`` seconds after a controller
  writes it (:meth:`JointGap.delayed`, a queue of timestamped commands);
* ``time_constant``: the servo's first-order lag (0 keeps the fake robot's own, 0.1 s);
* ``droop``: the servo stops ``droop`` short of its target on the side it came from, and a command
  within ``droop`` of where it stands does not move it (a stiff servo under load, or stiction), on
  the arm joints ``droop_joints`` (:meth:`JointGap.droop_target`);
* ``backlash``: play of ``backlash`` radians between the servo and the link: after a direction change
  the link does not move until the servo has crossed the play (:meth:`JointGap.play`);
* ``offset``: the encoder reads the link plus a calibration offset drawn per arm joint uniformly in
  ``[-offset, offset]``; the servo closes its loop on the encoder, so commands and ``joint_states``
  are in the encoder's frame and only the truth (:meth:`JointGap.truth`) shows the offset;
* ``noise``, ``drop``, ``late``/``late_by``, ``jitter``: what ``joint_states`` suffers on its way out
  (:class:`StateGap`: Gaussian position noise, dropped messages, messages delivered late but stamped
  with their capture time, publish times jittered around their slots).

Every random draw comes from a seeded :class:`numpy.random.Generator` (:func:`gap_generators`: one
stream for the joints' offsets, one for the messages), so the same seed gives the same robot.
The per-update work is a few vectorised numpy operations: the fake robot runs at 100 Hz beside
other processes.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from multiros.bounded_yaml import YamlBoundsError, read_yaml_bounded

__all__ = ["GapProfile", "GapProfileError", "JointGap", "KEYS", "PROFILES", "StateGap", "gap_generators",
           "load_gap_profile", "parse_gap_assignments"]

#: Keys that are fractions in [0, 1].
_FRACTIONS = ("drop", "late", "jitter")
#: Keys in seconds, bounded (the latency and late queues hold that many seconds of messages).
_SECONDS = ("latency", "time_constant", "late_by")
_MAX_SECONDS = 10.0
_MAX_DROOP_JOINT = 64


class GapProfileError(ValueError):
    """A gap profile that cannot be used (one line naming the key)."""


@dataclass(frozen=True)
class GapProfile:
    """The size of each part of the gap (every default 0: no gap). See the module docstring.

    Attributes:
        latency: s, a command takes effect this long after it arrives.
        time_constant: s, the joints' first-order lag (0: the fake robot's default).
        backlash: rad, play between servo and link (dead band on direction change).
        droop: rad, the ``droop_joints`` settle this far short of their target, on the side they came from.
        droop_joints: indices into the commanded arm joints (shoulder and elbow on every shipped arm).
        offset: rad, calibration offsets drawn per arm joint uniformly in ``[-offset, offset]``.
        noise: rad, standard deviation of Gaussian noise on published positions.
        drop: fraction of ``joint_states`` messages dropped.
        late: fraction of ``joint_states`` messages delivered ``late_by`` seconds late.
        late_by: s, how late a late message arrives (stamped with its capture time).
        jitter: fraction of the publish period: each publish time moves uniformly within
            ``+-jitter/2`` periods of its slot.
    """

    latency: float = 0.0
    time_constant: float = 0.0
    backlash: float = 0.0
    droop: float = 0.0
    droop_joints: tuple[int, ...] = (1, 2)
    offset: float = 0.0
    noise: float = 0.0
    drop: float = 0.0
    late: float = 0.0
    late_by: float = 0.0
    jitter: float = 0.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name == "droop_joints":
                continue
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value < 0:
                raise GapProfileError(f"gap key {f.name!r}: must be a finite number >= 0, got {value!r}")
            if f.name in _FRACTIONS and value > 1:
                raise GapProfileError(f"gap key {f.name!r}: must be a fraction in [0, 1], got {value!r}")
            if f.name in _SECONDS and value > _MAX_SECONDS:
                raise GapProfileError(f"gap key {f.name!r}: must be at most {_MAX_SECONDS:g} s, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        joints = self.droop_joints
        if not isinstance(joints, (tuple, list)) or not all(
                isinstance(i, int) and not isinstance(i, bool) and 0 <= i < _MAX_DROOP_JOINT for i in joints):
            raise GapProfileError(f"gap key 'droop_joints': must be a list of arm joint indices in "
                                  f"[0, {_MAX_DROOP_JOINT}), got {joints!r}")
        if len(set(joints)) != len(joints):
            raise GapProfileError(f"gap key 'droop_joints': indices repeat in {list(joints)}")
        object.__setattr__(self, "droop_joints", tuple(joints))

    @property
    def acts_on_joints(self) -> bool:
        """Whether the joints differ from a perfect follower (latency, backlash, droop, offsets)."""
        return bool(self.latency or self.backlash or self.droop or self.offset)

    @property
    def acts_on_messages(self) -> bool:
        """Whether ``joint_states`` suffers (noise, drops, late messages, jitter)."""
        return bool(self.noise or self.drop or (self.late and self.late_by) or self.jitter)


#: The shipped profiles (docs/fake_robot.md lists their values).
PROFILES: Mapping[str, GapProfile] = MappingProxyType({
    "none": GapProfile(),
    "mild": GapProfile(latency=0.02, time_constant=0.12, backlash=0.002, droop=0.01, offset=0.005, noise=0.001,
                       drop=0.01, late=0.01, late_by=0.05, jitter=0.1),
    "hard": GapProfile(latency=0.1, time_constant=0.25, backlash=0.005, droop=0.03, offset=0.01, noise=0.004,
                       drop=0.05, late=0.05, late_by=0.1, jitter=0.3),
})
KEYS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(GapProfile))


def _value(key: str, raw: Any) -> Any:
    """A key's value from YAML or the command line (strings parsed: ``1e-3``, ``1,2``, ``[1, 2]``)."""
    if key == "droop_joints":
        if isinstance(raw, str):
            text = raw.strip().removeprefix("[").removesuffix("]")
            try:
                return tuple(int(part) for part in text.split(",") if part.strip())
            except ValueError:
                raise GapProfileError(f"gap key 'droop_joints': must be a list of arm joint indices, got {raw!r}") \
                    from None
        return tuple(raw) if isinstance(raw, list) else raw
    if isinstance(raw, str):
        try:
            return float(raw)
        except ValueError:
            raise GapProfileError(f"gap key {key!r}: must be a number, got {raw!r}") from None
    return raw


def _with(base: GapProfile, values: Mapping[str, Any], where: str) -> GapProfile:
    unknown = [k for k in values if k not in KEYS]
    if unknown:
        raise GapProfileError(f"{where}: unknown gap key(s) {unknown}; the keys are {list(KEYS)}")
    return dataclasses.replace(base, **{k: _value(k, v) for k, v in values.items()})


def parse_gap_assignments(items: Sequence[str]) -> dict[str, str]:
    """``["drop=0.1", "droop_joints=1,2"]`` (``--gap-set``, repeatable) as a mapping; the last one wins."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise GapProfileError(f"--gap-set {item!r}: must look like KEY=VALUE (keys: {', '.join(KEYS)})")
        out[key.strip()] = value.strip()
    return out


def load_gap_profile(name_or_path: str | Path, overrides: Mapping[str, Any] | None = None) -> GapProfile:
    """A shipped profile by name (``none``, ``mild``, ``hard``) or a YAML mapping of profile keys (the
    others 0), with ``overrides`` (key -> value; strings are parsed as on the command line) on top.

    Raises:
        GapProfileError: an unknown name or key, a file that cannot be read, a bad value (one line).
    """
    name = str(name_or_path)
    if name in PROFILES and not isinstance(name_or_path, Path):  # a file called "hard": give it as ./hard
        profile = PROFILES[name]
    else:
        path = Path(name)
        if not path.is_file():
            raise GapProfileError(f"gap profile {name!r}: neither a shipped profile ({', '.join(PROFILES)}) "
                                  "nor a YAML file")
        try:
            data = read_yaml_bounded(path)
        except (OSError, YamlBoundsError) as exc:
            raise GapProfileError(f"gap profile {name}: cannot be read: {exc}") from None
        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise GapProfileError(f"gap profile {name}: must be a YAML mapping of gap keys ({', '.join(KEYS)})")
        profile = _with(GapProfile(), data, f"gap profile {name}")
    return _with(profile, dict(overrides or {}), "--gap-set") if overrides else profile


def gap_generators(seed: int | None) -> tuple[np.random.Generator, np.random.Generator]:
    """Two independent streams from ``seed``: the joints' (offsets) and the messages' (noise, drops,
    late messages, jitter), so changing one part of a profile does not change the other's draws."""
    joints, messages = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(joints), np.random.default_rng(messages)


class JointGap:
    """The per-joint state of the gap at the hardware (all arrays over the hardware joints).

    Args:
        profile: the gap.
        position: the joints' start positions (encoder frame); servo and link start there.
        arm_index: hardware indices of the commanded arm joints (``droop_joints`` index into them;
            offsets are drawn for them).
        rng: the joints' random stream (offsets).
    """

    def __init__(self, profile: GapProfile, position: np.ndarray, arm_index: Sequence[int] | np.ndarray,
                 rng: np.random.Generator) -> None:
        n = len(position)
        arm = np.asarray(arm_index, dtype=np.intp)
        self.profile = profile
        self.latency = profile.latency
        self.half_play = 0.5 * profile.backlash
        self.offsets = np.zeros(n)
        self.offsets[arm] = rng.uniform(-profile.offset, profile.offset, arm.size)
        self.droop = np.zeros(n)
        if profile.droop > 0:
            bad = [i for i in profile.droop_joints if i >= arm.size]
            if bad:
                raise GapProfileError(f"gap key 'droop_joints': {bad} out of range for the {arm.size} commanded arm "
                                      f"joints (indices 0..{arm.size - 1})")
            self.droop[arm[list(profile.droop_joints)]] = profile.droop
        self.droops = bool(np.any(self.droop > 0))
        #: The servo side of each joint (encoder frame); the link is the hardware's position.
        self.servo = np.asarray(position, dtype=float).copy()
        # Before the first command takes effect nothing is commanded (no mode: the joints hold, no effort).
        self._queue: deque[tuple[float, np.ndarray, np.ndarray]] = deque(
            [(-math.inf, self.servo.copy(), np.full(n, -1, dtype=np.int8))])

    def delayed(self, now: float, command: np.ndarray, mode: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Record the command interface at ``now``; return the one written ``latency`` seconds ago (the
        oldest one until then), with the joint modes of that time."""
        if not self.latency:
            return command, mode
        queue = self._queue
        queue.append((now, command.copy(), mode.copy()))
        due = now - self.latency
        while len(queue) > 1 and queue[1][0] <= due:
            queue.popleft()
        return queue[0][1], queue[0][2]

    def droop_target(self, command: np.ndarray) -> np.ndarray:
        """Where the servo heads for ``command``: the nearest point within ``droop`` of it (its own position
        when already there), i.e. short of the target on the side it comes from."""
        if not self.droops:
            return command
        return np.clip(self.servo, command - self.droop, command + self.droop)

    def play(self, servo: np.ndarray, link: np.ndarray) -> np.ndarray:
        """Move the servo to ``servo``; the link (``link``, its last position) follows only once the play
        is taken up. Returns the link's new position."""
        self.servo[:] = servo
        if not self.half_play:
            return servo.copy()
        return np.clip(link, servo - self.half_play, servo + self.half_play)

    def truth(self, encoder: np.ndarray) -> np.ndarray:
        """The true joint positions for encoder readings (encoder = truth + offset)."""
        return encoder - self.offsets


class StateGap:
    """What ``joint_states`` suffers on its way out: noise, drops, late delivery, publish jitter.

    Args:
        profile: the gap.
        period: the publish period in seconds.
        rng: the messages' random stream.
    """

    DROP, LATE, NOW = "drop", "late", "now"

    def __init__(self, profile: GapProfile, period: float, rng: np.random.Generator) -> None:
        self.profile = profile
        self.period = float(period)
        self._rng = rng
        self.late_by = profile.late_by if profile.late else 0.0

    def fate(self) -> str:
        """``DROP``, ``LATE`` or ``NOW`` for the next message."""
        p = self.profile
        if not (p.drop or self.late_by):
            return self.NOW
        u = float(self._rng.random())
        if u < p.drop:
            return self.DROP
        return self.LATE if self.late_by and u < p.drop + p.late else self.NOW

    def noisy(self, positions: list[float]) -> list[float]:
        """``positions`` with Gaussian noise of the profile's ``noise`` (unchanged when 0)."""
        if not self.profile.noise:
            return positions
        return (np.asarray(positions) + self._rng.normal(0.0, self.profile.noise, len(positions))).tolist()

    def jitter(self) -> float:
        """Seconds to move the next publish from its slot (uniform in ``+-jitter/2`` periods)."""
        if not self.profile.jitter:
            return 0.0
        return float(self._rng.uniform(-0.5, 0.5)) * self.profile.jitter * self.period

