"""Stepping robots of one simulation node from a client: one API whether the node is composed in
this process or runs elsewhere.

A :class:`RobotStepper` takes, per robot, an optional reset, its controller commands and the frames
it wants (:class:`~multiros.sim.client.RobotStepSpec`), advances the world ``steps`` physics steps
and returns every robot's state (:class:`StepReply`). Two implementations:

* :class:`ComposedStepper`, for a node in this process: the node's own ``StepRobots`` call
  (:class:`~multiros.sim.node_stepping.StepRobotsCall`), with no request, response, joint state or
  pose messages built and read back, as rclcpp's intra-process communication skips serialisation.
  The states of robots alike are read in one gather per array
  (:class:`~multiros.sim.state_gather.StateGather`) into one :class:`~multiros.robot_state.RobotStates`.
* :class:`ServiceStepper`, for a node anywhere else: the ``StepRobot`` service (one robot) or
  ``StepRobots`` (several), over the context's transport.

Both answer the same :class:`StepReply` for the same request, bit for bit (``tests/sim/test_stepper.py``).
A call runs in three phases (:class:`PendingStep`): ``begin`` (a composed node's lock is taken and
the commands applied), ``advance`` (the physics; any thread: ``mj_step`` releases the GIL) and
``finish`` (the states read, the lock released), so a batch over several nodes runs their physics
at once (:mod:`multiros.envs.batch`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from multiros.robot_state import RobotState, RobotStates
from multiros.sim import convert
from multiros.sim.client import RobotStepSpec, SimulationClient, SimulationServiceError, time_seconds
from multiros.sim.distro_adapters import get_message
from multiros.sim.node_stepping import ResolvedRobots, StepRobotsCall, StepRobotsRefused

if TYPE_CHECKING:
    from multiros.sim.frames import FrameSet
    from multiros.sim.node import SimulationNode

__all__ = ["StepReply", "PendingStep", "RobotStepper", "ComposedStepper", "ServiceStepper", "OK", "UNSTABLE"]

RobotStepResult: Any = get_message("uniros_interfaces/msg/RobotStepResult")

OK = int(RobotStepResult.OK)
UNSTABLE = int(RobotStepResult.UNSTABLE)
UNKNOWN_ROBOT = int(RobotStepResult.UNKNOWN_ROBOT)


@dataclass(slots=True)
class StepReply:
    """The answer to one step call, robot by robot in the order asked.

    Attributes:
        sim_time: simulation time after the steps (as the services' ``builtin_interfaces/Time`` carries it).
        status: per robot, a ``uniros_interfaces/msg/RobotStepResult`` code (``OK``; ``UNSTABLE``: physics
            diverged and the robot was restored at rest; others: its part was refused).
        message: per robot, the node's explanation when its status is not ``OK``.
        states: per robot, its state (``None`` for a robot the node does not know); made from
            ``stacked`` on first use when it is given.
        stacked: the same states as rows of one :class:`~multiros.robot_state.RobotStates` when every
            robot is known and alike (``states[j]`` is then ``stacked.row(j)``), else ``None``.
    """

    sim_time: float
    status: list[int]
    message: list[str]
    _states: list[RobotState | None] | None
    stacked: RobotStates | None = None

    @property
    def states(self) -> list[RobotState | None]:
        if self._states is None:
            assert self.stacked is not None
            self._states = list(self.stacked.rows())
        return self._states


class PendingStep(ABC):
    """One step call under way (see the module docstring for its phases)."""

    @abstractmethod
    def advance(self) -> None:
        """Run the physics (any thread)."""

    @abstractmethod
    def finish(self) -> StepReply:
        """The robots' states; ends the call (on the thread that began it)."""

    def close(self) -> None:  # noqa: B027 - optional hook: release what begin took, after an error
        """Release what the call holds, if it did not finish (idempotent)."""


class RobotStepper(ABC):
    """Steps robots of one simulation node (see the module docstring)."""

    #: Whether the node is composed in this process (no messages on the way).
    composed: bool = False

    @abstractmethod
    def begin(self, robots: Sequence[RobotStepSpec], steps: int) -> PendingStep:
        """Start a call: per robot its reset and commands, then ``steps`` physics steps for the world.

        Raises:
            SimulationServiceError: the call as a whole is refused (too many steps or robots, a
                running simulation with ``steps > 0``, ...); nothing was applied.
            SimulationNodeError: the node cannot be reached.
        """

    def step(self, robots: Sequence[RobotStepSpec], steps: int) -> StepReply:
        """:meth:`begin`, ``advance`` and ``finish`` in a row."""
        call = self.begin(robots, steps)
        try:
            call.advance()
            return call.finish()
        finally:
            call.close()


# -- composed --------------------------------------------------------------------------------------
class ComposedStepper(RobotStepper):
    """A node composed in this process, called without messages (see the module docstring). Its
    calls come one after another (one client): the robots and frame sets its last robot list
    resolved are reused while they stand (:class:`~multiros.sim.node_stepping.ResolvedRobots`)."""

    composed = True

    def __init__(self, node: SimulationNode) -> None:
        self.node = node
        self._resolved = ResolvedRobots()
        # the robot names and frame sets of the last robot list read, as the state gather's key (the
        # same objects while the list stands, so the gather finds its indices at once)
        self._gather_key: tuple[Any, tuple[str, ...], tuple[FrameSet | None, ...]] | None = None

    def begin(self, robots: Sequence[RobotStepSpec], steps: int) -> PendingStep:
        try:  # the specs are the call's items: they have its fields (entity, reset, commands, frames)
            call = _ComposedCall(self, StepRobotsCall(self.node, robots, int(steps), self._resolved))
        except StepRobotsRefused as exc:
            raise _refused(self.node, exc) from exc
        call.prepare()
        return call

    def step(self, robots: Sequence[RobotStepSpec], steps: int) -> StepReply:
        """The call's phases in a row on this thread (:meth:`StepRobotsCall.run`), with no pending
        call between them: what :meth:`begin`, ``advance`` and ``finish`` do, with less on the way."""
        try:
            call = StepRobotsCall(self.node, robots, int(steps), self._resolved)
        except StepRobotsRefused as exc:
            raise _refused(self.node, exc) from exc
        reader = _ComposedCall(self, call)
        try:
            return reader.reply(call.run(reader._read)[0])
        except StepRobotsRefused as exc:
            raise _refused(self.node, exc) from exc

    def gather_key(self, prepared: Sequence[tuple[Any, FrameSet | None]]) -> tuple[tuple[str, ...],
                                                                                tuple[FrameSet | None, ...]]:
        """The names and frame sets of ``prepared`` robots (all known), kept while ``prepared`` is the same list."""
        key = self._gather_key
        if key is None or key[0] is not prepared:
            key = self._gather_key = (prepared, tuple(robot.name for robot, _ in prepared),
                                      tuple(frame_set for _, frame_set in prepared))
        return key[1], key[2]


def _refused(node: SimulationNode, exc: StepRobotsRefused) -> SimulationServiceError:
    return SimulationServiceError(f"{node.get_fully_qualified_name()}/step_robots", exc.code, exc.message)


class _ComposedCall(PendingStep):
    def __init__(self, stepper: ComposedStepper, call: StepRobotsCall) -> None:
        self.stepper = stepper
        self.node = stepper.node
        self.call = call
        self.stacked: RobotStates | None = None
        self.time = 0.0

    def prepare(self) -> None:
        try:
            self.call.prepare()
        except BaseException:
            self.call.close()
            raise

    def advance(self) -> None:
        self.call.advance()

    def finish(self) -> StepReply:
        try:
            parts, _ = self.call.finish(self._read)
        except StepRobotsRefused as exc:
            raise _refused(self.node, exc) from exc
        return self.reply(parts)

    def reply(self, parts: list[tuple[int, str, Any]]) -> StepReply:
        """The reply from the call's parts (and what :meth:`_read` kept)."""
        t = self.time
        status = [int(code) for code, _, _ in parts]
        message = [msg for _, msg, _ in parts]
        stacked = self.stacked
        if stacked is not None:
            return StepReply(t, status, message, None, stacked)
        return StepReply(t, status, message, [None if part is None else RobotState(t, *part) for _, _, part in parts],
                         None)

    def close(self) -> None:
        self.call.close()

    def _read(self, prepared: Sequence[tuple[Any, FrameSet | None]]) -> list[tuple[Any, ...] | None]:
        """Every robot's state fields but the time: rows of one gather (kept as ``stacked``) when all
        the robots are known and alike, else robot by robot (lock held)."""
        node = self.node
        world = node.world
        self.time = t = convert.time_seconds(world.time)  # the time the service's message would carry
        self.stacked = None
        if prepared and all(robot is not None for robot, _ in prepared):
            stacked = node.state_gather.read(*self.stepper.gather_key(prepared), t)
            if stacked is not None:
                self.stacked = stacked
                return [() for _ in prepared]  # the rows come from ``stacked`` (see finish)
        return [None if robot is None else _read_one(world, robot, frame_set) for robot, frame_set in prepared]


def _read_one(world: Any, robot: Any, frame_set: FrameSet | None) -> tuple[Any, ...]:
    poses = frame_set.pose_arrays() if frame_set is not None else (np.empty((0, 3)), np.empty((0, 4)))
    return (world.joint_names(robot.name), *world.joint_state_arrays(robot.name), *poses)


# -- over ROS ---------------------------------------------------------------------------------------
class ServiceStepper(RobotStepper):
    """A node reached over the context's transport: ``StepRobot`` for one robot without a reset,
    ``StepRobots`` otherwise.

    Args:
        client: the simulation node's client.
        timeout_sec: bound on each call (the client's by default).
    """

    def __init__(self, client: SimulationClient, timeout_sec: float | None = None) -> None:
        self.client = client
        self.timeout_sec = client.timeout_sec if timeout_sec is None else float(timeout_sec)

    def begin(self, robots: Sequence[RobotStepSpec], steps: int) -> PendingStep:
        return _ServiceCall(self, list(robots), int(steps))


class _ServiceCall(PendingStep):
    def __init__(self, stepper: ServiceStepper, robots: list[RobotStepSpec], steps: int) -> None:
        self.stepper = stepper
        self.robots = robots
        self.steps = steps
        self.reply: StepReply | None = None
        self.error: BaseException | None = None

    def advance(self) -> None:
        try:
            self.reply = self._call()
        except BaseException as exc:  # noqa: BLE001 - raised again by finish, on the caller's thread
            self.error = exc

    def finish(self) -> StepReply:
        if self.reply is None and self.error is None:
            self.advance()
        if self.error is not None:
            raise self.error
        assert self.reply is not None
        return self.reply

    def _call(self) -> StepReply:
        client, timeout = self.stepper.client, self.stepper.timeout_sec
        robots, steps = self.robots, self.steps
        if len(robots) == 1 and not robots[0].reset:
            spec = robots[0]
            try:
                state = client.step_robot(spec.entity, spec.commands, steps, spec.frames, timeout_sec=timeout)
            except SimulationServiceError as exc:
                if exc.code == UNSTABLE:  # the robot was restored at rest: its state is read at once
                    state = client.step_robot(spec.entity, None, 0, spec.frames, timeout_sec=timeout)
                    return StepReply(state.sim_time, [UNSTABLE], [exc.message], None, _one(state))
                raise
            return StepReply(state.sim_time, [OK], [""], None, _one(state))
        request = client.step_robots_request(robots, steps)
        response = client.step_robots_call(request, timeout)
        outcomes = client.step_robots_outcomes(request, response)
        states: list[RobotState | None] = [o.state for o in outcomes]
        known = [s for s in states if s is not None]
        stacked = RobotStates.of(known) if len(known) == len(states) else None
        t = time_seconds(response.sim_time)
        return StepReply(t, [o.status for o in outcomes], [o.message for o in outcomes],
                         None if stacked is not None else states, stacked)


def _one(state: RobotState) -> RobotStates:
    return RobotStates(state.sim_time, state.names, state.position[None], state.velocity[None], state.effort[None],
                       state.frame_positions[None], state.frame_orientations[None])
