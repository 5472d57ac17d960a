"""Actions served by the simulation node.

* ``<ns>/<controller>/follow_joint_trajectory`` (``control_msgs/action/FollowJointTrajectory``) for
  every joint trajectory controller of every robot, as ros2_control's JointTrajectoryController
  serves it: the goal becomes the controller's trajectory (starting at the trajectory's header
  stamp in sim time, or now when it is zero), feedback (desired, actual, error) follows every
  physics step call or real-time chunk, and the result uses control_msgs' codes.
  Tolerances (positions only): ``path_tolerance`` is checked while the trajectory runs
  (PATH_TOLERANCE_VIOLATED); at the end every joint must be within ``goal_tolerance`` by
  ``goal_time_tolerance`` after the last point (GOAL_TOLERANCE_VIOLATED); with no goal time
  tolerance given the node waits at most ``DEFAULT_GOAL_TIME`` seconds of sim time. A tolerance
  <= 0 is not checked. The checks run in the stepping thread after every step call or real-time
  chunk, so a result depends on sim time only, never on how soon a goal's thread gets to run. A
  cancel holds the joints where they are. A new goal, or a trajectory on the
  controller's topic, ends the running goal (ABORTED, "preempted"). Only one goal runs per
  controller; goals for an inactive controller, unknown or missing joints, an empty or malformed
  trajectory, or one that ended in the past are rejected. Goals and results are the same in every
  served distribution; feedback is published in each distribution's definition (Kilted's and
  Rolling's carry ``index``), so clients of any of them get it.
* ``~/simulate_steps`` (``simulation_interfaces/action/SimulateSteps``): steps a paused simulation,
  with feedback (completed/remaining steps) and cancel; more than the node's
  ``max_steps_per_call`` steps, or a simulation that is not paused, finish with
  RESULT_OPERATION_FAILED.

Sim time advances only when the simulation plays or someone steps it; goals wait for it (their
threads end when the goal is canceled or the node shuts down).
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from multiros.ros.action import ActionServer, CancelResponse, GoalResponse, ServerGoalHandle
from multiros.ros.interfaces import get_action, get_message
from multiros.sim import convert
from multiros.sim.controllers import JointTrajectoryController
from multiros.sim.errors import CommandError, ControllerError

__all__ = ["TrajectoryActions", "SimulateStepsAction", "DEFAULT_GOAL_TIME"]

FollowJointTrajectory = get_action("control_msgs/action/FollowJointTrajectory")
SimulateSteps = get_action("simulation_interfaces/action/SimulateSteps")
Duration = get_message("builtin_interfaces/msg/Duration")
_FJT = FollowJointTrajectory.Result
_PAUSED = get_message("simulation_interfaces/msg/SimulationState").STATE_PAUSED

#: Seconds of sim time the joints get to reach the goal tolerance when the goal gives none.
DEFAULT_GOAL_TIME = 1.0
_WAKE_SEC = 0.1  # re-check cancel/shutdown at least this often while sim time stands still
_FEEDBACK_PERIOD_SEC = 0.02  # SimulateSteps feedback at most this often (wall clock)
_STEP_CHUNK = 50  # SimulateSteps physics steps per lock acquisition


def _other_variants(action: Any) -> list[Any]:
    """The served distributions' other definitions of ``action`` (one per distinct type hash).

    control_msgs' FollowJointTrajectory feedback gained ``index``/``multi_dof_index`` after Jazzy;
    goal and result stayed, so one server serves all, publishing each feedback in every variant.
    """
    from multiros.ros.interfaces import registry_for, type_hash
    from multiros.sim.distro_adapters import SERVED_DISTROS

    seen, variants = {type_hash(action)}, []
    for distro in SERVED_DISTROS:
        variant = registry_for(distro).action_class(action._type)
        key = type_hash(variant)
        if key not in seen:
            seen.add(key)
            variants.append(variant)
    return variants


def _seconds(duration: Any) -> float:
    return float(duration.sec) + float(duration.nanosec) * 1e-9


class _StepSignal:
    """Wakes goal threads after the world advanced (a step call or a real-time chunk)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._generation = 0

    def notify(self) -> None:
        with self._cond:
            self._generation += 1
            self._cond.notify_all()

    def wait(self, generation: int, timeout: float) -> int:
        with self._cond:
            if self._generation == generation:
                self._cond.wait(timeout)
            return self._generation

    @property
    def generation(self) -> int:
        return self._generation


class _GoalWatch:
    """What a running goal is checked against, and the check's first verdict.

    The verdict is decided in :meth:`TrajectoryActions.on_step`, in the stepping thread right after
    each step call or real-time chunk, so that it depends on sim time only: a goal thread that
    wakes late (a loaded machine, a paused simulation stepped in quick calls) reports what was true
    when the world was at that time, not what is true when it gets around to looking.
    """

    __slots__ = ("ctrl", "owner", "jidx", "joints", "start", "end", "deadline", "path_tol", "goal_tol", "verdict")

    def __init__(self, ctrl: Any, owner: Any, jidx: np.ndarray, joints: list[str], start: float, end: float,
                 deadline: float, path_tol: np.ndarray, goal_tol: np.ndarray) -> None:
        self.ctrl, self.owner, self.jidx, self.joints = ctrl, owner, jidx, joints
        self.start, self.end, self.deadline = start, end, deadline
        self.path_tol, self.goal_tol = path_tol, goal_tol
        self.verdict: tuple[int, str] | None = None  # (control_msgs code, text), set once

    def check(self, now: float, desired: np.ndarray, actual: np.ndarray) -> None:
        """Record the verdict if this state decides the goal (caller holds the node lock)."""
        if self.verdict is not None:
            return
        if now < self.end:
            error = desired - actual
            bad = np.nonzero((self.path_tol > 0) & (np.abs(error) > self.path_tol))[0]
            if bad.size:
                j = bad[0]
                self.verdict = (_FJT.PATH_TOLERANCE_VIOLATED, f"path tolerance violated by joint {self.joints[j]} "
                                f"(error {error[j]:.4g}, tolerance {self.path_tol[j]:.4g})")
            return
        target = self.ctrl._pos[-1]
        off = np.nonzero((self.goal_tol > 0) & (np.abs(target - actual) > self.goal_tol))[0]
        if not off.size:
            self.verdict = (_FJT.SUCCESSFUL, "")
        elif now > self.deadline:
            j = off[0]
            self.verdict = (_FJT.GOAL_TOLERANCE_VIOLATED,
                            f"joint {self.joints[j]} is {abs(target[j] - actual[j]):.4g} from its goal "
                            f"(tolerance {self.goal_tol[j]:.4g}) {now - self.end:.3f} s after the trajectory's end")


class TrajectoryActions:
    """FollowJointTrajectory servers of one robot's joint trajectory controllers.

    Args:
        node: the simulation node.
        world: its world.
        robot: the robot entity's name.
        namespace: the robot's namespace ("" or "/ns").
        lock: the node's lock, held around every world access.
    """

    def __init__(self, node: Any, world: Any, robot: str, namespace: str, lock: threading.RLock) -> None:
        self.node, self.world, self.robot, self.ns, self.lock = node, world, robot, namespace, lock
        self._servers: dict[str, ActionServer] = {}
        self._active: dict[str, ServerGoalHandle] = {}  # controller -> its running goal
        self._preempted: set[ServerGoalHandle] = set()
        self._watches: dict[ServerGoalHandle, _GoalWatch] = {}  # running goals' checks (node lock)
        self._signal = _StepSignal()
        self._point = threading.local()  # the trajectory point the feedback being published is at
        self._variants = [(v, lambda fb, cls=v.Feedback: self._converted(fb, cls))
                          for v in _other_variants(FollowJointTrajectory)]

    # -- attachment (called by RobotInterfaces) ------------------------------------------------
    def add(self, controller: str, ctrl: Any) -> None:
        """Serve ``controller``'s action if it is a joint trajectory controller."""
        if controller in self._servers or not isinstance(ctrl, JointTrajectoryController):
            return
        self._servers[controller] = ActionServer(
            self.node, FollowJointTrajectory, f"{self.ns}/{controller}/follow_joint_trajectory",
            lambda handle, c=controller: self._execute(c, handle),
            goal_callback=lambda goal, c=controller: self._accept(c, goal),
            handle_accepted_callback=lambda handle, c=controller: self._start(c, handle),
            cancel_callback=lambda handle: CancelResponse.ACCEPT,
            max_goals=4,
            feedback_variants=self._variants,
        )

    def remove(self, controller: str) -> None:
        server = self._servers.pop(controller, None)
        if server is not None:
            server.destroy(timeout_sec=0.0)  # callers hold the node lock the goal threads need
        self._active.pop(controller, None)

    def on_step(self) -> None:
        """The world advanced: decide the running goals' tolerance checks at this sim time, then wake
        their threads (caller holds the node lock)."""
        if not self._active:
            return
        if self._watches:
            now = self.world.time
            position = self.world.joint_state(self.robot).position
            for watch in tuple(self._watches.values()):  # goal threads remove theirs without the lock
                if watch.verdict is None and watch.ctrl._pos is watch.owner:
                    watch.check(now, watch.ctrl.hw.command[watch.ctrl.idx], position[watch.jidx])
        self._signal.notify()

    def destroy(self) -> None:
        for controller in list(self._servers):
            self.remove(controller)

    # -- goals ---------------------------------------------------------------------------------
    def _controller(self, controller: str) -> JointTrajectoryController:
        ctrl = self.world.controller_manager(self.robot).get(controller)
        if not isinstance(ctrl, JointTrajectoryController):
            raise ControllerError(f"controller '{controller}' is not a joint trajectory controller")
        return ctrl

    def _reject(self, controller: str, why: str) -> GoalResponse:
        self.node.get_logger().warning("%s/%s/follow_joint_trajectory: goal rejected: %s", self.ns, controller, why)
        return GoalResponse.REJECT

    def _accept(self, controller: str, goal: Any) -> GoalResponse:
        traj = goal.trajectory
        with self.lock:
            try:
                ctrl = self._controller(controller)
            except ControllerError as exc:
                return self._reject(controller, str(exc))
            if ctrl.state != "active":
                return self._reject(controller, f"controller '{controller}' is {ctrl.state}, not active")
            joints = list(ctrl.joints)
            now = self.world.time
        names = list(traj.joint_names)
        if not traj.points:
            return self._reject(controller, "the trajectory has no points")
        if sorted(names) != sorted(joints) or len(set(names)) != len(names):
            return self._reject(controller, f"trajectory joints {names} must be exactly {joints}")
        start = _seconds(traj.header.stamp)
        end = _seconds(traj.points[-1].time_from_start)
        if start > 0 and start + end < now:
            return self._reject(controller, f"the trajectory (stamp {start:.3f} s) ended before now ({now:.3f} s)")
        for i, point in enumerate(traj.points):
            values = [point.positions, point.velocities]
            if len(point.positions) != len(names) or len(point.velocities) not in (0, len(names)):
                return self._reject(controller, f"point {i} has {len(point.positions)} positions and "
                                                f"{len(point.velocities)} velocities for {len(names)} joints")
            if not all(np.all(np.isfinite(np.asarray(v, dtype=float))) for v in values):
                return self._reject(controller, f"point {i} has a NaN or infinite value")
        return GoalResponse.ACCEPT

    def _start(self, controller: str, handle: ServerGoalHandle) -> None:
        previous = self._active.get(controller)
        if previous is not None and previous.is_active:
            self._preempted.add(previous)  # its thread aborts it at its next wake-up
        self._active[controller] = handle
        handle.execute()

    def _converted(self, feedback: Any, cls: type) -> Any:
        """``feedback`` in another distribution's definition (``index``: the current point)."""
        from multiros.sim.distro_adapters import convert_message

        out = convert_message(feedback, cls)
        if hasattr(out, "index"):
            out.index = getattr(self._point, "index", 0)
        return out

    def _tolerances(self, entries: Any, joints: list[str]) -> np.ndarray:
        tol = np.zeros(len(joints))
        for entry in entries:
            if entry.name in joints and entry.position > 0:
                tol[joints.index(entry.name)] = float(entry.position)
        return tol

    def _execute(self, controller: str, handle: ServerGoalHandle) -> Any:
        goal = handle.request
        traj = goal.trajectory
        result = FollowJointTrajectory.Result()
        names = list(traj.joint_names)
        times = [_seconds(p.time_from_start) for p in traj.points]
        velocities = [p.velocities for p in traj.points] if all(len(p.velocities) for p in traj.points) else None
        with self.lock:
            try:
                ctrl = self._controller(controller)
                stamp = _seconds(traj.header.stamp)
                start = stamp if stamp > 0 else self.world.time
                ctrl.set_trajectory(names, [p.positions for p in traj.points], times, velocities, time=start)
                self.world.controllers_changed(self.robot)
            except (CommandError, ControllerError) as exc:
                return self._finish(controller, handle, result, _FJT.INVALID_GOAL, str(exc))
            joints = list(ctrl.joints)
            all_joints = list(self.world.joint_names(self.robot))
            jidx = np.array([all_joints.index(j) for j in joints], dtype=np.intp)
            owner = ctrl._pos  # the trajectory arrays this goal installed (identity tells if replaced)
            end = start + times[-1]
            goal_time = _seconds(goal.goal_time_tolerance)
            deadline = end + (goal_time if goal_time > 0 else DEFAULT_GOAL_TIME)
            watch = _GoalWatch(ctrl, owner, jidx, joints, start, end, deadline,
                               self._tolerances(goal.path_tolerance, joints),
                               self._tolerances(goal.goal_tolerance, joints))
            self._watches[handle] = watch  # checked from the next world advance on
        try:
            return self._follow(controller, handle, watch, times, result)
        finally:
            # Without the node lock: a client stepping in a tight loop can hold it for long
            # stretches, and the goal's result goes out only when this returns. A dict pop is
            # atomic, and on_step iterates over a snapshot.
            self._watches.pop(handle, None)

    def _follow(self, controller: str, handle: ServerGoalHandle, watch: _GoalWatch, times: list[float],
                result: Any) -> Any:
        """Feedback after every world advance until the goal is canceled, preempted or decided."""
        ctrl, owner, jidx, joints, start = watch.ctrl, watch.owner, watch.jidx, watch.joints, watch.start
        generation = self._signal.generation
        while True:
            if handle.is_cancel_requested:
                with self.lock:
                    if self._owns(controller, ctrl, owner):
                        self._hold(ctrl)  # stop where the joints are
                return self._finish(controller, handle, result, _FJT.SUCCESSFUL, "canceled", canceled=True)
            if handle in self._preempted:
                self._preempted.discard(handle)
                return self._finish(controller, handle, result, _FJT.INVALID_GOAL, "preempted by a new goal")
            with self.lock:
                if not self._owns(controller, ctrl, owner):
                    replaced = True
                else:
                    replaced = False
                    now = self.world.time
                    desired = ctrl.hw.command[ctrl.idx].copy()
                    desired_vel = ctrl.hw.command_velocity[ctrl.idx].copy()
                    state = self.world.joint_state(self.robot)  # hw.position is refreshed only on events
                    actual = state.position[jidx]
                    actual_vel = state.velocity[jidx]
                    verdict = watch.verdict
            if replaced:
                return self._finish(controller, handle, result, _FJT.INVALID_GOAL,
                                    "preempted: the controller got another trajectory, was deactivated or unloaded")
            self._point.index = min(int(np.searchsorted(times, now - start)), len(times) - 1)
            handle.publish_feedback(self._feedback(joints, now, now - start, desired, desired_vel, actual,
                                                   actual_vel))
            if verdict is not None:
                code, text = verdict
                if code == _FJT.SUCCESSFUL:
                    return self._finish(controller, handle, result, code, text)
                return self._hold_and_abort(controller, handle, ctrl, owner, result, code, text)
            generation = self._signal.wait(generation, _WAKE_SEC)

    def _hold_and_abort(self, controller: str, handle: ServerGoalHandle, ctrl: Any, owner: Any, result: Any,
                        code: int, text: str) -> Any:
        with self.lock:
            if self._owns(controller, ctrl, owner):
                self._hold(ctrl)
        return self._finish(controller, handle, result, code, text)

    def _hold(self, ctrl: Any) -> None:
        """Make ``ctrl`` hold the joints' current positions (lock held)."""
        cm = self.world.controller_manager(self.robot)
        if cm.refresh_state is not None:
            cm.refresh_state()  # the hardware view is refreshed on events only; hold needs it now
        ctrl.hold()
        self.world.controllers_changed(self.robot)

    def _owns(self, controller: str, ctrl: Any, owner: Any) -> bool:
        """Whether ``ctrl`` is still loaded, active and following this goal's trajectory (lock held)."""
        try:
            current = self.world.controller_manager(self.robot).get(controller)
        except Exception:  # noqa: BLE001 - unloaded, or the robot is gone
            return False
        return current is ctrl and ctrl.state == "active" and ctrl._pos is owner

    def _finish(self, controller: str, handle: ServerGoalHandle, result: Any, code: int, text: str,
                canceled: bool = False) -> Any:
        if self._active.get(controller) is handle:
            del self._active[controller]
        self._preempted.discard(handle)
        result.error_code = code
        result.error_string = text
        if canceled:
            handle.canceled()
        elif code == _FJT.SUCCESSFUL:
            handle.succeed()
        else:
            self.node.get_logger().warning("%s/%s/follow_joint_trajectory: %s", self.ns, controller, text)
            handle.abort()
        return result

    @staticmethod
    def _feedback(joints: list[str], now: float, elapsed: float, desired: np.ndarray, desired_vel: np.ndarray,
                  actual: np.ndarray, actual_vel: np.ndarray) -> Any:
        fb = FollowJointTrajectory.Feedback()
        fb.header.stamp = convert.time_msg(now)
        fb.joint_names = joints
        sec, nanosec = divmod(int(round(max(0.0, elapsed) * 1e9)), 1_000_000_000)
        since = Duration(sec=sec, nanosec=nanosec)
        for point, pos, vel in ((fb.desired, desired, desired_vel), (fb.actual, actual, actual_vel),
                                (fb.error, desired - actual, desired_vel - actual_vel)):
            point.positions = pos
            point.velocities = vel
            point.time_from_start = since
        return fb


class SimulateStepsAction:
    """``~/simulate_steps`` of the simulation node."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self._server = ActionServer(node, SimulateSteps, "~/simulate_steps", self._execute,
                                    cancel_callback=lambda handle: CancelResponse.ACCEPT, max_goals=4)

    def _execute(self, handle: ServerGoalHandle) -> Any:
        node = self.node
        result = SimulateSteps.Result()
        res = result.result
        steps = int(handle.request.steps)
        paused = node.simulation_state == _PAUSED
        if steps > node.max_steps_per_call or not paused:
            res.result = res.RESULT_OPERATION_FAILED
            res.error_message = (
                f"steps={steps} exceeds this node's max_steps_per_call ({node.max_steps_per_call}); split the goal"
                if paused else "SimulateSteps needs a paused simulation; pause it first")
            handle.abort()
            return result
        done, last_feedback = 0, 0.0
        while done < steps:
            if handle.is_cancel_requested:
                res.result = res.RESULT_OK
                res.error_message = f"canceled after {done} of {steps} steps"
                handle.canceled()
                return result
            chunk = min(_STEP_CHUNK, steps - done)
            with node.lock:
                if node.simulation_state != _PAUSED:
                    res.result = res.RESULT_OPERATION_FAILED
                    res.error_message = f"the simulation left the paused state after {done} of {steps} steps"
                    handle.abort()
                    return result
                try:
                    node._step_world(chunk)
                except Exception as exc:  # noqa: BLE001 - unstable physics, node shutdown
                    res.result = res.RESULT_OPERATION_FAILED
                    res.error_message = f"stepping failed after {done} of {steps} steps: {exc}"
                    handle.abort()
                    return result
                node._after_step()
            done += chunk
            now = time.monotonic()
            if done == steps or now - last_feedback >= _FEEDBACK_PERIOD_SEC:
                last_feedback = now
                handle.publish_feedback(SimulateSteps.Feedback(completed_steps=done, remaining_steps=steps - done))
        res.result = res.RESULT_OK
        handle.succeed()
        return result

    def destroy(self) -> None:
        self._server.destroy()
