"""``uniros teleop ID``: drive any arm env by hand over ROS 2, in simulation or through its Real twin.

The input is a topic the user already has, or the keyboard:

* ``--joy TOPIC``: ``sensor_msgs/Joy`` (ROS 2's ``joy_node`` for a gamepad). Default mapping (an Xbox-style
  pad as joy_node reports it): left stick up/down moves the end effector along x, left/right along y,
  the right stick up/down along z; button 0 (A) closes the gripper, button 1 (B) opens it. ``--joy-map
  x=1,y=0,z=4,close=0,open=1`` changes it (axis and button indices; a ``-`` before an axis inverts it).
* ``--twist TOPIC``: ``geometry_msgs/Twist`` (``teleop_twist_keyboard``): ``linear.x/y/z`` move the end
  effector, ``angular.z`` opens (> 0) or closes (< 0) the gripper; ``--twist-scale`` is the speed that
  means a full step (teleop_twist_keyboard's default speed, 0.5).
* ``--keyboard``: keys in this terminal: ``w``/``s`` x, ``a``/``d`` y, ``r``/``f`` z, space toggles the
  gripper, ``q`` ends the session (a terminal only).

An input becomes the env's action: end-effector deltas in ``[-1, 1]`` (the env scales them by its
``ee_delta_coeff`` and keeps them in its workspace: a Real twin through its safety rules) and, for tasks
with a gripper, the gripper's target (-1 closed, +1 open, held until changed). A topic that falls silent
for :data:`STALE_AFTER` seconds stops the arm (zero motion; the gripper holds). The env needs end-effector
actions: reach envs are made with ``ee_action_type=True``.

:class:`TeleopPolicy` is the same mapping as a policy object (``policy(obs) -> action``), which
``uniros record ID --policy teleop`` uses to write the episodes a person drives.

Written here rather than taken from a library: ROS 2's teleop packages publish Joy and Twist, which this
reads; what turns them into an env's action is the env's own (its action layout, its gripper's sign).
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["JoyMapping", "STALE_AFTER", "TeleopInput", "TeleopPolicy", "add_teleop_parser", "main", "parse_joy_map",
           "subscribe", "teleop_env_kwargs"]

#: Seconds after the last message at which a silent input stops the arm.
STALE_AFTER = 0.5
_DEADZONE = 0.1  # stick travel (of 1) read as zero: a released stick rests near, not at, zero


class TeleopError(ValueError):
    """A bad teleoperation option or an env that cannot be driven by hand (one line)."""


@dataclass(frozen=True)
class JoyMapping:
    """Which Joy axes move x, y, z (a negative sign inverts) and which buttons close and open the gripper."""

    x: tuple[int, float] = (1, 1.0)
    y: tuple[int, float] = (0, 1.0)
    z: tuple[int, float] = (4, 1.0)
    close: int = 0
    open: int = 1


def parse_joy_map(text: str) -> JoyMapping:
    """``x=1,y=0,z=4,close=0,open=1`` (``-`` before an axis index inverts it) into a :class:`JoyMapping`."""
    values: dict[str, Any] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        key, sep, value = part.partition("=")
        key = key.strip()
        if not sep or key not in ("x", "y", "z", "close", "open"):
            raise TeleopError(f"--joy-map: {part[:40]!r} is not KEY=INDEX with KEY one of x, y, z, close, open")
        value = value.strip()
        sign = -1.0 if key in ("x", "y", "z") and value.startswith("-") else 1.0
        digits = value.lstrip("-")
        if not digits.isdigit() or int(digits) > 63:
            raise TeleopError(f"--joy-map: {key}={value[:20]!r}: an index is a whole number from 0 to 63")
        values[key] = (int(digits), sign) if key in ("x", "y", "z") else int(digits)
    return JoyMapping(**values)


class TeleopInput:
    """The latest command of a person: motion ``(3,)`` in ``[-1, 1]``, the gripper's target, and when.

    Messages arrive on another thread (a subscription's); the env's loop reads :meth:`command`.
    Everything from the wire is checked: a wrong length, NaN or infinite values leave the command as it was.
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._motion = np.zeros(3)
        self._gripper = 1.0  # open
        self._at = -math.inf
        self.messages = 0
        self.ignored = 0
        self.quit = False

    def set(self, motion: Sequence[float], gripper: float | None = None) -> None:
        m = np.clip(np.asarray(motion, dtype=np.float64).reshape(3), -1.0, 1.0)
        with self._lock:
            self._motion = m
            if gripper is not None:
                self._gripper = 1.0 if gripper > 0 else -1.0
            self._at = self._clock()
            self.messages += 1

    def command(self) -> tuple[np.ndarray, float]:
        """The motion (zero once the input has been silent for :data:`STALE_AFTER` s) and the gripper target."""
        with self._lock:
            fresh = self._clock() - self._at <= STALE_AFTER
            return (self._motion.copy() if fresh else np.zeros(3)), self._gripper

    # -- from messages ------------------------------------------------------------------------------------
    def on_joy(self, msg: Any, mapping: JoyMapping) -> None:
        axes, buttons = list(msg.axes), list(msg.buttons)
        needed = max(mapping.x[0], mapping.y[0], mapping.z[0])
        if len(axes) > 64 or len(buttons) > 64 or len(axes) <= needed or not all(map(math.isfinite, axes)):
            self.ignored += 1
            return

        def axis(spec: tuple[int, float]) -> float:
            value = float(axes[spec[0]]) * spec[1]
            return 0.0 if abs(value) < _DEADZONE else value

        gripper = None
        if mapping.close < len(buttons) and buttons[mapping.close]:
            gripper = -1.0
        elif mapping.open < len(buttons) and buttons[mapping.open]:
            gripper = 1.0
        self.set((axis(mapping.x), axis(mapping.y), axis(mapping.z)), gripper)

    def on_twist(self, msg: Any, scale: float) -> None:
        lin, ang = msg.linear, msg.angular
        values = [lin.x, lin.y, lin.z, ang.z]
        if not all(map(math.isfinite, values)):
            self.ignored += 1
            return
        gripper = None if ang.z == 0 else float(ang.z)
        self.set([v / scale for v in values[:3]], gripper)

    def on_key(self, key: str) -> None:
        moves = {"w": (1, 0, 0), "s": (-1, 0, 0), "a": (0, 1, 0), "d": (0, -1, 0), "r": (0, 0, 1), "f": (0, 0, -1)}
        if key == "q":
            self.quit = True
        elif key == " ":
            with self._lock:
                self._gripper = -self._gripper
            self.set((0.0, 0.0, 0.0))
        elif key in moves:
            self.set(moves[key])


class TeleopPolicy:
    """A person's input as a policy: ``policy(obs) -> action`` for an env of end-effector actions."""

    def __init__(self, source: TeleopInput, action_space: Any) -> None:
        shape = tuple(getattr(action_space, "shape", ()) or ())
        if shape not in ((3,), (4,)):
            raise TeleopError(f"teleoperation drives end-effector actions (3 numbers, and the gripper's as a 4th); "
                              f"this env's action space is {action_space}: make a reach env with ee_action_type=True")
        self.source, self.gripper = source, shape == (4,)

    def __call__(self, obs: Any = None) -> np.ndarray:
        motion, gripper = self.source.command()
        action = np.concatenate([motion, [gripper]]) if self.gripper else motion
        return action.astype(np.float32)


# -- the command ----------------------------------------------------------------------------------------------
def add_teleop_parser(sub: Any) -> None:
    p = sub.add_parser("teleop", help="drive an env by hand: a gamepad (Joy), teleop_twist_keyboard (Twist) or "
                                      "the keyboard, in simulation or through a Real twin")
    p.add_argument("env_id", metavar="ID", help="a registered ID (Sim, or Real for the robot)")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--joy", metavar="TOPIC", help="sensor_msgs/Joy topic (e.g. /joy)")
    source.add_argument("--twist", metavar="TOPIC", help="geometry_msgs/Twist topic (e.g. /cmd_vel)")
    source.add_argument("--keyboard", action="store_true", help="keys of this terminal (w/s, a/d, r/f, space, q)")
    p.add_argument("--joy-map", default="", metavar="MAP", help="x=1,y=0,z=4,close=0,open=1 (the default)")
    p.add_argument("--twist-scale", type=float, default=0.5, help="speed meaning a full step (%(default)s)")
    p.add_argument("--episodes", type=int, default=None, help="episodes to drive (default: until q or Ctrl-C)")
    p.add_argument("--viewer", action="store_true", help="show the MuJoCo viewer (simulation, with a display)")
    p.add_argument("--transport", choices=["zenoh", "rclpy"], help="ROS transport of the input topic")
    p.add_argument("--router", metavar="ENDPOINT", help="the Zenoh router to join (tcp/HOST:PORT)")
    p.set_defaults(func=_cmd_teleop)


def teleop_env_kwargs(env_id: str) -> dict[str, Any]:
    """The keywords that give ``env_id`` end-effector actions (reach takes ``ee_action_type=True``)."""
    import gymnasium as gym

    spec = gym.spec(env_id)
    task = (spec.kwargs or {}).get("task")
    return {"ee_action_type": True} if task in ("reach", "frobs_reach") or "Reacher" in env_id else {}


def subscribe(context: Any, source: TeleopInput, opts: argparse.Namespace) -> Any:
    """A node on ``context`` feeding ``source`` from the Joy or Twist topic of ``opts``; returns the node."""
    from multiros.ros import Node
    from multiros.ros.interfaces import get_message

    node = Node(f"uniros_teleop_{time.monotonic_ns()}", context=context)
    if opts.joy:
        mapping = parse_joy_map(opts.joy_map) if opts.joy_map else JoyMapping()
        node.create_subscription(get_message("sensor_msgs/msg/Joy"), opts.joy,
                                 lambda msg: source.on_joy(msg, mapping), 10)
    elif opts.twist:
        if not (math.isfinite(opts.twist_scale) and opts.twist_scale > 0):
            raise TeleopError(f"--twist-scale must be a speed > 0, got {opts.twist_scale}")
        node.create_subscription(get_message("geometry_msgs/msg/Twist"), opts.twist,
                                 lambda msg: source.on_twist(msg, opts.twist_scale), 10)
    return node


def _keyboard(source: TeleopInput, stop: threading.Event) -> threading.Thread:
    import termios
    import tty

    if not sys.stdin.isatty():
        raise TeleopError("--keyboard reads this terminal's keys: stdin is not a terminal (use --joy or --twist)")
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)

    def run() -> None:
        import select

        tty.setcbreak(fd)
        try:
            while not stop.is_set() and not source.quit:
                ready, _, _ = select.select([sys.stdin], [], [], 0.1)
                if ready:
                    source.on_key(sys.stdin.read(1).lower())
        finally:
            termios.tcsetattr(fd, termios.TCSADRAIN, saved)

    thread = threading.Thread(target=run, name="uniros-teleop-keys", daemon=True)
    thread.start()
    return thread


def run_teleop(opts: argparse.Namespace, say: Callable[[str], None]) -> int:
    """Drive ``opts.env_id`` with the input ``opts`` names until the episodes are done, ``q`` or Ctrl-C."""
    import uniros
    from multiros.ros import Context
    from multiros.ros.processes import discovery_environment
    from multiros.ros.transport import wire_transport

    if opts.episodes is not None and opts.episodes < 1:
        raise TeleopError(f"--episodes must be at least 1, got {opts.episodes}")
    if opts.keyboard and not sys.stdin.isatty():
        raise TeleopError("--keyboard reads this terminal's keys: stdin is not a terminal (use --joy or --twist)")
    source = TeleopInput()
    transport = wire_transport(opts.transport)
    options: dict[str, Any] = {"router": opts.router} if opts.router and transport == "zenoh" else {}
    context = None if opts.keyboard else Context(transport=transport, env=discovery_environment(), **options).init()
    stop = threading.Event()
    env = None
    node = None
    try:
        extra: dict[str, Any] = {"context": context} if context is not None and "Real" in opts.env_id else {}
        env = uniros.make(opts.env_id, **teleop_env_kwargs(opts.env_id), **extra)
        policy = TeleopPolicy(source, env.action_space)
        if context is not None:
            node = subscribe(context, source, opts)
            from multiros.ros.executors import SingleThreadedExecutor

            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            threading.Thread(target=executor.spin, name="uniros-teleop-input", daemon=True).start()
        else:
            _keyboard(source, stop)
        core: Any = env.unwrapped
        if opts.viewer:
            core.connection.show_viewer()
        # A simulation steps as fast as it can: a person needs it at the robot's pace (a Real twin keeps its own).
        period = 0.0 if core.ON_ROBOT else float(core.connection.control_period)
        episode = 0
        while (opts.episodes is None or episode < opts.episodes) and not source.quit:
            obs, info = env.reset()
            done, steps = False, 0
            next_step = time.monotonic()
            while not done and not source.quit:
                next_step += period
                obs, _, terminated, truncated, info = env.step(policy(obs))
                done, steps = bool(terminated or truncated), steps + 1
                time.sleep(max(0.0, next_step - time.monotonic()))
            episode += 1
            say(f"episode {episode}: {'success' if info.get('is_success') else 'failure'}, {steps} steps "
                f"({source.messages} input messages, {source.ignored} ignored)")
    except KeyboardInterrupt:
        say("stopped (Ctrl-C)")
    finally:
        stop.set()
        if env is not None:
            env.close()
        if context is not None:
            context.try_shutdown()
    return 0


def _cmd_teleop(args: argparse.Namespace) -> int:
    return run_teleop(args, lambda text: print(text, flush=True))


def main(argv: Sequence[str] | None = None) -> int:
    """``uniros teleop`` alone (tests call it): its arguments without the subcommand's name."""
    parser = argparse.ArgumentParser(prog="uniros")
    add_teleop_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["teleop", *(sys.argv[1:] if argv is None else argv)])
    try:
        return int(args.func(args))
    except TeleopError as exc:
        print(f"uniros teleop: error: {exc}", file=sys.stderr)
        return 2
