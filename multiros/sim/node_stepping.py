"""The simulation node's stepping services: ``~/step_simulation``, the lockstep ``~/step_robot``
and its batched form ``~/step_robots`` (many robots, one round trip: a vector env's step).

Both refuse more than the node's ``max_steps_per_call`` steps and need a paused simulation to
advance time; the node's lock is held while the world steps (in chunks that stop when the node
shuts down, see ``SimulationNode._step_world``). StepRobot also applies controller commands before
the steps and returns joint state, sim time and the poses of the frames it names, whose frame sets
are kept in a bounded :class:`FrameSetCache`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, TypeVar

from multiros.sim import convert
from multiros.sim.distro_adapters import get_message
from multiros.sim.errors import (
    CommandError,
    ControllerError,
    EntityError,
    StepInterruptedError,
    UnstableSimulationError,
)
from multiros.sim.node_results import FAILED, INCORRECT_STATE, NOT_FOUND, fail, ok

if TYPE_CHECKING:
    from multiros.sim.frames import FrameSet
    from multiros.sim.node import SimulationNode
    from multiros.sim.world import World

SimulationState = get_message("simulation_interfaces/msg/SimulationState")
RobotStepResult = get_message("uniros_interfaces/msg/RobotStepResult")

T = TypeVar("T")

_MAX_FRAMES = 1024  # frames per StepRobot request
_MAX_FRAME_SETS = 64  # cached frame lists (a new list per call must not grow memory without end)


class FrameSetCache:
    """The frame sets StepRobot requests named, by ``(entity, frames)``; emptied when it holds
    ``_MAX_FRAME_SETS`` of them, so distinct frame lists per call cannot grow memory without end."""

    def __init__(self, limit: int = _MAX_FRAME_SETS) -> None:
        self._sets: dict[tuple[str, tuple[str, ...]], FrameSet] = {}
        self._limit = max(1, int(limit))

    def get(self, world: World, entity: str, frames: tuple[str, ...]) -> FrameSet:
        """The cached frame set, else a new one (EntityError for an unknown entity or frame)."""
        key = (entity, frames)
        frame_set = self._sets.get(key)
        if frame_set is None or frame_set.stale:  # stale: an object whose frames it read was deleted
            frame_set = world.frame_set(frames, entity)
            if len(self._sets) >= self._limit:
                self._sets.clear()
            self._sets[key] = frame_set
        return frame_set

    def clear(self) -> None:
        """Forget every frame set."""
        self._sets.clear()

    def forget(self, entity: str) -> None:
        """Drop the frame sets of an entity (deleted, or re-created by a reset)."""
        for key in [k for k in self._sets if k[0] == entity]:
            del self._sets[key]


def too_many_steps_message(node: SimulationNode, steps: int) -> str:
    return (f"steps={steps} exceeds this node's max_steps_per_call ({node.max_steps_per_call}); "
            f"split the call, or start the node with a larger max_steps_per_call")


def too_many_steps(node: SimulationNode, steps: int, result: Any) -> bool:
    """True (with ``result`` set) when ``steps`` exceeds the node's ``max_steps_per_call``."""
    if steps <= node.max_steps_per_call:
        return False
    fail(result, FAILED, too_many_steps_message(node, steps))
    return True


def step_simulation(node: SimulationNode, request: Any, response: Any) -> Any:
    """``simulation_interfaces/srv/StepSimulation``: advance a paused simulation."""
    steps = int(request.steps)
    if too_many_steps(node, steps, response.result):
        return response
    if node.simulation_state != SimulationState.STATE_PAUSED:
        fail(response.result, FAILED, "StepSimulation needs a paused simulation; pause it first")
        return response
    with node.lock:
        try:
            node._step_world(steps)
        except (UnstableSimulationError, StepInterruptedError) as exc:
            fail(response.result, FAILED, str(exc))
            return response
        node._after_step()
    ok(response.result)
    return response


def step_robot(node: SimulationNode, request: Any, response: Any) -> Any:
    """``uniros_interfaces/srv/StepRobot``: commands, then steps, then the robot's observation.

    A StepRobots call of one robot (:class:`StepRobotsCall`, the one implementation) that stops
    before stepping when the robot's part is refused, with StepRobot's codes: an unknown robot
    ``NOT_FOUND``, a refused command or frame the robot's code; divergence ``UNSTABLE``.
    """
    res = response.result
    steps = int(request.steps)
    if too_many_steps(node, steps, res):
        return response
    if len(request.frames) > _MAX_FRAMES:
        fail(res, response.UNKNOWN_FRAME, f"{len(request.frames)} frames requested; at most {_MAX_FRAMES}")
        return response
    item = RobotStepItem(request.entity, False, {c.controller: c.command for c in request.commands},
                         tuple(request.frames))
    try:
        call = StepRobotsCall(node, [item], steps, stop_on_refusal=True)
    except StepRobotsRefused as exc:
        fail(res, exc.code, exc.message.replace("StepRobots", "StepRobot"))
        return response

    def read(prepared: Sequence[tuple[Any, FrameSet | None]]) -> list[Any]:
        robot, frame_set = prepared[0]
        return [None if robot is None else _fill_robot_state(response, robot, frame_set)]

    try:
        ((code, message, _),), sim_time = call.run(read)
    except StepRobotsRefused as exc:
        fail(res, exc.code, exc.message)
        return response
    if code == RobotStepResult.UNKNOWN_ROBOT:
        fail(res, NOT_FOUND, message)
    elif code != RobotStepResult.OK:
        fail(res, code, message)
    else:
        response.sim_time = convert.time_msg(sim_time)
        ok(res)
    return response


def _fill_robot_state(out: Any, robot: Any, frame_set: FrameSet | None) -> Any:
    """Write a robot's joint state and frame poses into a StepRobot response or a ``RobotStepResult``."""
    robot.fill_joint_state(out.joint_state)
    if frame_set is not None:
        out.frame_poses = [convert.pose_from_row(row) for row in frame_set.poses()]
    return out


class StepRobotsRefused(Exception):
    """A ``StepRobots`` call refused as a whole: its ``Result`` code and message."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


class RobotStepItem(NamedTuple):
    """One robot's part of a ``StepRobots`` call, out of its message. A composed client passes its
    :class:`~multiros.sim.client.RobotStepSpec` objects instead: they have the same fields."""

    entity: str
    reset: bool
    commands: Mapping[str, Any] | None  # controller -> command vector
    frames: Sequence[str]


class StepItem(Protocol):
    """What a call needs of each robot: a :class:`RobotStepItem` or a client's ``RobotStepSpec``."""

    @property
    def entity(self) -> str: ...

    @property
    def reset(self) -> bool: ...

    @property
    def commands(self) -> Mapping[str, Any] | None: ...

    @property
    def frames(self) -> Sequence[str]: ...


def _check_items(node: SimulationNode, items: Sequence[StepItem]) -> None:
    """Refuse a robot list the node cannot take: more robots than ``max_robots``, a robot twice,
    too many frames for one robot."""
    if len(items) > node.max_robots:
        raise StepRobotsRefused(FAILED, f"{len(items)} robots in one StepRobots request; this node holds "
                                f"at most max_robots={node.max_robots}")
    names = [item.entity for item in items]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise StepRobotsRefused(FAILED, f"robots {dup} appear more than once in one StepRobots request; "
                                "list each robot once")
    for item in items:
        if len(item.frames) > _MAX_FRAMES:
            raise StepRobotsRefused(FAILED, f"{len(item.frames)} frames requested for {item.entity!r}; at "
                                    f"most {_MAX_FRAMES}")


class ResolvedRobots:
    """The robots and frame sets of a composed client's last robot list, reused by its next calls
    while they still stand: the world's ids unchanged (``World.binding``), every robot the same
    object, no frame set stale. Kept by one client (its calls come one after another)."""

    def __init__(self) -> None:
        self.key: tuple[tuple[str, tuple[str, ...]], ...] | None = None
        self.binding = -1
        self.prepared: list[tuple[Any, FrameSet | None]] = []

    def holds(self, node: SimulationNode, key: tuple[tuple[str, tuple[str, ...]], ...]) -> bool:
        if key != self.key or node.world.binding != self.binding:
            return False
        robots = node._robots
        for robot, fs in self.prepared:
            if robots.get(robot.name) is not robot or (fs is not None and fs.stale):
                return False
        return True

    def keep(self, node: SimulationNode, key: tuple[tuple[str, tuple[str, ...]], ...],
             prepared: list[tuple[Any, FrameSet | None]]) -> None:
        if all(robot is not None for robot, _ in prepared) and all(
                fs is not None for (robot, fs), (_, frames) in zip(prepared, key) if frames):
            self.key, self.binding, self.prepared = key, node.world.binding, prepared
        else:
            self.key = None


class StepRobotsCall:
    """One ``StepRobots`` call in three phases: :meth:`prepare` (lock taken, resets and commands),
    :meth:`advance` (the physics), :meth:`finish` (every robot's state, lock released); :meth:`run`
    runs them in a row. The one implementation of ``StepRobots``, for its service and for composed
    clients (:class:`~multiros.sim.stepper.ComposedStepper`).

    :meth:`prepare` and :meth:`finish` run on one thread, which owns the node's lock in between;
    :meth:`advance` may run on another. A batched vector env over several composed nodes thus
    prepares each node on its own thread and runs each node's physics on a worker thread
    (``mj_step`` releases the GIL), so the Python of one node never waits for another node's.
    The lock still keeps every other caller out of the node for the whole call.

    Raises:
        StepRobotsRefused: from the constructor (nothing applied) or from :meth:`finish` (the node
            shut down while stepping), when the call as a whole is refused.
    """

    def __init__(self, node: SimulationNode, items: Sequence[StepItem], steps: int,
                 cache: ResolvedRobots | None = None, *, stop_on_refusal: bool = False) -> None:
        if steps > node.max_steps_per_call:
            raise StepRobotsRefused(FAILED, too_many_steps_message(node, steps))
        key = tuple([(item.entity, tuple(item.frames)) for item in items])
        if cache is None or cache.key != key:  # a robot list a cache already holds was checked then
            _check_items(node, items)
        if steps > 0 and node.simulation_state != SimulationState.STATE_PAUSED:
            raise StepRobotsRefused(INCORRECT_STATE, "StepRobots with steps > 0 needs a paused simulation "
                                    "(lockstep mode)")
        self.node, self.items, self.steps = node, items, steps
        self.key, self.cache = key, cache
        self.stop_on_refusal = stop_on_refusal  # StepRobot's rule: a refused part stops the call unstepped
        self.status = [RobotStepResult.OK] * len(items)
        self.message = [""] * len(items)
        self._prepared: list[tuple[Any, FrameSet | None]] = []
        self._interrupted: StepInterruptedError | None = None
        self._locked = False

    def prepare(self) -> None:
        """Take the node's lock, then reset and command each robot."""
        node = self.node
        node.lock.acquire()
        self._locked = True
        world = node.world
        cache = self.cache
        if cache is not None and cache.holds(node, self.key):
            for j, item in enumerate(self.items):  # robots and frame sets resolved by an earlier call
                _reset_and_command(node, world, item, self.status, self.message, j)
            self._prepared = cache.prepared
            return
        self._prepared = [_prepare(node, world, item, self.status, self.message, j)
                          for j, item in enumerate(self.items)]
        if cache is not None:
            cache.keep(node, self.key, self._prepared)

    def advance(self) -> None:
        """Step the world (any thread; the preparing thread holds the lock)."""
        if self.steps <= 0 or (self.stop_on_refusal and any(self.status)):
            return
        try:
            self.node._step_world(self.steps)
        except UnstableSimulationError as exc:
            for j, item in enumerate(self.items):
                if item.entity in exc.entities:
                    self.status[j], self.message[j] = RobotStepResult.UNSTABLE, str(exc)
                    if item.entity in exc.removed:  # gone from the world: no state to read
                        self._prepared[j] = (None, None)
        except StepInterruptedError as exc:
            self._interrupted = exc

    def finish(self, read: Callable[[Sequence[tuple[Any, FrameSet | None]]], Sequence[T | None]]
               ) -> tuple[list[tuple[int, str, T | None]], float]:
        """Publish the state topics, ``read`` the robots' states and release the lock.

        ``read`` gets each robot's ``(interfaces, frame set)`` (``(None, None)`` for an unknown
        robot) and returns their states in order (``None`` for an unknown robot).

        Returns:
            Per robot ``(status, message, state)``, and the simulation time after the steps.
        """
        try:
            if self._interrupted is not None:
                raise StepRobotsRefused(FAILED, str(self._interrupted)) from self._interrupted
            if self.stop_on_refusal and any(self.status):
                return list(zip(self.status, self.message, [None] * len(self.items))), self.node.world.time
            if self.steps > 0:
                self.node._after_step()
            states = read(self._prepared)
            return list(zip(self.status, self.message, states)), self.node.world.time
        finally:
            self.close()

    def close(self) -> None:
        """Release the node's lock if this call holds it (after an error between the phases)."""
        if self._locked:
            self._locked = False
            self.node.lock.release()

    def run(self, read: Callable[[Sequence[tuple[Any, FrameSet | None]]], Sequence[T | None]]
            ) -> tuple[list[tuple[int, str, T | None]], float]:
        """The three phases in a row on this thread; returns what :meth:`finish` returns."""
        try:
            self.prepare()
            self.advance()
            return self.finish(read)
        finally:
            self.close()


def step_robots(node: SimulationNode, request: Any, response: Any) -> Any:
    """``uniros_interfaces/srv/StepRobots``: per robot a reset and commands, one advance, every state.

    A robot's own failure (unknown robot, bad command, unknown frame, divergence) is reported in
    its ``RobotStepResult`` and leaves the others stepping; a diverging robot is restored at rest
    by the world (see ``World.step``) and the client resets it.
    """
    res = response.result
    items = [RobotStepItem(item.entity, bool(item.reset), {c.controller: c.command for c in item.commands},
                           tuple(item.frames)) for item in request.robots]

    def read(prepared: Sequence[tuple[Any, FrameSet | None]]) -> list[Any]:
        return [None if robot is None else _fill_robot_state(RobotStepResult(), robot, frame_set)
                for robot, frame_set in prepared]

    try:
        parts, sim_time = StepRobotsCall(node, items, int(request.steps)).run(read)
    except StepRobotsRefused as exc:
        fail(res, exc.code, exc.message)
        return response
    results = []
    for code, message, out in parts:
        out = RobotStepResult() if out is None else out
        out.status, out.message = code, message
        results.append(out)
    response.robots = results
    response.sim_time = convert.time_msg(sim_time)
    ok(res)
    return response


def _prepare(node: SimulationNode, world: World, item: StepItem, status: list[int], message: list[str],
             j: int) -> tuple[Any, FrameSet | None]:
    """Reset and command robot ``j`` of a StepRobots call (lock held); its interfaces and frame set."""
    entity = item.entity
    robot = node._robots.get(entity)
    if robot is None:
        status[j], message[j] = RobotStepResult.UNKNOWN_ROBOT, node.unknown_robot_message(entity)
        return None, None
    _reset_and_command(node, world, item, status, message, j)
    if not item.frames:
        return robot, None
    try:
        return robot, node._frame_sets.get(world, entity, tuple(item.frames))
    except EntityError as exc:
        status[j], message[j] = RobotStepResult.UNKNOWN_FRAME, str(exc)
        return robot, None


def _reset_and_command(node: SimulationNode, world: World, item: StepItem, status: list[int],
                       message: list[str], j: int) -> None:
    """Robot ``j``'s reset (when asked) and commands (lock held; the robot is known)."""
    entity = item.entity
    if item.reset:  # the robot and the objects spawned into its namespace (its task's table, cube, ...)
        robot = node._robots[entity]
        group = world.entities_in_namespace(robot.ns) if robot.ns else ()
        world.reset_entities(group or (entity,))
        for name in group or (entity,):
            member = node._robots.get(name)
            if member is not None:
                member.on_reset()
    commands = item.commands
    try:
        if commands:
            for controller, command in commands.items():
                world.set_command(entity, controller, command)
    except CommandError as exc:
        status[j], message[j] = RobotStepResult.BAD_COMMAND, str(exc)
    except ControllerError as exc:
        status[j], message[j] = RobotStepResult.UNKNOWN_CONTROLLER, str(exc)
