"""``/tf`` and ``/tf_static`` of the simulation node, as ``robot_state_publisher`` sends them.

Each robot (and each entity with a camera) gets an :class:`~multiros.sim.tf_tree.EntityFrames`.
Static transforms go out together on ``/tf_static`` (reliable, transient local, depth 1, as tf2's
static broadcaster: one message holds every static transform of every entity, so a late joiner
gets them all), again whenever one of them changes (an entity moved or spawned). Dynamic ones go on
``/tf`` with every published joint state (after each step, if anyone subscribes) and, so that a
paused simulation is in the tree too, from a heartbeat thread (4 Hz): when a listener comes or
something moved without a step (joints or poses set, a reset) while anyone listens.

Stamps: tf2 ignores a transform whose stamp it already holds for that frame (``TF_REPEATED_DATA``, a
warning each time), and a paused simulation's time stands still. So ``/tf`` never repeats a stamp:
a message sent while the time has not moved carries the last stamp plus one nanosecond, and the
heartbeat sends nothing unless a listener came or something moved.

Frame names: the description's link names (``frame_prefix=""``, the default), or under a prefix the
node was given (a template: ``"{entity}/"`` puts each entity's name first). Two entities would
publish the same frame (two robots of one description, no prefix): the later one falls back to the
prefix ``<entity>/`` and a warning says so, with the way to choose (a ``robot_name`` of its own or
a node frame prefix).
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from multiros.ros.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from multiros.sim import convert
from multiros.sim.distro_adapters import get_message
from multiros.sim.tf_tree import WORLD, EntityFrames

__all__ = ["TFPublisher", "check_frame_prefix"]

TFMessage = get_message("tf2_msgs/msg/TFMessage")
TransformStamped = get_message("geometry_msgs/msg/TransformStamped")
Time = get_message("builtin_interfaces/msg/Time")

STATIC_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
HEARTBEAT_SEC = 0.25
_SAME_TIME_NS = 1000  # a stamp this close behind the last one is the same time, bumped (not a reset)
_STATIC_CHECK_BEATS = 8
_PREFIX = re.compile(r"^[A-Za-z0-9_/]*$")


def check_frame_prefix(template: str) -> str:
    """A frame prefix template, checked: letters, digits, ``_``, ``/`` and ``{entity}``.

    Raises:
        ValueError: anything else (the message names the template and the fix).
    """
    if not isinstance(template, str) or not _PREFIX.match(template.replace("{entity}", "x")):
        raise ValueError(f"frame_prefix {template!r} is not a TF frame prefix; use letters, digits, '_' and '/', "
                         f"and {{entity}} for the entity's name (e.g. '{{entity}}/'), or '' for the description's "
                         f"link names")
    return template


def _fill(msg: Any, parent: str, child: str, stamp: Any, t: np.ndarray, q: np.ndarray) -> Any:
    msg.header.stamp = stamp
    msg.header.frame_id = parent
    msg.child_frame_id = child
    tr, rot = msg.transform.translation, msg.transform.rotation
    tr.x, tr.y, tr.z = float(t[0]), float(t[1]), float(t[2])
    rot.w, rot.x, rot.y, rot.z = float(q[0]), float(q[1]), float(q[2]), float(q[3])
    return msg


class TFPublisher:
    """The node's TF broadcaster (see the module docstring).

    Args:
        node: the simulation node (its publishers).
        world: its world.
        lock: the node's lock (the heartbeat takes it to read poses).
        frame_prefix: frame prefix template (``""``: the description's link names).
        warn: logs a warning (a frame clash).
    """

    def __init__(self, node: Any, world: Any, lock: Any, frame_prefix: str = "",
                 warn: Callable[[str], None] = lambda text: None) -> None:
        self._node, self._world, self._lock = node, world, lock
        self.frame_prefix = check_frame_prefix(frame_prefix)
        self._warn = warn
        self._tf = node.create_publisher(TFMessage, "/tf", 100)
        self._static = node.create_publisher(TFMessage, "/tf_static", STATIC_QOS)
        self._entities: dict[str, EntityFrames] = {}
        self._owners: dict[str, str] = {}  # child frame -> entity
        self._sent: tuple[tuple[str, ...], np.ndarray] | None = None  # the last /tf_static: children, values
        self._wake, self._stop = threading.Event(), threading.Event()
        self._thread: threading.Thread | None = None
        self._fell_back = False
        self._dirty = False  # something moved since the last /tf message
        self._listeners: tuple[int, int, int | None] = (0, 0, None)  # /tf, /tf_static subscriptions, graph version
        self._last_ns = -1  # the stamp of the last /tf message

    # -- entities -------------------------------------------------------------------------------
    def attach(self, name: str, cameras: Iterable[tuple[str, str]] = ()) -> EntityFrames:
        """Build entity ``name``'s tree (``cameras``: its camera sensors, ``(camera, frame_name)``);
        caller holds the node's lock."""
        self.detach(name)
        cameras = tuple(cameras)
        prefix = self.frame_prefix.replace("{entity}", name)
        frames = EntityFrames(self._world, name, prefix, cameras)
        clash = self._clashes(frames)
        if clash and not prefix:
            fallback = EntityFrames(self._world, name, f"{name}/", cameras)
            if not self._clashes(fallback):
                if not self._fell_back:  # once: a vector env's robots would say it a hundred times
                    self._warn(f"entity {name!r}: its TF frames {clash[:3]} are already published by entity "
                               f"{self._owners[clash[0]]!r}; its frames (and those of later entities like it) "
                               f"are published as '{name}/<link>' instead. Give it a robot_name (xacro "
                               f"argument) of its own, or start the node with a frame prefix (uniros-sim "
                               f"--frame-prefix '{{entity}}/') to choose")
                self._fell_back = True
                frames, clash = fallback, []
        if clash:
            self._warn(f"entity {name!r}: TF frames {clash[:3]} are already published by entity "
                       f"{self._owners[clash[0]]!r}; they are left out of its tree")
            frames.drop(clash)
        for child in frames.children:
            self._owners[child] = name
        self._entities[name] = frames
        self._dirty = True
        self._start()
        self._wake.set()
        return frames

    def _clashes(self, frames: EntityFrames) -> list[str]:
        return [c for c in frames.children if c == WORLD or c in self._owners]

    def detach(self, name: str) -> None:
        """Forget entity ``name``'s tree (its static transforms leave ``/tf_static``)."""
        frames = self._entities.pop(name, None)
        if frames is None:
            return
        for child in frames.children:
            if self._owners.get(child) == name:
                del self._owners[child]
        self._wake.set()

    def frames(self, name: str) -> EntityFrames | None:
        """Entity ``name``'s tree, if it has one."""
        return self._entities.get(name)

    def changed(self) -> None:
        """Something moved outside a step (a pose set, a reset): send the trees again soon, if anyone
        listens. Nobody listening (lockstep training, the usual case), the heartbeat is left asleep: it
        would take the node's lock to read poses nobody wants, at every reset, and the client would
        wait for it (1.4 ms a reset of the RX200 reach, more than the reset's own work). A listener
        that comes later gets both trees at the next beat (see :meth:`_run`)."""
        if self._entities:
            self._dirty = True
            if self._tf.get_subscription_count() or self._static.get_subscription_count():
                self._wake.set()

    # -- publishing -----------------------------------------------------------------------------
    def publish(self) -> bool:
        """Send the dynamic transforms if anyone subscribes to ``/tf`` (caller holds the node's
        lock); whether anyone does."""
        if not self._entities or not self._tf.has_subscribers():
            return False
        ns = int(round(self._world.time * 1e9))
        if 0 <= self._last_ns - ns < _SAME_TIME_NS:  # the time stood still: a stamp tf2 has not seen
            ns = self._last_ns + 1
        self._last_ns = ns
        stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        self._dirty = False
        transforms: list[Any] = []
        for frames in self._entities.values():
            edges, translation, rotation = frames.transforms(self._world, static=False)
            transforms.extend(_fill(TransformStamped(), e.parent, e.child, stamp, t, q)
                              for e, t, q in zip(edges, translation, rotation))
        if transforms:
            self._tf.publish(TFMessage(transforms=transforms))
        return True

    def publish_static(self, force: bool = False) -> bool:
        """Send every static transform on ``/tf_static`` if any changed since the last time (or
        ``force``); caller holds the node's lock. Whether it sent."""
        stamp = convert.time_msg(self._world.time)
        rows, children, values = [], [], []
        for frames in self._entities.values():
            edges, translation, rotation = frames.transforms(self._world, static=True)
            for e, t, q in zip(edges, translation, rotation):
                rows.append((e, t, q))
                children.append(f"{e.parent}>{e.child}")
                values.append(np.concatenate([t, q]))
        current = (tuple(children), np.array(values).reshape(-1, 7))
        if not force and self._sent is not None and self._sent[0] == current[0] and np.array_equal(
                self._sent[1], current[1]):
            return False
        self._static.publish(TFMessage(transforms=[_fill(TransformStamped(), e.parent, e.child, stamp, t, q)
                                                   for e, t, q in rows]))
        self._sent = current
        return True

    # -- heartbeat ------------------------------------------------------------------------------
    def _start(self) -> None:
        if self._thread is None and not self._stop.is_set():
            self._thread = threading.Thread(target=self._run, name="uniros-tf", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        beats = 0
        while not self._stop.is_set():
            woken = self._wake.wait(HEARTBEAT_SEC)
            self._wake.clear()
            beats += 1
            if self._stop.is_set():
                return
            with self._lock:
                if self._stop.is_set():
                    return
                try:
                    # A listener that came since the last message (any change of the graph, or of the
                    # number of /tf and /tf_static subscriptions where the transport keeps no graph version).
                    listeners = (self._tf.get_subscription_count(), self._static.get_subscription_count(),
                                 self._node.context.transport.graph_version())
                    came = listeners != self._listeners
                    # Static transforms change only when an entity comes, goes or is moved (each wakes
                    # this thread while anyone listens); checked when a listener comes (a move nobody
                    # heard of is sent then) and every 2 s besides.
                    if woken or came or beats % _STATIC_CHECK_BEATS == 0:
                        self.publish_static()
                    if self._dirty or came:
                        self._listeners = listeners
                        self.publish()
                    problem = ""
                except Exception as exc:  # noqa: BLE001 - report it (once), keep the node up
                    problem = f"TF not published: {exc}"
            if problem and problem != self._problem and not self._stop.is_set():
                self._warn(problem)
            self._problem = problem

    _problem = ""

    def close(self) -> None:
        """Stop the heartbeat and destroy the publishers."""
        self._stop.set()
        self._wake.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=5.0)
        self._entities.clear()
        self._owners.clear()
        for pub in (self._tf, self._static):
            self._node.destroy_publisher(pub)
