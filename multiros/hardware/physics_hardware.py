"""Physics behind the fake robot's driver names: a MuJoCo world of its own, stepped in real time.

:class:`~multiros.hardware.fake_hardware.FakeHardware` moves joints with a first-order lag and knows no
objects; a push or pick-and-place Real twin needs an object that the arm really pushes and grasps, with
masses and frictions that may differ from the simulation it was trained in. :class:`PhysicsHardware`
offers the same small "world" view as ``FakeHardware`` (what :class:`~multiros.hardware.fake_robot.FakeRobot`,
its controller-manager services and its FollowJointTrajectory servers use) over a
:class:`~multiros.sim.world.World` holding the robot, spawned with the driver's controllers, and the
task's other entities (a table, an object). The world's controllers are the simulation node's
ros2_control-style ones, so the driver's interfaces answer as the plain fake robot's do.

Time: the world's clock is the wall clock (``data.time`` starts at ``time.time()``), as a driver's
is: trajectories stamped by a client and the controllers' interpolation share one time base.
:meth:`PhysicsHardware.update` steps the world until its clock catches up with the wall clock (never
more than ``max_lag`` seconds at once: a paused process resumes without a burst).

A :class:`~multiros.hardware.gap.GapProfile` acts through the world's command shaping
(:mod:`multiros.sim.entity_properties`): ``latency`` and ``time_constant`` on the arm's commands, and
calibration ``offset`` (drawn as the plain fake robot draws them: the encoders read the truth plus the
offset, commands land in the encoders' frame), ``droop`` on the ``droop_joints`` as the shaping's
``droop`` (the servo settles that far short on the side it came from, and a command within it does not
move it: the plain fake robot's model), and ``backlash`` by its static effect, a dead band of its width
added to every arm joint's ``droop`` (the link's free play inside it under the physics' own dynamics
is not modelled). The message keys (noise, drops, late messages, jitter) stay the fake robot's business.

Physical properties (masses, frictions, damping, servo gains) are set through
:meth:`~multiros.sim.world.World.set_entity_properties`: scales of the spawned values.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from multiros.hardware.fake_hardware import JointStateView
from multiros.hardware.gap import GapProfile, GapProfileError, gap_generators
from multiros.hardware.robot_spec import RobotSpec
from multiros.sim.controller_manager import ControllerManager
from multiros.sim.errors import UnstableSimulationError
from multiros.sim.world import World, WorldOptions

__all__ = ["PhysicsEntity", "PhysicsHardware", "PropertyRow"]

_logger = logging.getLogger(__name__)

#: ``(target, name, property, value)``: a row of :meth:`~multiros.sim.world.World.set_entity_properties`.
PropertyRow = tuple[str, str, str, float]


@dataclass(frozen=True)
class PhysicsEntity:
    """An entity of the world besides the robot (a table, an object).

    Attributes:
        name: its entity name (letters, digits, ``_``).
        description: a ``package://`` URI or path of an MJCF/URDF file, or MJCF text.
        position: where its root is spawned, world frame (m).
        orientation: its root's orientation ``(w, x, y, z)``.
        frame: the body whose pose is the entity's (:meth:`PhysicsHardware.pose`), unprefixed.
    """

    name: str
    description: str
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    frame: str = ""


class PhysicsHardware:
    """The robot of ``spec`` and ``entities`` in a MuJoCo world, behind the fake robot's "world" view.

    Args:
        spec: the robot (joints, start positions, the driver's controllers YAML as a mapping).
        description: the robot's description (URI or path of a URDF/xacro/MJCF) as the world spawns it.
        xacro_args: its xacro arguments.
        base_position: where the robot's base stands in the world (m).
        entities: the other entities, spawned in order after the robot.
        timestep: the physics time step (s).
        gap: a reality gap (see the module docstring), ``None`` for none.
        seed: seeds the gap's calibration offsets (the plain fake robot's stream).
        clock: wall-clock source (seconds).
        max_lag: most seconds of physics one :meth:`update` catches up; more is skipped.

    Raises:
        DescriptionError, EntityError, ControllerError, ValueError: the robot or an entity cannot be spawned.

    Attributes:
        lock: held around every access to the world and its controllers.
        world: the :class:`~multiros.sim.world.World` (hold :attr:`lock` to touch it).
    """

    hardware_plugin = "uniros/MujocoSystem"  # the hardware component list_hardware_components names

    def __init__(self, spec: RobotSpec, description: str, *, xacro_args: Mapping[str, str] | None = None,
                 base_position: Sequence[float] = (0.0, 0.0, 0.0), entities: Sequence[PhysicsEntity] = (),
                 timestep: float = 0.002, gap: GapProfile | None = None, seed: int | None = 0,
                 clock: Callable[[], float] = time.time, max_lag: float = 0.1) -> None:
        if not (math.isfinite(max_lag) and max_lag > 0):
            raise ValueError(f"max_lag must be > 0 seconds, got {max_lag}")
        self.spec = spec
        self.robot = spec.name
        self.gap = gap
        self.lock = threading.RLock()
        self.max_lag = float(max_lag)
        self._clock = clock
        self.world = World(WorldOptions(timestep=timestep))
        initial = {j.name: j.initial for j in spec.joints}
        self.world.spawn(spec.name, description, pose=(tuple(base_position), (1.0, 0.0, 0.0, 0.0)),
                         xacro_args=dict(xacro_args or {}), joint_positions=initial, controllers=[],
                         controllers_yaml=spec.controllers or None)
        self.entities = {e.name: e for e in entities}
        for entity in entities:
            self.world.spawn(entity.name, entity.description, pose=(entity.position, entity.orientation))
        self.world.data.time = clock()
        self.steps = 0  # physics steps taken
        self.skipped = 0.0  # seconds of physics skipped (the loop fell more than max_lag behind)
        self.unstable = 0  # step calls the world reported diverging
        names = list(self.world.joint_names(spec.name))
        missing = [j for j in spec.published_joints if j not in names]
        if missing:
            raise ValueError(f"the physics model of {spec.name!r} has no joints {missing} (its joints: {names})")
        self._published_idx = np.array([names.index(j) for j in spec.published_joints], dtype=np.intp)
        arm = np.array([names.index(j) for j in spec.arm if j in names], dtype=np.intp)
        self._offsets = np.zeros(len(names))
        if gap is not None and gap.offset > 0:
            self._offsets[arm] = gap_generators(seed)[0].uniform(-gap.offset, gap.offset, arm.size)
        if gap is not None:
            self._shape(gap, [names[i] for i in arm])

    def _shape(self, gap: GapProfile, arm: Sequence[str]) -> None:
        """The gap's timing and offsets as the world's command shaping of the arm joints."""
        beyond = [i for i in gap.droop_joints if i >= len(arm)]
        if gap.droop > 0 and beyond:
            raise GapProfileError(f"gap key 'droop_joints': {beyond} beyond the {len(arm)} arm joints {list(arm)}")
        offsets = {n: float(self._offsets[i]) for i, n in enumerate(self.world.joint_names(self.robot))}
        rows: list[PropertyRow] = []
        if gap.latency > 0:
            rows.append(("command", "", "latency", float(gap.latency)))
        for k, joint in enumerate(arm):
            if gap.time_constant > 0:
                rows.append(("command", joint, "time_constant", float(gap.time_constant)))
            if offsets[joint]:
                rows.append(("command", joint, "offset", -offsets[joint]))  # encoder = truth + offset
            band = gap.backlash + (gap.droop if k in gap.droop_joints else 0.0)
            if band > 0:
                rows.append(("command", joint, "droop", float(band)))
        if rows:
            self.set_properties(self.robot, rows)

    # -- physical properties ------------------------------------------------------------------------
    def set_properties(self, entity: str, rows: Sequence[PropertyRow], *, restore: bool = False) -> int:
        """Set an entity's physical properties (rows of :mod:`multiros.sim.entity_properties`); the
        model values written. Raises EntityError or PropertyError (nothing changed)."""
        targets, names, props, values = zip(*rows) if rows else ((), (), (), ())
        with self.lock:
            return self.world.set_entity_properties(entity, targets, names, props, values, restore=restore)

    # -- the entities ------------------------------------------------------------------------------
    def pose(self, entity: str) -> tuple[np.ndarray, np.ndarray]:
        """World pose ``(xyz, quat wxyz)`` of an entity's frame (its root without one)."""
        with self.lock:
            frame = self.entities[entity].frame if entity in self.entities else ""
            if frame:
                return self.world.frame_pose(frame, entity)
            state = self.world.get_entity_state(entity)
            return state.position, state.orientation

    def place(self, entity: str, position: Sequence[float] | np.ndarray,
              orientation: Sequence[float] | np.ndarray = (1.0, 0.0, 0.0, 0.0)) -> None:
        """Teleport an entity's root, at rest (a hand putting an object down)."""
        with self.lock:
            self.world.set_entity_state(entity, position=[float(v) for v in position],
                                        orientation=[float(v) for v in orientation],
                                        linear_velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0))

    # -- the "world" view used by TrajectoryActions and ControllerInterfaces -----------------------
    @property
    def time(self) -> float:
        """The world's clock: the wall clock (seconds since the epoch) as of its last step."""
        return float(self.world.data.time)

    @property
    def offsets(self) -> np.ndarray:
        """Calibration offsets per joint of the world's robot (encoder minus truth)."""
        return self._offsets.copy()

    def controller_manager(self, robot: str) -> ControllerManager:
        return self.world.controller_manager(robot)

    def controllers_changed(self, robot: str) -> None:
        self.world.controllers_changed(robot)

    def set_command(self, robot: str, controller: str, command: Sequence[float]) -> None:
        """Send a command vector to a controller (CommandError/ControllerError if refused)."""
        self.world.set_command(robot, controller, command)

    def joint_names(self, robot: str | None = None) -> tuple[str, ...]:
        return self.world.joint_names(self.robot if robot is None else robot)

    def joint_state(self, robot: str | None = None) -> JointStateView:
        """The robot's joints as the encoders read them (copies)."""
        position, velocity, effort = self.world.joint_state_arrays(self.robot if robot is None else robot)
        return JointStateView(position + self._offsets, velocity, effort)

    # -- simulation --------------------------------------------------------------------------
    def start_controllers(self, names: list[str] | None = None) -> list[str]:
        """Load and configure every controller of the YAML; activate ``names`` (default: each one
        whose joints are still free, in file order). Returns the active ones."""
        with self.lock:
            cm = self.world.controller_manager(self.robot)
            if names is not None:
                for name in cm.types:  # the others loaded and configured, inactive
                    if name not in names:
                        cm.load(name)
                        cm.configure(name)
            active = cm.spawn(names, time=self.time)
            self.world.controllers_changed(self.robot)
            return active

    def update(self, dt: float = 0.0, now: float | None = None) -> None:
        """Step the world until its clock reaches ``now`` (default the wall clock); ``dt`` is not used
        (the world keeps its own time). More than ``max_lag`` behind, the rest is skipped."""
        with self.lock:
            now = self._clock() if now is None else now
            d = self.world.data
            step = self.world.timestep
            behind = now - d.time
            if behind > self.max_lag:
                self.skipped += behind - self.max_lag
                d.time = now - self.max_lag
                behind = self.max_lag
            n = int(behind / step)
            if n <= 0:
                return
            try:
                self.world.step(n)
            except UnstableSimulationError as exc:
                self.unstable += 1
                _logger.warning("physics: %s", exc)
            self.steps += n

    def published_state(self) -> tuple[list[float], list[float], list[float]]:
        """Positions, velocities and efforts of every published joint, as the encoders read them."""
        with self.lock:
            position, velocity, effort = self.world.joint_state_arrays(self.robot)
            idx = self._published_idx
            return (position + self._offsets)[idx].tolist(), velocity[idx].tolist(), effort[idx].tolist()

    def true_state(self) -> tuple[list[float], list[float], list[float]]:
        """:meth:`published_state` as the joints truly are."""
        with self.lock:
            position, velocity, effort = self.world.joint_state_arrays(self.robot)
            idx = self._published_idx
            return position[idx].tolist(), velocity[idx].tolist(), effort[idx].tolist()

    def close(self) -> None:
        """Release the world."""
        with self.lock:
            self.world.close()
