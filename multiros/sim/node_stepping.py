"""The simulation node's stepping services: ``~/step_simulation``, the lockstep ``~/step_robot``
and its batched form ``~/step_robots`` (many robots, one round trip: a vector env's step).

Both refuse more than the node's ``max_steps_per_call`` steps and need a paused simulation to
advance time; the node's lock is held while the world steps (in chunks that stop when the node
shuts down, see ``SimulationNode._step_world``). StepRobot also applies controller commands before
the steps and returns joint state, sim time and the poses of the frames it names, whose frame sets
are kept in a bounded :class:`FrameSetCache`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

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

    def forget(self, entity: str) -> None:
        """Drop the frame sets of an entity (deleted, or re-created by a reset)."""
        for key in [k for k in self._sets if k[0] == entity]:
            del self._sets[key]


def too_many_steps(node: SimulationNode, steps: int, result: Any) -> bool:
    """True (with ``result`` set) when ``steps`` exceeds the node's ``max_steps_per_call``."""
    if steps <= node.max_steps_per_call:
        return False
    fail(result, FAILED, f"steps={steps} exceeds this node's max_steps_per_call ({node.max_steps_per_call}); "
         f"split the call, or start the node with a larger max_steps_per_call")
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
    """``uniros_interfaces/srv/StepRobot``: commands, then steps, then the robot's observation."""
    res = response.result
    steps = int(request.steps)
    if too_many_steps(node, steps, res):
        return response
    if len(request.frames) > _MAX_FRAMES:
        fail(res, response.UNKNOWN_FRAME, f"{len(request.frames)} frames requested; at most {_MAX_FRAMES}")
        return response
    if steps > 0 and node.simulation_state != SimulationState.STATE_PAUSED:
        fail(res, INCORRECT_STATE, "StepRobot with steps > 0 needs a paused simulation (lockstep mode)")
        return response
    entity = request.entity
    world = node.world
    with node.lock:
        robot = node._robots.get(entity)
        if robot is None:
            fail(res, NOT_FOUND, f"no robot {entity!r}; robots: {list(node._robots)}")
            return response
        try:
            for command in request.commands:
                world.set_command(entity, command.controller, command.command)
        except CommandError as exc:
            fail(res, response.BAD_COMMAND, str(exc))
            return response
        except ControllerError as exc:
            fail(res, response.UNKNOWN_CONTROLLER, str(exc))
            return response
        frames = tuple(request.frames)
        frame_set = None
        if frames:
            try:
                frame_set = node._frame_sets.get(world, entity, frames)
            except EntityError as exc:
                fail(res, response.UNKNOWN_FRAME, str(exc))
                return response
        if steps > 0:
            try:
                node._step_world(steps)
            except UnstableSimulationError as exc:
                fail(res, response.UNSTABLE, str(exc))
                return response
            except StepInterruptedError as exc:
                fail(res, FAILED, str(exc))
                return response
            node._after_step()
        robot.fill_joint_state(response.joint_state)
        response.sim_time = convert.time_msg(world.time)
        if frame_set is not None:
            response.frame_poses = [convert.pose_from_row(row) for row in frame_set.poses()]
    ok(res)
    return response


def step_robots(node: SimulationNode, request: Any, response: Any) -> Any:
    """``uniros_interfaces/srv/StepRobots``: per robot a reset and commands, one advance, every state.

    A robot's own failure (unknown robot, bad command, unknown frame, divergence) is reported in
    its ``RobotStepResult`` and leaves the others stepping; a diverging robot is restored at rest
    by the world (see ``World.step``) and the client resets it.
    """
    res = response.result
    steps = int(request.steps)
    items = list(request.robots)
    if too_many_steps(node, steps, res):
        return response
    if len(items) > node.max_robots:
        fail(res, FAILED, f"{len(items)} robots in one StepRobots request; this node holds at most "
             f"max_robots={node.max_robots}")
        return response
    names = [item.entity for item in items]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        fail(res, FAILED, f"robots {dup} appear more than once in one StepRobots request; list each robot once")
        return response
    for item in items:
        if len(item.frames) > _MAX_FRAMES:
            fail(res, FAILED, f"{len(item.frames)} frames requested for {item.entity!r}; at most {_MAX_FRAMES}")
            return response
    if steps > 0 and node.simulation_state != SimulationState.STATE_PAUSED:
        fail(res, INCORRECT_STATE, "StepRobots with steps > 0 needs a paused simulation (lockstep mode)")
        return response
    world = node.world
    results = [RobotStepResult() for _ in items]
    with node.lock:
        robots: list[Any] = []
        frame_sets: list[FrameSet | None] = []
        for item, out in zip(items, results):
            robot, frame_set = _prepare(node, world, item, out)
            robots.append(robot)
            frame_sets.append(frame_set)
        if steps > 0:
            try:
                node._step_world(steps)
            except UnstableSimulationError as exc:
                for item, out in zip(items, results):
                    if item.entity in exc.entities:
                        out.status, out.message = RobotStepResult.UNSTABLE, str(exc)
            except StepInterruptedError as exc:
                fail(res, FAILED, str(exc))
                return response
            node._after_step()
        for robot, frame_set, out in zip(robots, frame_sets, results):
            if robot is None:
                continue
            robot.fill_joint_state(out.joint_state)
            if frame_set is not None:
                out.frame_poses = [convert.pose_from_row(row) for row in frame_set.poses()]
        response.sim_time = convert.time_msg(world.time)
    response.robots = results
    ok(res)
    return response


def _prepare(node: SimulationNode, world: World, item: Any, out: Any) -> tuple[Any, FrameSet | None]:
    """Reset and command one robot of a StepRobots request (lock held); its interfaces and frame set."""
    entity = item.entity
    robot = node._robots.get(entity)
    if robot is None:
        out.status, out.message = RobotStepResult.UNKNOWN_ROBOT, f"no robot {entity!r}"
        return None, None
    if item.reset:
        world.reset_entity(entity)
        robot.on_reset()
    try:
        for command in item.commands:
            world.set_command(entity, command.controller, command.command)
    except CommandError as exc:
        out.status, out.message = RobotStepResult.BAD_COMMAND, str(exc)
    except ControllerError as exc:
        out.status, out.message = RobotStepResult.UNKNOWN_CONTROLLER, str(exc)
    frames = tuple(item.frames)
    if not frames:
        return robot, None
    try:
        return robot, node._frame_sets.get(world, entity, frames)
    except EntityError as exc:
        out.status, out.message = RobotStepResult.UNKNOWN_FRAME, str(exc)
        return robot, None
