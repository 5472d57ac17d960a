"""ros2_control-style controllers driven by the world at each control tick.

Controllers never touch MuJoCo. They read and write a :class:`RobotHardware` (numpy arrays the
world fills with joint state and reads commands from). The world turns each joint's command into
a MuJoCo actuator: a position servo (``kp``, ``kd``), a velocity servo (``kv``) or a motor, clamped
to the joint's effort limit. MuJoCo servos are used rather than a Python PD loop because their
damping is integrated implicitly (``implicitfast``), which tracks stiffly and stays stable at the
default 2 ms step, and because a constant setpoint then needs no Python work per physics step.

Hand-written because ros2_control itself (C++, rclcpp) cannot run here; the YAML format, type
strings, lifecycle states and claiming rules follow ros2_control.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from multiros.sim.errors import CommandError, ControllerError

__all__ = [
    "JointMode",
    "RobotHardware",
    "Controller",
    "JointStateBroadcaster",
    "ForwardCommandController",
    "JointTrajectoryController",
    "CONTROLLER_TYPES",
]


class JointMode(enum.IntEnum):
    """How the world actuates a joint."""

    EFFORT = 0
    POSITION = 1
    VELOCITY = 2


class RobotHardware:
    """Joint state and command buffers of one robot, shared between the world and its controllers.

    Args:
        joint_names: the robot's actuatable joints.
        lower, upper: position limits (+-inf when unlimited).
        effort_limit: effort limits (0 = unlimited).
        velocity_limit: velocity limits (0 = unknown).
        kp, kd, kv: servo gains per joint (position stiffness, position damping, velocity gain).
    """

    def __init__(self, joint_names: Sequence[str], lower: np.ndarray, upper: np.ndarray,
                 effort_limit: np.ndarray, velocity_limit: np.ndarray, kp: np.ndarray, kd: np.ndarray,
                 kv: np.ndarray) -> None:
        self.joint_names = tuple(joint_names)
        n = len(self.joint_names)
        self._index = {name: i for i, name in enumerate(self.joint_names)}
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.effort_limit, self.velocity_limit = np.asarray(effort_limit, float), np.asarray(velocity_limit, float)
        self.kp, self.kd, self.kv = np.asarray(kp, float), np.asarray(kd, float), np.asarray(kv, float)
        self.position, self.velocity, self.effort = np.zeros(n), np.zeros(n), np.zeros(n)
        self.command = np.zeros(n)
        self.command_velocity = np.zeros(n)  # velocity feed-forward of position setpoints (trajectories)
        self.mode = np.full(n, int(JointMode.EFFORT), dtype=np.int8)
        self.dirty = True  # modes or gains changed: the world rewrites actuator parameters

    def indices(self, names: Iterable[str], *, what: str = "joint") -> np.ndarray:
        """Indices of joint names; raises ControllerError naming the unknown ones."""
        names = list(names)
        missing = [n for n in names if n not in self._index]
        if missing:
            raise ControllerError(f"unknown {what}(s) {missing}; the robot's joints are {list(self.joint_names)}")
        return np.array([self._index[n] for n in names], dtype=np.intp)

    def set_mode(self, idx: np.ndarray, mode: JointMode, command: np.ndarray | float) -> None:
        self.mode[idx] = int(mode)
        self.command[idx] = command
        self.command_velocity[idx] = 0.0
        self.dirty = True

    def set_gains(self, idx: int, *, p: float | None = None, d: float | None = None, v: float | None = None) -> None:
        for arr, value in ((self.kp, p), (self.kd, d), (self.kv, v)):
            if value is not None:
                arr[idx] = float(value)
        self.dirty = True


def _check_vector(values: Sequence[float], n: int, what: str) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float)
        if arr.ndim != 1:
            arr = arr.reshape(-1)
    except (TypeError, ValueError) as exc:
        raise CommandError(f"{what}: command is not a vector of numbers ({exc})") from exc
    if arr.shape[0] != n:
        raise CommandError(f"{what}: command has {arr.shape[0]} values, expected {n} (one per joint)")
    if not _all_finite(arr):
        raise CommandError(f"{what}: command contains NaN or infinite values: {arr.tolist()}")
    return arr


def _all_finite(arr: np.ndarray) -> bool:
    """``np.isfinite(arr).all()`` of a 1-D float array; for the few values of one robot's command
    (every robot, every step) through Python floats, in a fifth of numpy's time."""
    if arr.shape[0] > 64:
        return bool(np.isfinite(arr).all())
    return all(map(math.isfinite, arr.tolist()))


# ------------------------------------------------------------------------------------------ controllers
class Controller:
    """Base class: a named controller over some joints with ros2_control lifecycle states."""

    type_name = ""
    time_varying = False  # True when update() must run at every control tick

    def __init__(self, name: str, params: Mapping | None = None) -> None:
        self.name = name
        self.params = dict(params or {})
        self.joints: tuple[str, ...] = tuple(self.params.get("joints", ()))
        self.state = "unconfigured"
        self.hw: RobotHardware | None = None
        self.idx = np.zeros(0, dtype=np.intp)

    @property
    def command_interfaces(self) -> tuple[str, ...]:
        """Interfaces this controller claims when active (``"<joint>/<interface>"``)."""
        return ()

    @property
    def state_interfaces(self) -> tuple[str, ...]:
        ifaces = self.params.get("state_interfaces", ("position", "velocity", "effort"))
        return tuple(f"{j}/{i}" for j in self.joints for i in ifaces)

    def configure(self, hw: RobotHardware) -> None:
        if not self.joints:
            self.joints = hw.joint_names
        self.idx = hw.indices(self.joints)
        self.hw = hw

    def activate(self, time: float) -> None:
        """Take over the claimed joints (hook)."""

    def deactivate(self) -> None:
        """Release the claimed joints (hook)."""

    def update(self, time: float) -> None:
        """Write setpoints for ``time`` (hook; only called when ``time_varying``)."""

    def hold(self) -> None:
        """Re-take the current joint positions as setpoint (after a teleport or reset)."""

    def set_command(self, values: Sequence[float], time: float) -> None:
        raise ControllerError(f"controller '{self.name}' ({self.type_name}) takes no command vector")


class JointStateBroadcaster(Controller):
    """Marks which joints are reported in ``joint_states`` (all joints when ``joints`` is empty)."""

    type_name = "joint_state_broadcaster/JointStateBroadcaster"


class ForwardCommandController(Controller):
    """Forwards a command vector (controller joint order) to one interface of its joints.

    Params: ``joints``, ``interface_name`` (``position``, ``velocity`` or ``effort``). Position
    commands are clamped to the joint limits; efforts to the effort limits by the actuator.
    """

    type_name = "forward_command_controller/ForwardCommandController"
    default_interface = ""

    def __init__(self, name: str, params: Mapping | None = None) -> None:
        super().__init__(name, params)
        self.interface = str(self.params.get("interface_name", self.default_interface))
        if self.interface not in ("position", "velocity", "effort"):
            raise ControllerError(f"controller '{name}': interface_name '{self.interface}' is not one of "
                                  f"position, velocity, effort")
        self.mode = {"position": JointMode.POSITION, "velocity": JointMode.VELOCITY,
                     "effort": JointMode.EFFORT}[self.interface]
        self._limit_cache: tuple[RobotHardware, np.ndarray, np.ndarray, np.ndarray, slice | np.ndarray] | None = None

    @property
    def command_interfaces(self) -> tuple[str, ...]:
        return tuple(f"{j}/{self.interface}" for j in self.joints)

    def activate(self, time: float) -> None:
        hw = self.hw
        hold = hw.position[self.idx] if self.mode == JointMode.POSITION else 0.0
        hw.set_mode(self.idx, self.mode, hold)

    def deactivate(self) -> None:
        self.hw.set_mode(self.idx, JointMode.EFFORT, 0.0)

    def hold(self) -> None:
        if self.mode == JointMode.POSITION:
            self.hw.command[self.idx] = self.hw.position[self.idx]
        else:
            self.hw.command[self.idx] = 0.0

    def set_command(self, values: Sequence[float], time: float) -> None:
        lower, upper, where = self._limits()
        arr = _check_vector(values, len(lower), f"controller '{self.name}'")
        if self.mode == JointMode.POSITION:
            arr = np.minimum(np.maximum(arr, lower), upper)  # np.clip, faster
        self.hw.command[where] = arr

    def _limits(self) -> tuple[np.ndarray, np.ndarray, slice | np.ndarray]:
        """The position limits of this controller's joints (the hardware's never change in place)
        and where they sit in the hardware's arrays (a slice when consecutive), gathered again only
        when its hardware or joints do."""
        cached = self._limit_cache
        if cached is None or cached[0] is not self.hw or cached[1] is not self.idx:
            idx = self.idx
            run = len(idx) > 0 and bool(np.all(np.diff(idx) == 1))
            where = slice(int(idx[0]), int(idx[-1]) + 1) if run else idx
            cached = self._limit_cache = (self.hw, idx, self.hw.lower[idx], self.hw.upper[idx], where)
        return cached[2], cached[3], cached[4]


class JointGroupPositionController(ForwardCommandController):
    type_name = "position_controllers/JointGroupPositionController"
    default_interface = "position"


class JointGroupVelocityController(ForwardCommandController):
    type_name = "velocity_controllers/JointGroupVelocityController"
    default_interface = "velocity"


class JointGroupEffortController(ForwardCommandController):
    type_name = "effort_controllers/JointGroupEffortController"
    default_interface = "effort"


class JointTrajectoryController(Controller):
    """Follows a joint trajectory; holds the last point afterwards.

    Params: ``joints``, ``command_interfaces`` (claimed; tracking is by the position servo),
    ``interpolation_method``: ``splines`` (cubic Hermite where the points carry velocities,
    linear otherwise; the default) or ``linear``/``none``.
    The trajectory starts at the command's sim time, from the current setpoint.
    """

    type_name = "joint_trajectory_controller/JointTrajectoryController"
    time_varying = True

    def __init__(self, name: str, params: Mapping | None = None) -> None:
        super().__init__(name, params)
        self.interfaces = tuple(self.params.get("command_interfaces", ("position",)))
        self.cubic = str(self.params.get("interpolation_method", "splines")) not in ("linear", "none")
        self._times = np.zeros(1)
        self._pos = np.zeros((1, 0))
        self._vel: np.ndarray | None = None
        self._start = 0.0
        self._seg = 0

    @property
    def command_interfaces(self) -> tuple[str, ...]:
        return tuple(f"{j}/{i}" for j in self.joints for i in self.interfaces)

    def activate(self, time: float) -> None:
        self.hw.set_mode(self.idx, JointMode.POSITION, self.hw.position[self.idx])
        self._hold_at(self.hw.position[self.idx].copy(), time)

    def deactivate(self) -> None:
        self.hw.set_mode(self.idx, JointMode.EFFORT, 0.0)

    def hold(self) -> None:
        current = self.hw.position[self.idx].copy()
        self.hw.command[self.idx] = current
        self.hw.command_velocity[self.idx] = 0.0
        self._hold_at(current, self._start)

    def _hold_at(self, positions: np.ndarray, time: float) -> None:
        self._times, self._pos, self._vel, self._start, self._seg = np.zeros(1), positions[None, :], None, time, 0

    def set_command(self, values: Sequence[float], time: float) -> None:
        """A bare vector is a one-point trajectory reached immediately (a setpoint step)."""
        arr = _check_vector(values, len(self.idx), f"controller '{self.name}'")
        self._hold_at(np.clip(arr, self.hw.lower[self.idx], self.hw.upper[self.idx]), time)
        self.hw.command[self.idx] = self._pos[0]
        self.hw.command_velocity[self.idx] = 0.0

    def set_trajectory(self, joint_names: Sequence[str], positions: Sequence[Sequence[float]],
                       times_from_start: Sequence[float], velocities: Sequence[Sequence[float]] | None = None,
                       *, time: float) -> None:
        """Replace the trajectory. ``joint_names`` may be in any order but must cover the
        controller's joints; ``times_from_start`` strictly increasing, >= 0.

        Raises:
            CommandError: unknown/missing joints, wrong shapes, NaN/inf, bad times (nothing applied).
        """
        what = f"controller '{self.name}'"
        names = list(joint_names)
        if sorted(names) != sorted(self.joints) or len(set(names)) != len(names):
            raise CommandError(f"{what}: trajectory joints {names} must be exactly {list(self.joints)}")
        order = np.array([names.index(j) for j in self.joints], dtype=np.intp)
        times = np.asarray(times_from_start, dtype=float).reshape(-1)
        k = times.shape[0]
        if k == 0:
            raise CommandError(f"{what}: trajectory has no points")
        if not np.all(np.isfinite(times)) or np.any(times < 0) or np.any(np.diff(times) <= 0):
            raise CommandError(f"{what}: time_from_start must be finite, >= 0 and strictly increasing: "
                               f"{times.tolist()}")
        pos = np.stack([_check_vector(p, len(names), f"{what} point {i} positions")
                        for i, p in enumerate(positions)]) if len(positions) == k else None
        if pos is None:
            raise CommandError(f"{what}: {len(positions)} position vectors for {k} points")
        vel = None
        if velocities is not None and len(velocities) > 0:
            if len(velocities) != k:
                raise CommandError(f"{what}: {len(velocities)} velocity vectors for {k} points")
            vel = np.stack([_check_vector(v, len(names), f"{what} point {i} velocities")
                            for i, v in enumerate(velocities)])[:, order]
        pos = np.clip(pos[:, order], self.hw.lower[self.idx], self.hw.upper[self.idx])
        start_pos = self.hw.command[self.idx].copy()
        self._times = np.concatenate(([0.0], times)) if times[0] > 0 else times
        self._pos = np.vstack([start_pos, pos]) if times[0] > 0 else pos
        if vel is not None:
            self._vel = np.vstack([np.zeros(len(self.idx)), vel]) if times[0] > 0 else vel
        else:
            self._vel = None
        self._start, self._seg = time, 0

    def update(self, time: float) -> None:
        t = time - self._start
        times, n = self._times, self._times.shape[0]
        if n == 1 or t >= times[-1]:
            self.hw.command[self.idx] = self._pos[-1]
            self.hw.command_velocity[self.idx] = 0.0
            return
        if t <= times[0]:
            self.hw.command[self.idx] = self._pos[0]
            self.hw.command_velocity[self.idx] = 0.0
            return
        seg = self._seg
        while seg + 1 < n - 1 and t >= times[seg + 1]:
            seg += 1
        self._seg = seg
        t0, t1 = times[seg], times[seg + 1]
        h = t1 - t0
        s = (t - t0) / h
        p0, p1 = self._pos[seg], self._pos[seg + 1]
        if self.cubic and self._vel is not None:
            v0, v1 = self._vel[seg] * h, self._vel[seg + 1] * h
            s2, s3 = s * s, s * s * s
            self.hw.command[self.idx] = ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * v0
                                         + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * v1)
            self.hw.command_velocity[self.idx] = ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * v0
                                                  + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * v1) / h
        else:
            self.hw.command[self.idx] = p0 + s * (p1 - p0)
            self.hw.command_velocity[self.idx] = (p1 - p0) / h

    @property
    def done(self) -> bool:
        return True if self._times.shape[0] == 1 else bool(self._seg >= self._times.shape[0] - 2)


CONTROLLER_TYPES: dict[str, type[Controller]] = {
    cls.type_name: cls for cls in (JointStateBroadcaster, ForwardCommandController, JointGroupPositionController,
                                   JointGroupVelocityController, JointGroupEffortController,
                                   JointTrajectoryController)
}
