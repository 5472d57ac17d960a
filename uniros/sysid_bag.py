"""A rosbag's arm commands and joint states as a :class:`~uniros.sysid_fit.Recording` (``uniros sysid``).

Reads ROS 2 bags (sqlite3 ``.db3`` and MCAP storage) and ROS 1 bags with the ``rosbags`` library
(its ``AnyReader``): ``sensor_msgs/JointState`` on the joint states topic, and the arm controller's
commands, ``trajectory_msgs/JointTrajectory`` on ``<controller>/joint_trajectory`` (a trajectory
controller: the setpoint moves linearly from where it was to each point) or
``std_msgs/Float64MultiArray`` on ``<controller>/commands`` (a forward controller: a step, values in
the controller's joint order, the arm file's ``arm.joints``). :func:`default_topics` names them as the
arm's Real twins do (the arm file's ``real:`` section).

A bag is a file from elsewhere: it is read within bounds (:data:`MAX_BAG_BYTES`, :data:`MAX_MESSAGES`,
:data:`MAX_MESSAGE_BYTES`), and each message that cannot be used is skipped and counted by reason
(undecodable, wrong lengths, NaN, names that do not match, stamps out of order or far from when the
message was recorded). Too little left is a :class:`BagError`, one line.

Time: the joint states' header stamps when the bag's clock agrees with them (within a second: a
robot on the recording machine's clock), else the time each message was recorded; commands start
when they were recorded (a trajectory at its header stamp when it has one on that clock).
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uniros.sysid_fit import CommandTrace, Recording

__all__ = ["BagError", "BagSummary", "BagTopics", "MAX_BAG_BYTES", "MAX_MESSAGES", "MAX_MESSAGE_BYTES",
           "default_topics", "read_recording"]

#: Bytes of a bag (all its files) read at most.
MAX_BAG_BYTES = 4 * 1024**3
#: Messages of the topics read at most (5.5 h of joint states at 100 Hz).
MAX_MESSAGES = 2_000_000
#: Bytes of one message: a JointState of a few thousand joints; a larger one is skipped.
MAX_MESSAGE_BYTES = 1024 * 1024
#: Joint names of one JointState, points of one JointTrajectory.
MAX_NAMES, MAX_POINTS = 1024, 10_000
#: s: a stamp further than this from when its message was recorded is on another clock.
CLOCK_AGREEMENT = 1.0
_MIN_STATES = 50

JOINT_STATE = "sensor_msgs/msg/JointState"
TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
FORWARD = "std_msgs/msg/Float64MultiArray"
_COMMAND_TYPES = (TRAJECTORY, FORWARD)


class BagError(ValueError):
    """A bag that cannot be read, or holds too little to fit (one line: the bag, what is wrong, the fix)."""


@dataclass(frozen=True)
class BagTopics:
    """Where the joint states and the arm's commands are (absolute topic names)."""

    joint_states: str
    commands: tuple[str, ...]


@dataclass(frozen=True)
class BagSummary:
    """What was read: the bag's storage, the topics, the messages kept and skipped, the clock used."""

    path: Path
    storage: str
    joint_states_topic: str
    command_topics: tuple[str, ...]
    states: int
    commands: int
    skipped: dict[str, int]
    time_base: str


def _resolve(namespace: str, name: str) -> str:
    ns = "/" + namespace.strip("/") if namespace.strip("/") else ""
    return name if name.startswith("/") else f"{ns}/{name}"


def default_topics(namespace: str, arm_controller: str, joint_states_topic: str | None) -> BagTopics:
    """The topics of an arm file's ``real:`` section, as its Real twins resolve them: joint states on
    ``joint_states_topic`` (default ``joint_states``) and the arm controller's ``joint_trajectory`` and
    ``commands`` topics, relative names inside ``namespace``."""
    return BagTopics(_resolve(namespace, joint_states_topic or "joint_states"),
                     (_resolve(namespace, f"{arm_controller}/joint_trajectory"),
                      _resolve(namespace, f"{arm_controller}/commands")))


def _bag_paths(path: Path, max_bytes: int) -> tuple[Path, str]:
    """The path ``AnyReader`` opens (a ROS 2 bag's folder, a ROS 1 ``.bag`` file) and its storage's name."""
    if not path.exists():
        raise BagError(f"{path}: no such bag (a ROS 2 bag's folder, its .db3 or .mcap file, or a ROS 1 .bag)")
    if path.is_file() and path.suffix in (".db3", ".mcap") and (path.parent / "metadata.yaml").is_file():
        path = path.parent
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise BagError(f"{path}: not a ROS 2 bag (no metadata.yaml in the folder)")
        files = []
        for i, entry in enumerate(path.iterdir()):
            if i >= 10_000:
                raise BagError(f"{path}: more than 10,000 files in the bag's folder")
            if entry.is_file():
                files.append(entry)
        size = sum(f.stat().st_size for f in files)
        kinds = {f.suffix for f in files}
        storage = "ROS 2 (MCAP)" if ".mcap" in kinds else "ROS 2 (sqlite3)" if ".db3" in kinds else "ROS 2"
    elif path.suffix == ".bag":
        size, storage = path.stat().st_size, "ROS 1"
    else:
        raise BagError(f"{path}: not a bag (a ROS 2 bag's folder or its .db3/.mcap file with metadata.yaml beside "
                       "it, or a ROS 1 .bag file)")
    if size > max_bytes:
        raise BagError(f"{path}: {size / 1024**3:.1f} GiB, more than the {max_bytes / 1024**3:.1f} GiB "
                       "uniros sysid reads: cut it to the stretch to fit (ros2 bag convert with start/end "
                       "times, or record a shorter one)")
    return path, storage


def _default_typestore() -> Any:
    """The ROS 2 distro's type store for bags that carry no message definitions ($ROS_DISTRO, else jazzy)."""
    from rosbags.typesys import Stores, get_typestore

    distro = os.environ.get("ROS_DISTRO", "").strip().upper()
    store = getattr(Stores, f"ROS2_{distro}", None) if distro.isalpha() else None
    return get_typestore(store or Stores.ROS2_JAZZY)


def _seconds(stamp: Any) -> float:
    """A ``builtin_interfaces`` Time/Duration (ROS 1's ``nsec`` too) in seconds."""
    nanos: Any = getattr(stamp, "nanosec", None)
    if nanos is None:
        nanos = getattr(stamp, "nsec", 0)
    return float(stamp.sec) + float(nanos) * 1e-9


class _Reader:
    """Decodes and checks the messages of one bag; counts what it skips."""

    def __init__(self, joints: Sequence[str], controller_joints: Sequence[str]) -> None:
        self.joints = tuple(joints)
        self.controller_index = [list(controller_joints).index(j) for j in self.joints]
        self.n_controller = len(controller_joints)
        self.skipped: Counter[str] = Counter()
        #: joint states: (recorded at, header stamp or nan, positions)
        self.states: list[tuple[float, float, np.ndarray]] = []
        #: commands: (recorded at, header stamp or nan, offsets, positions)
        self.commands: list[tuple[float, float, np.ndarray, np.ndarray]] = []

    def skip(self, why: str) -> None:
        self.skipped[why] += 1

    def joint_state(self, msg: Any, recorded: float) -> None:
        names = list(msg.name)
        position = np.asarray(msg.position, dtype=np.float64)
        if len(names) > MAX_NAMES or position.shape != (len(names),) or len(set(names)) != len(names):
            return self.skip("joint states whose names and positions do not match")
        try:
            index = [names.index(j) for j in self.joints]
        except ValueError:
            return self.skip("joint states without every arm joint")
        values = position[index]
        if not np.all(np.isfinite(values)):
            return self.skip("joint states with NaN or infinite positions")
        stamp = _seconds(msg.header.stamp)
        self.states.append((recorded, stamp if stamp > 0 else np.nan, values))

    def trajectory(self, msg: Any, recorded: float) -> None:
        names = list(msg.joint_names)
        points = list(msg.points)
        if not points or len(points) > MAX_POINTS or len(names) > MAX_NAMES or len(set(names)) != len(names):
            return self.skip("trajectories with no points, too many, or a joint named twice")
        try:
            index = [names.index(j) for j in self.joints]
        except ValueError:
            return self.skip("trajectories without every arm joint")
        offsets = np.array([_seconds(p.time_from_start) for p in points])
        rows = [np.asarray(p.positions, dtype=np.float64) for p in points]
        if any(r.shape != (len(names),) for r in rows):
            return self.skip("trajectory points whose positions do not match the joint names")
        positions = np.stack(rows)[:, index]
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(offsets)) and offsets[0] >= 0
                and np.all(np.diff(offsets) > 0)):
            return self.skip("trajectories with NaN positions or times not increasing from >= 0")
        stamp = _seconds(msg.header.stamp)
        self.commands.append((recorded, stamp if stamp > 0 else np.nan, offsets, positions))

    def forward(self, msg: Any, recorded: float) -> None:
        data = np.asarray(msg.data, dtype=np.float64)
        if data.shape != (self.n_controller,):
            return self.skip(f"forward commands whose length is not the controller's {self.n_controller} joints")
        values = data[self.controller_index]
        if not np.all(np.isfinite(values)):
            return self.skip("forward commands with NaN or infinite values")
        self.commands.append((recorded, np.nan, np.zeros(1), values[None, :]))

    def recording(self) -> tuple[Recording, str]:
        """The kept messages on one clock, in order (later stamps than the last kept only)."""
        if len(self.states) < _MIN_STATES:
            raise BagError(f"{len(self.states)} usable joint states{self._skipped_text()}: a fit needs at least "
                           f"{_MIN_STATES}")
        if not self.commands:
            raise BagError(f"no usable command{self._skipped_text()}: nothing says what the joints were told")
        recorded = np.array([s[0] for s in self.states])
        stamps = np.array([s[1] for s in self.states])
        lag = recorded - stamps
        stamped = np.isfinite(lag)
        offset = float(np.median(lag[stamped])) if stamped.mean() >= 0.9 else np.inf
        use_stamps = abs(offset) < CLOCK_AGREEMENT
        if use_stamps:
            far = stamped & (np.abs(np.where(stamped, lag, 0.0) - offset) > CLOCK_AGREEMENT)
            self.skipped["joint states without a stamp"] += int((~stamped).sum())
            times = np.where(far | ~stamped, np.nan, stamps)
            base = f"joint states' header stamps (recorded {offset * 1e3:.1f} ms after them, median)"
        else:
            far, times = np.zeros_like(stamped), recorded
            base = "the times messages were recorded (the joint states' stamps are on another clock)"
        self.skipped["joint states stamped far from when they were recorded"] += int(far.sum())
        keep, last = [], -np.inf
        for i, t in enumerate(times):
            if not np.isfinite(t):
                continue
            if t <= last:
                self.skip("joint states stamped out of order or twice")
                continue
            keep.append(i)
            last = t
        starts, offsets, positions, last = [], [], [], -np.inf
        for rec_t, stamp, offs, pos in self.commands:
            start = stamp if use_stamps and np.isfinite(stamp) and abs(rec_t - stamp) < CLOCK_AGREEMENT else rec_t
            if start < last:
                self.skip("commands out of order")
                continue
            starts.append(start)
            offsets.append(offs)
            positions.append(pos)
            last = start
        if len(keep) < _MIN_STATES:
            raise BagError(f"{len(keep)} usable joint states{self._skipped_text()}: a fit needs at least {_MIN_STATES}")
        trace = CommandTrace(np.array(starts), tuple(offsets), tuple(positions))
        rec = Recording(self.joints, times[keep], np.stack([self.states[i][2] for i in keep]), trace)
        return rec, base

    def _skipped_text(self) -> str:
        if not self.skipped:
            return ""
        return " (skipped: " + "; ".join(f"{n} {why}" for why, n in self.skipped.most_common() if n) + ")"


def read_recording(path: str | os.PathLike[str], *, joints: Sequence[str], controller_joints: Sequence[str],
                   topics: BagTopics, max_bytes: int = MAX_BAG_BYTES, max_messages: int = MAX_MESSAGES,
                   ) -> tuple[Recording, BagSummary]:
    """The joint states and commands of ``joints`` in a bag.

    Args:
        path: a ROS 2 bag's folder (or its ``.db3``/``.mcap`` file), or a ROS 1 ``.bag`` file.
        joints: the joints to read (a subset of ``controller_joints``, any order).
        controller_joints: the arm controller's joints in its order (a forward command's values).
        topics: the joint states topic and the command topics (those the bag lacks are ignored, but
            one must be there).

    Raises:
        BagError: not a bag, too large, the topics missing or of another type, too little usable.
    """
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise BagError("uniros sysid reads bags with the rosbags library: pip install rosbags") from None
    bag, storage = _bag_paths(Path(path).expanduser(), max_bytes)
    missing = [j for j in joints if j not in controller_joints]
    if missing:
        raise BagError(f"joints {missing} are not the arm's joints {list(controller_joints)}")
    reader = _Reader(joints, controller_joints)
    try:
        with AnyReader([bag], default_typestore=_default_typestore()) as any_reader:
            conns = any_reader.connections
            by_topic: dict[str, list[Any]] = {}
            for c in conns:
                by_topic.setdefault(c.topic, []).append(c)
            shown = ", ".join(sorted(by_topic)[:20]) + (" ..." if len(by_topic) > 20 else "")
            states = by_topic.get(topics.joint_states, [])
            if not states:
                raise BagError(f"{bag}: no topic {topics.joint_states} (the bag has: {shown or 'no topics'}); "
                               "name the joint states topic with --joint-states-topic")
            wrong = sorted({c.msgtype for c in states if c.msgtype != JOINT_STATE})
            if wrong:
                raise BagError(f"{bag}: {topics.joint_states} carries {wrong[0]}, not {JOINT_STATE}")
            commands = [c for t in topics.commands for c in by_topic.get(t, [])]
            if not commands:
                raise BagError(f"{bag}: none of the command topics {list(topics.commands)} (the bag has: {shown}); "
                               "name the arm controller's topic with --command-topic")
            wrong = sorted({f"{c.topic} ({c.msgtype})" for c in commands if c.msgtype not in _COMMAND_TYPES})
            if wrong:
                raise BagError(f"{bag}: {wrong[0]} is no arm command: uniros sysid reads {TRAJECTORY} "
                               f"(<controller>/joint_trajectory) and {FORWARD} (<controller>/commands)")
            wanted = states + commands
            total = sum(int(getattr(c, "msgcount", 0) or 0) for c in wanted)
            if total > max_messages:
                raise BagError(f"{bag}: {total:,} messages on the topics read, more than {max_messages:,}: cut the "
                               "bag to the stretch to fit")
            count = 0
            for conn, timestamp, raw in any_reader.messages(connections=wanted):
                count += 1
                if count > max_messages:
                    raise BagError(f"{bag}: more than {max_messages:,} messages on the topics read (its index "
                                   "said fewer): cut the bag to the stretch to fit")
                if len(raw) > MAX_MESSAGE_BYTES:
                    reader.skip(f"messages over {MAX_MESSAGE_BYTES:,} bytes")
                    continue
                try:
                    msg = any_reader.deserialize(raw, conn.msgtype)
                except Exception:  # noqa: BLE001 - a hostile or truncated message: skipped and counted
                    reader.skip("messages that do not decode")
                    continue
                recorded = timestamp * 1e-9
                if conn.msgtype == JOINT_STATE:
                    reader.joint_state(msg, recorded)
                elif conn.msgtype == TRAJECTORY:
                    reader.trajectory(msg, recorded)
                else:
                    reader.forward(msg, recorded)
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags' errors on a broken bag (its own classes, sqlite, mcap)
        text = str(exc).strip().splitlines()[0][:300] if str(exc).strip() else type(exc).__name__
        raise BagError(f"{bag}: cannot be read as a bag: {text}") from None
    rec, base = reader.recording()
    summary = BagSummary(path=bag, storage=storage, joint_states_topic=topics.joint_states,
                         command_topics=tuple(sorted({c.topic for c in commands})), states=len(rec.times),
                         commands=len(rec.commands), skipped={k: v for k, v in reader.skipped.items() if v},
                         time_base=base)
    return rec, summary
