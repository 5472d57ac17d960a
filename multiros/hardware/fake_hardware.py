"""Fake hardware in the spirit of ros2_control's ``mock_components``: joints that follow commands.

Each joint moves toward its commanded position with a first-order lag (time constant ``tau``),
never faster than its URDF velocity limit, and stays inside its URDF position limits. Velocity
commands are integrated (same caps); joints no controller commands hold where they are. Time is
the wall clock (``time.time()``), as on a real robot.

With a :class:`~multiros.hardware.gap.GapProfile` the joints are imperfect in known amounts
(:class:`~multiros.hardware.gap.JointGap`): commands take effect ``latency`` late, the servo droops
and the gear train has backlash, and the encoders (the hardware's positions) read the truth plus
calibration offsets; :meth:`FakeHardware.true_state` is the truth. Without one the joints are as
above, bit for bit.

The controllers are uniros' ros2_control-style controllers (:mod:`multiros.sim.controllers`, plain
numpy, no MuJoCo). :class:`FakeHardware` also offers the small "world" view that the simulation
node's FollowJointTrajectory servers (:class:`multiros.sim.actions.TrajectoryActions`) use, so both
stand-ins answer trajectory goals with the same rules.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from multiros.hardware.gap import GapProfile, JointGap, gap_generators
from multiros.hardware.robot_spec import RobotSpec
from multiros.sim.controller_manager import ControllerManager
from multiros.sim.controllers import JointMode, RobotHardware

__all__ = ["FakeHardware", "JointStateView", "DEFAULT_TIME_CONSTANT"]

#: Seconds for a joint to cover ~63 % of a position step (before velocity limits).
DEFAULT_TIME_CONSTANT = 0.1
_MAX_DT = 0.1  # a stalled loop (suspended process) must not make joints jump


@dataclass(frozen=True)
class JointStateView:
    """Copies of the hardware joints' state."""

    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


class FakeHardware:
    """The joints of one robot and its controller manager.

    Args:
        spec: the robot (joints, limits, initial positions, controllers YAML).
        time_constant: first-order lag of position tracking in seconds (0 = reach the command at
            the next update, velocity limits still apply); default: the gap's ``time_constant`` when
            it is > 0, else :data:`DEFAULT_TIME_CONSTANT`.
        clock: wall-clock source (seconds).
        gap: the reality gap of the joints (latency, backlash, droop, offsets; the profile's message
            keys are the fake robot's business), ``None`` for none.
        seed: seeds the gap's random parts (the offsets: :func:`~multiros.hardware.gap.gap_generators`).

    Raises:
        GapProfileError: ``droop_joints`` beyond the arm joints (:attr:`RobotSpec.arm`).

    Attributes:
        lock: held around every access to the hardware and its controllers.
    """

    hardware_plugin = "uniros/FakeSystem"  # the hardware component list_hardware_components names

    def __init__(self, spec: RobotSpec, *, time_constant: float | None = None,
                 clock: Callable[[], float] = time.time, gap: GapProfile | None = None, seed: int | None = 0) -> None:
        if time_constant is None:
            time_constant = gap.time_constant if gap is not None and gap.time_constant > 0 else DEFAULT_TIME_CONSTANT
        if not math.isfinite(time_constant) or time_constant < 0:
            raise ValueError(f"time_constant must be a finite number >= 0 seconds, got {time_constant}")
        self.spec = spec
        self.robot = spec.name
        self.time_constant = float(time_constant)
        self._clock = clock
        self.lock = threading.RLock()
        n = len(spec.joints)
        self.hw = RobotHardware(
            [j.name for j in spec.joints],
            np.array([j.lower for j in spec.joints]), np.array([j.upper for j in spec.joints]),
            np.zeros(n), np.array([j.velocity for j in spec.joints]), np.zeros(n), np.zeros(n), np.zeros(n),
        )
        self.hw.position[:] = [j.initial for j in spec.joints]
        self.hw.command[:] = self.hw.position
        self.cm = ControllerManager(self.hw, spec.controllers or None)
        names = list(self.hw.joint_names)
        self._mimic_idx = np.array([names.index(m.leader) for m in spec.mimics], dtype=np.intp)
        self._mimic_mul = np.array([m.multiplier for m in spec.mimics])
        self._mimic_off = np.array([m.offset for m in spec.mimics])
        self._mimic_lo = np.array([m.lower for m in spec.mimics])
        self._mimic_hi = np.array([m.upper for m in spec.mimics])
        self.gap = gap
        self._gap: JointGap | None = None
        if gap is not None and gap.acts_on_joints:
            self._gap = JointGap(gap, self.hw.position, self.hw.indices(spec.arm, what="arm joint"),
                                 gap_generators(seed)[0])

    @property
    def offsets(self) -> np.ndarray:
        """Calibration offsets per joint (encoder minus truth; zeros without a gap)."""
        return self._gap.offsets.copy() if self._gap is not None else np.zeros(len(self.hw.joint_names))

    # -- the "world" view used by TrajectoryActions and ControllerInterfaces -----------------------
    @property
    def time(self) -> float:
        """Now, wall clock (seconds since the epoch)."""
        return self._clock()

    def controller_manager(self, robot: str) -> ControllerManager:
        return self.cm

    def controllers_changed(self, robot: str) -> None:
        """Nothing to rebuild: modes and gains are read at every update."""

    def set_command(self, robot: str, controller: str, command: Sequence[float]) -> None:
        """Send a command vector to a controller, now (CommandError/ControllerError if refused)."""
        self.cm.set_command(controller, command, self.time)

    def joint_names(self, robot: str) -> tuple[str, ...]:
        return self.hw.joint_names

    def joint_state(self, robot: str | None = None) -> JointStateView:
        hw = self.hw
        return JointStateView(hw.position.copy(), hw.velocity.copy(), hw.effort.copy())

    # -- simulation --------------------------------------------------------------------------
    def start_controllers(self, names: list[str] | None = None) -> list[str]:
        """Load and configure every controller of the YAML; activate ``names`` (default: each one
        whose joints are still free, in file order). Returns the active ones."""
        with self.lock:
            if names is None:
                return self.cm.spawn(None, time=self.time)
            for name in self.cm.types:  # the others loaded and configured, inactive
                if name not in names:
                    self.cm.load(name)
                    self.cm.configure(name)
            return self.cm.spawn(names, time=self.time)

    def update(self, dt: float, now: float | None = None) -> None:
        """Advance ``dt`` seconds: controllers write commands for ``now``, joints follow them."""
        with self.lock:
            now = self.time if now is None else now
            dt = min(max(float(dt), 0.0), _MAX_DT)
            self.cm.update(now)
            hw = self.hw
            gap = self._gap
            # With a gap: the command interface as it was `latency` ago, the servo's side of the joints.
            command, mode = (hw.command, hw.mode) if gap is None else gap.delayed(now, hw.command, hw.mode)
            pos = hw.position if gap is None else gap.servo
            if dt <= 0.0:
                return
            target = pos.copy()
            position_mode = mode == int(JointMode.POSITION)
            velocity_mode = mode == int(JointMode.VELOCITY)
            alpha = 1.0 - math.exp(-dt / self.time_constant) if self.time_constant > 0 else 1.0
            setpoint = command if gap is None else gap.droop_target(command)
            target[position_mode] += alpha * (setpoint[position_mode] - pos[position_mode])
            target[velocity_mode] += command[velocity_mode] * dt
            step = target - pos
            capped = hw.velocity_limit > 0
            cap = hw.velocity_limit[capped] * dt
            step[capped] = np.clip(step[capped], -cap, cap)
            new = np.clip(pos + step, hw.lower, hw.upper)
            if gap is not None:
                new = gap.play(new, hw.position)  # the link, as the encoder reads it
            hw.velocity[:] = (new - hw.position) / dt
            hw.position[:] = new
            effort_mode = mode == int(JointMode.EFFORT)
            hw.effort[:] = np.where(effort_mode, command, 0.0)

    def published_state(self) -> tuple[list[float], list[float], list[float]]:
        """Positions, velocities and efforts of every published joint (mimic joints last), as the
        encoders read them."""
        with self.lock:
            hw = self.hw
            return self._published(hw.position, hw.velocity, hw.effort)

    def true_state(self) -> tuple[list[float], list[float], list[float]]:
        """:meth:`published_state` as the joints truly are (encoders minus their calibration offsets)."""
        with self.lock:
            hw = self.hw
            pos = hw.position if self._gap is None else self._gap.truth(hw.position)
            return self._published(pos, hw.velocity, hw.effort)

    def _published(self, pos: np.ndarray, vel: np.ndarray,
                   eff: np.ndarray) -> tuple[list[float], list[float], list[float]]:
        if self._mimic_idx.size:
            mpos = np.clip(self._mimic_mul * pos[self._mimic_idx] + self._mimic_off, self._mimic_lo, self._mimic_hi)
            mvel = self._mimic_mul * vel[self._mimic_idx]
            return (np.concatenate([pos, mpos]).tolist(), np.concatenate([vel, mvel]).tolist(),
                    np.concatenate([eff, np.zeros(self._mimic_idx.size)]).tolist())
        return pos.tolist(), vel.tolist(), eff.tolist()
