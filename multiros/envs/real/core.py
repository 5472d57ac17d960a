"""What RealBaseEnv and RealGoalEnv share: the robot link, the control loop, safety, resets, prompts.

A Real env talks to its robot only through what a ros2_control robot offers (see
:mod:`multiros.envs.real.robot_link`): no simulation service, no simulation clock. Every command
passes :class:`~multiros.envs.real.safety.SafetyRules` first; every wait is bounded; a stale or
malformed ``joint_states`` stops commanding and raises :class:`StaleStateError`. When the env errors
or closes it sends nothing more: a JointTrajectoryController holds the end of its last trajectory,
a forward command controller its last command.
"""

from __future__ import annotations

import itertools
import logging
import os
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from multiros.envs.core import EnvError, MujocoEnvCore, ResetError
from multiros.envs.joint_access import JointStateAccess
from multiros.envs.real.control_loop import ControlLoop
from multiros.envs.real.errors import RobotConnectionError, StaleStateError, UnsafeCommandError
from multiros.envs.real.robot_link import JointSample, RobotLink
from multiros.envs.real.safety import SafetyDecision, SafetyRules, description_joint_limits

_logger = logging.getLogger(__name__)
_env_ids = itertools.count()

# RealROS / ROS 1 knobs with no meaning in ROS 2 (no master, no launching from the env).
_IGNORED = {
    "kill_rosmaster": "there is no ROS master in ROS 2",
    "clean_logs": "ROS 2 logs are not the env's to clean",
    "ros_port": "there is no ROS master port in ROS 2 (set ROS_DOMAIN_ID / UNIROS_ZENOH_ROUTER)",
    "new_roscore": "there is no ROS master in ROS 2",
    "roscore_port": "there is no ROS master port in ROS 2",
    "default_port": "there is no ROS master port in ROS 2",
    "new_robot_state_term": "the env opens no terminals",
    "robot_state_publisher_max_freq": "robot_state_publisher belongs to the robot's launch",
    "launch_robot_state_pub": "robot_state_publisher belongs to the robot's launch",
    "controllers_file": "controller parameters come from the robot driver's launch (its controllers YAML)",
    "load_urdf": "the description for limits and kinematics is robot_description= (or the robot env's)",
}
# Knobs that would start something on the robot side: refused, with what to do instead.
_REFUSED = {
    "load_robot": "start the robot's ROS 2 driver yourself (e.g. `ros2 launch interbotix_xsarm_control "
                  "xsarm_control.launch.py robot_model:=rx200`), then make the env",
    "robot_pkg_name": "a Real env does not launch the robot: start its ROS 2 driver yourself",
    "robot_launch_file": "a Real env does not launch the robot: start its ROS 2 driver yourself",
    "robot_args": "a Real env does not launch the robot: start its ROS 2 driver yourself",
}
#: Knobs of the simulation envs that mean nothing to a robot (a Real env ignores them with a warning).
SIMULATION_KNOBS = frozenset({
    "sim_mode", "sim_node_name", "gui", "num_sim_steps", "sim_timestep", "real_time_factor", "spawn_robot",
    "robot_model_xml", "reset_mode", "step_mode", "frames", "render_camera", "render_width", "render_height",
})


def _interactive() -> bool:
    try:
        return sys.stdin is not None and sys.stdin.isatty()
    except (ValueError, OSError):
        return False


class RealEnvCore(JointStateAccess):
    """Machinery shared by :class:`RealBaseEnv` and :class:`RealGoalEnv`.

    Args:
        namespace: the robot's ROS namespace (``"/rx200"``); ``"/"`` for none.
        robot_name: a name for messages (default: the namespace).
        arm_joints: the joints :meth:`send_joint_targets` commands, in command order.
        arm_controller: the controller commanding ``arm_joints``.
        arm_controller_type: ``"trajectory"`` (a JointTrajectoryController, the default) or
            ``"forward"`` (a ForwardCommandController / JointGroupPositionController).
        command_interface: for trajectory controllers, ``"topic"`` (``<controller>/joint_trajectory``,
            the default) or ``"action"`` (``<controller>/follow_joint_trajectory``, each goal checked).
        controllers_list: controllers that must be active (besides ``arm_controller``).
        load_controllers: load/configure/activate ``arm_controller`` and ``controllers_list`` at start.
        reset_controllers: restart them on every reset; ``reset_controllers_prompt`` asks first.
        joint_states_topic: relative to the namespace unless absolute.
        environment_loop_rate, action_cycle_time: the control loop (see
            :class:`~multiros.envs.real.control_loop.ControlLoop`).
        safety: the :class:`~multiros.envs.real.safety.SafetyRules` of the arm (a robot env builds them
            from its description); without them, ``robot_description`` gives the joint limits.
        robot_description: URDF text or a ``.urdf``/``.urdf.xacro`` path for the joint limits.
        max_joint_delta: per-command cap used when the env builds the rules itself.
        joint_state_timeout: a state older than this (s) is stale: the env stops and raises.
        startup_timeout: bound on waiting for the robot's first joint states and controllers.
        timeout_sec: bound on each service call and action answer.
        reset_joint_speed: rad/s of the move to an episode's initial pose.
        reset_tolerance: how close (rad) that move must get; reset_timeout: extra seconds allowed.
        out_of_range_action: ``"error"`` (default: an action outside the action space raises and
            nothing is sent) or ``"clip"``.
        reset_env_prompt, close_env_prompt: ask the operator (Enter) before each reset / at close.
            Only when stdin is a terminal; otherwise a warning and no wait.
        use_sim_time: read ``/clock`` (when the robot side publishes it) into ``robot_time``.
        context: a ``multiros.ros.Context`` to join (the caller owns it); default a Zenoh context on
            the graph the environment names (``UNIROS_ZENOH_ROUTER``, ``ROS_DOMAIN_ID``).
        transport: transport of the context the env creates (``"zenoh"``).
        seed: seed of the first reset; log_internal_state: log each step's state and safety.
    """

    metadata: dict[str, Any] = {"render_modes": []}

    # The hook dispatch is the simulation envs' own (canonical and MultiROS/RealROS names, the most
    # derived alias wins); these methods touch no simulation.
    _hook = MujocoEnvCore._hook
    _run_reset_hooks = MujocoEnvCore._run_reset_hooks
    _set_action_hook = MujocoEnvCore._set_action_hook

    def _init_real(
        self,
        *,
        namespace: str = "/",
        robot_name: str | None = None,
        arm_joints: Sequence[str] = (),
        arm_controller: str | None = None,
        arm_controller_type: str = "trajectory",
        command_interface: str = "topic",
        controllers_list: Sequence[str] | None = None,
        load_controllers: bool = False,
        reset_controllers: bool = False,
        reset_controllers_prompt: bool = False,
        joint_states_topic: str = "joint_states",
        environment_loop_rate: float = 10.0,
        action_cycle_time: float = 0.0,
        safety: SafetyRules | None = None,
        robot_description: str | os.PathLike[str] | None = None,
        max_joint_delta: float | None = 0.15,
        joint_state_timeout: float = 0.5,
        startup_timeout: float = 10.0,
        timeout_sec: float = 5.0,
        reset_joint_speed: float = 0.5,
        reset_tolerance: float = 0.02,
        reset_timeout: float = 10.0,
        out_of_range_action: str = "error",
        reset_env_prompt: bool = False,
        close_env_prompt: bool = False,
        use_sim_time: bool = False,
        context: Any = None,
        transport: str = "zenoh",
        seed: int | None = None,
        log_internal_state: bool = False,
        render_mode: str | None = None,
        **legacy: Any,
    ) -> None:
        self._closed = False
        self.link: RobotLink | None = None
        for key in list(legacy):
            if key in _REFUSED and legacy[key]:
                raise ValueError(f"{type(self).__name__}: {key}={legacy[key]!r} is not supported: {_REFUSED[key]}")
            if key in _REFUSED:
                legacy.pop(key)
        for old in ("ros_controllers_list", "controller_list"):  # MultiROS / FRobs_RL spellings
            if old in legacy:
                controllers_list = legacy.pop(old)
        unknown = sorted(set(legacy) - set(_IGNORED) - SIMULATION_KNOBS)
        if unknown:
            raise TypeError(f"{type(self).__name__} got unexpected keyword argument(s) {unknown}; see "
                            "multiros.envs.real.core.RealEnvCore for the accepted knobs")
        for key, value in legacy.items():
            why = _IGNORED.get(key, "it configures the simulation, and a Real env drives a robot")
            _logger.warning("%s ignores %s=%r: %s", type(self).__name__, key, value, why)
        if render_mode is not None:
            raise ValueError(f"{type(self).__name__} cannot render (render_mode={render_mode!r}): use the robot's "
                             "cameras or RViz")
        if arm_controller_type not in ("trajectory", "forward"):
            raise ValueError(f"arm_controller_type {arm_controller_type!r} is not 'trajectory' or 'forward'")
        if command_interface not in ("topic", "action"):
            raise ValueError(f"command_interface {command_interface!r} is not 'topic' or 'action'")
        if out_of_range_action not in ("error", "clip"):
            raise ValueError(f"out_of_range_action {out_of_range_action!r} is not 'error' or 'clip'")
        if not joint_state_timeout > 0:
            raise ValueError(f"joint_state_timeout must be > 0 s, got {joint_state_timeout!r}")
        self.render_mode = None
        ns = (namespace or "").strip("/")
        self.namespace = "/" + ns if ns else "/"
        self.robot_name = robot_name or (ns or "robot")
        self.arm_joints: tuple[str, ...] = tuple(arm_joints)
        self.arm_controller = arm_controller
        self.arm_controller_type = arm_controller_type
        self.command_interface = command_interface
        self.controllers_list = list(controllers_list or [])
        self.reset_controllers = bool(reset_controllers)
        self.reset_controllers_prompt = bool(reset_controllers_prompt)
        self.loop = ControlLoop(environment_loop_rate, action_cycle_time)
        self.joint_state_timeout = float(joint_state_timeout)
        self.startup_timeout = float(startup_timeout)
        self.timeout_sec = float(timeout_sec)
        self.reset_joint_speed = float(reset_joint_speed)
        self.reset_tolerance = float(reset_tolerance)
        self.reset_timeout = float(reset_timeout)
        self.out_of_range_action = out_of_range_action
        self.reset_env_prompt = bool(reset_env_prompt)
        self.close_env_prompt = bool(close_env_prompt)
        self.log_internal_state = bool(log_internal_state)
        self._pending_seed = seed
        self._fault: BaseException | None = None
        self._state: JointSample | None = None
        self._observed: tuple[str, ...] = ()
        self._set_joint_order(())
        self.last_command: np.ndarray | None = None
        self.last_decision: SafetyDecision | None = None
        self.commands_sent = 0
        self.info: dict[str, Any] = {}
        if safety is None and self.arm_joints:
            if robot_description is None:
                raise ValueError(f"{type(self).__name__} commands {list(self.arm_joints)} but has no joint limits: "
                                 "pass safety=SafetyRules(...) or robot_description= (a URDF)")
            lo, hi = description_joint_limits(robot_description, self.arm_joints)
            safety = SafetyRules(self.arm_joints, lower=lo, upper=hi, max_joint_delta=max_joint_delta)
        if safety is not None and tuple(safety.joint_names) != self.arm_joints:
            raise ValueError(f"safety rules cover {list(safety.joint_names)}, the arm joints are "
                             f"{list(self.arm_joints)}")
        self.safety = safety
        if self.arm_joints and not self.arm_controller:
            raise ValueError("arm_joints need an arm_controller (the controller commanding them)")

        from multiros.ros import Context, Node

        self._owns_context = context is None
        self.context = Context(transport=transport).init() if context is None else context
        try:
            self.node = Node(f"uniros_real_env_{os.getpid()}_{next(_env_ids)}", context=self.context)
            self.link = RobotLink(self.node, self.namespace, joint_states_topic=joint_states_topic,
                                  use_sim_time=use_sim_time, timeout_sec=self.timeout_sec)
            self._connect(load_controllers)
        except BaseException:
            self.close()
            raise

    # -- start-up ---------------------------------------------------------------------------
    def _connect(self, load_controllers: bool) -> None:
        link = self.link
        assert link is not None
        needed = self.arm_joints
        deadline = time.monotonic() + self.startup_timeout
        ok = link.node.context.wait_for(
            lambda: link.states.received_count > 0 and all(j in link.states.names for j in needed),
            self.startup_timeout)
        if not ok:
            raise RobotConnectionError(
                f"no usable joint states from {link.joint_states_topic} within {self.startup_timeout:g} s "
                f"({link.states.describe_problem(needed)}): is the robot's driver running in namespace "
                f"{self.namespace!r}, with the same ROS_DOMAIN_ID and Zenoh router (UNIROS_ZENOH_ROUTER) as this "
                "process?"
            )
        self._observed = tuple(dict.fromkeys((*needed, *link.states.names)))
        self._set_joint_order(self._observed)
        controllers = ([self.arm_controller] if self.arm_controller else []) + [
            c for c in self.controllers_list if c != self.arm_controller]
        if controllers:
            if load_controllers:
                link.spawn_controllers(controllers)
            link.require_active(controllers)
        if self.arm_controller:
            remaining = max(0.5, deadline - time.monotonic())
            if self.arm_controller_type == "trajectory" and self.command_interface == "action":
                ready = link.wait_for_action(self.arm_controller, remaining)
                where = link.action_name(self.arm_controller)
            else:
                kind = "trajectory" if self.arm_controller_type == "trajectory" else "forward"
                ready = link.wait_for_subscriber(self.arm_controller, kind, remaining)
                where = (link.trajectory_topic(self.arm_controller) if kind == "trajectory"
                         else link.commands_topic(self.arm_controller))
            if not ready:
                raise RobotConnectionError(f"nobody serves {where} (controller {self.arm_controller!r} is active, but "
                                           f"its command interface did not appear within {remaining:.1f} s)")
        self._state = self._fresh_sample()

    # -- state ------------------------------------------------------------------------------
    def _fresh_sample(self) -> JointSample:
        """The freshest state of the observed joints; :class:`StaleStateError` when too old."""
        assert self.link is not None
        sample = self.link.states.sample(self._observed)
        now = time.monotonic()
        if sample is None or now - sample.received > self.joint_state_timeout:
            age = "never" if sample is None else f"{now - sample.received:.3f} s ago"
            err = StaleStateError(
                f"joint_states of {self.robot_name!r} ({self.link.joint_states_topic}) are stale: the last usable "
                f"state arrived {age}, limit joint_state_timeout={self.joint_state_timeout:g} s "
                f"({self.link.states.describe_problem(self._observed)}). The env stopped commanding; the robot "
                "holds its last command. Check the robot driver, then reset the env or make a new one."
            )
            self._fault = err
            raise err
        return sample

    def _watchdog(self) -> None:
        self._fresh_sample()

    @property
    def robot_state(self) -> JointSample:
        """The state observed after the last step or reset."""
        if self._state is None:
            raise EnvError("no robot state yet")
        return self._state

    @property
    def state_age(self) -> float:
        """Seconds between the observed state's arrival and now."""
        return self.robot_state.age()

    @property
    def robot_time(self) -> float | None:
        """The robot side's ``/clock`` (with ``use_sim_time``), else ``None``."""
        return None if self.link is None else self.link.robot_time

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self._observed

    def _observe_state(self) -> None:
        self._state = self._fresh_sample()
        self.info["state_age_sec"] = self._state.age()
        if self.robot_time is not None:
            self.info["robot_time"] = self.robot_time

    # -- commanding -------------------------------------------------------------------------
    def _ensure_commandable(self) -> None:
        if self._closed:
            raise EnvError(f"{type(self).__name__} is closed")
        if self._fault is not None:
            raise EnvError(f"{type(self).__name__} stopped after an error ({self._fault}); reset it once the robot "
                           "is back, or make a new env")

    def send_joint_targets(self, targets: Sequence[float] | np.ndarray) -> SafetyDecision:
        """Command the arm: the safety rules first, then the arm controller (nothing sent if refused).

        The decision goes to ``info["safety"]``. Raises :class:`UnsafeCommandError` for NaN/infinite or
        wrong-length targets and :class:`StaleStateError` when the state is too old to act on.
        """
        self._ensure_commandable()
        if self.safety is None or self.arm_controller is None:
            raise EnvError(f"{type(self).__name__} has no arm joints/controller configured")
        current = self._fresh_sample()
        idx = [self._joint_index[j] for j in self.arm_joints]
        decision = self.safety.check(targets, current.position[idx])
        self.last_decision = decision
        self.info["safety"] = decision.as_info()
        if decision.events:
            _logger.log(logging.INFO if self.log_internal_state else logging.DEBUG, "safety: %s", decision.reason)
        if decision.refused or decision.target is None:
            return decision
        self._send(decision.target, self.loop.cycle)
        return decision

    def _send(self, target: np.ndarray, duration: float) -> Any:
        assert self.link is not None and self.arm_controller is not None
        handle = None
        if self.arm_controller_type == "forward":
            self.link.publish_forward(self.arm_controller, target)
        elif self.command_interface == "action":
            handle = self.link.send_trajectory_goal(self.arm_controller, self.arm_joints, target, duration)
        else:
            self.link.publish_trajectory(self.arm_controller, self.arm_joints, target, duration)
        self.last_command = np.asarray(target, dtype=np.float64).copy()
        self.commands_sent += 1
        return handle

    def send_command(self, controller: str, command: Sequence[float] | np.ndarray) -> None:
        """Command a controller by name: the arm controller goes through :meth:`send_joint_targets`;
        another (e.g. a gripper's forward command controller) gets finite values on ``<controller>/commands``."""
        if controller == self.arm_controller:
            self.send_joint_targets(command)
            return
        self._ensure_commandable()
        values = np.asarray(command, dtype=np.float64)
        if values.ndim != 1 or not np.all(np.isfinite(values)):
            raise UnsafeCommandError(f"command for {controller!r} must be a 1-D finite vector, got {command!r}; "
                                     "nothing was sent")
        self._fresh_sample()
        assert self.link is not None
        self.link.publish_forward(controller, values)

    def move_to_initial_pose(self, names: Sequence[str], positions: Sequence[float], tolerance: float = 1e-3) -> None:
        """Move the arm to ``positions`` at ``reset_joint_speed`` and wait until it is there.

        The target is clamped to the joint limits and the path checked against the workspace and
        floor (a violation refuses the move). Raises :class:`ResetError` when the arm does not arrive
        within ``reset_tolerance`` (or ``tolerance`` if larger) in time.
        """
        self._ensure_commandable()
        if self.safety is None:
            raise EnvError(f"{type(self).__name__} has no arm joints/controller configured")
        order = {n: i for i, n in enumerate(names)}
        if set(order) != set(self.arm_joints):
            raise EnvError(f"move_to_initial_pose moves the arm joints {list(self.arm_joints)}, got {list(names)}")
        target = np.asarray(positions, dtype=np.float64)[[order[j] for j in self.arm_joints]]
        current = self._fresh_sample()
        idx = [self._joint_index[j] for j in self.arm_joints]
        decision = self.safety.check_move(target, current.position[idx])
        if decision.refused or decision.target is None:
            raise ResetError(f"initial pose of {self.robot_name!r}: {decision.reason}; move the robot by hand")
        goal = decision.target
        start = current.position[idx]
        duration = max(self.loop.cycle, float(np.max(np.abs(goal - start))) / max(self.reset_joint_speed, 1e-6))
        tol = max(float(tolerance), self.reset_tolerance)
        deadline = time.monotonic() + duration + self.reset_timeout
        if self.arm_controller_type == "forward":
            steps = max(1, int(np.ceil(duration / self.loop.period)))
            for k in range(1, steps + 1):
                self._send(start + (goal - start) * (k / steps), self.loop.period)
                self.loop.wait(time.monotonic(), self._watchdog)
        else:
            handle = self._send(goal, duration)
            if handle is not None:
                assert self.link is not None
                self.link.check_goal_result(handle, f"moving {self.robot_name!r} to its initial pose",
                                            duration + self.reset_timeout)
        error = np.inf
        while True:
            sample = self._fresh_sample()
            error = float(np.max(np.abs(sample.position[idx] - goal)))
            if error <= tol:
                self._state = sample
                return
            if time.monotonic() > deadline:
                raise ResetError(
                    f"robot {self.robot_name!r} did not reach its initial pose {np.round(goal, 4).tolist()} within "
                    f"{duration + self.reset_timeout:.1f} s (max joint error {error:.4g} rad > {tol:g}); check the "
                    "controller is tracking (gains, limits) or raise reset_tolerance / reset_timeout")
            time.sleep(min(0.01, self.loop.tick))

    # -- actions ----------------------------------------------------------------------------
    def _check_action(self, action: Any) -> np.ndarray:
        """Refuse NaN/infinite values, wrong shapes and (by default) out-of-range values."""
        space = self.action_space  # type: ignore[attr-defined]
        if isinstance(space, spaces.Box):
            arr = np.asarray(action, dtype=np.float64)
            if arr.shape != space.shape:
                raise UnsafeCommandError(f"action shape {arr.shape} does not match the action space {space.shape}; "
                                         "nothing was sent")
            if not np.all(np.isfinite(arr)):
                raise UnsafeCommandError(f"action {arr.tolist()} contains NaN or infinite values; nothing was sent")
            low, high = space.low.astype(np.float64), space.high.astype(np.float64)
            slack = 1e-6 * np.maximum(1.0, np.abs(high - low))
            if self.out_of_range_action == "error" and (np.any(arr < low - slack) or np.any(arr > high + slack)):
                raise UnsafeCommandError(
                    f"action {np.round(arr, 6).tolist()} is outside the action space [{low.tolist()}, "
                    f"{high.tolist()}]; "
                    "nothing was sent (out_of_range_action='clip' clips instead)")
            return np.minimum(np.maximum(arr, low), high)
        if not space.contains(action):
            raise UnsafeCommandError(f"action {action!r} is not in the action space {space}; nothing was sent")
        return np.asarray(action)

    def _act_and_wait(self, base: type, action: np.ndarray) -> None:
        """One control cycle: watchdog, the action hook (commands through safety), the wait, the freshest state."""
        self._ensure_commandable()
        self._fresh_sample()
        self._set_action_hook(base, action)  # type: ignore[attr-defined]
        acted = time.monotonic()
        started = self.loop.last_observe
        observed = self.loop.wait(acted, self._watchdog)
        self._observe_state()
        self.info["cycle_time_sec"] = observed - (started if started is not None else acted)
        if self.log_internal_state:
            _logger.info("%s: state age %.4f s, cycle %.4f s, safety %s", self.robot_name, self.info["state_age_sec"],
                         self.info["cycle_time_sec"], self.info.get("safety"))

    # -- resets and prompts -----------------------------------------------------------------
    def _prompt(self, message: str) -> None:
        if _interactive():
            input(message)
        else:
            _logger.warning("%s: not waiting for the operator (stdin is not a terminal): %s", type(self).__name__,
                            message)

    def _real_reset(self, base: type, options: dict[str, Any] | None) -> None:
        if self._closed:
            raise EnvError(f"{type(self).__name__} is closed")
        assert self.link is not None
        self.info = {}
        if self.reset_env_prompt:
            self._prompt("Reset the robot's surroundings, then press Enter to start the episode: ")
        # A fault (stale state) ends once fresh states arrive again.
        ok = self.context.wait_for(
            lambda: (s := self.link.states.sample(self._observed)) is not None
            and time.monotonic() - s.received <= self.joint_state_timeout, self.startup_timeout)
        if not ok:
            self._fault = None
            self._fresh_sample()  # raises with the reason
        self._fault = None
        controllers = ([self.arm_controller] if self.arm_controller else []) + [
            c for c in self.controllers_list if c != self.arm_controller]
        if self.reset_controllers and controllers:
            if self.reset_controllers_prompt:
                self._prompt(f"Press Enter to restart the controllers {controllers}: ")
            self.link.reset_controllers(controllers)
        if controllers:
            self.link.require_active(controllers)
        self._state = self._fresh_sample()
        self._run_reset_hooks(base, options)  # type: ignore[attr-defined]
        self.loop.start_episode()
        self.info = {k: v for k, v in self.info.items() if k != "safety"}
        self._observe_state()

    def close(self) -> None:
        """Stop talking to the robot; nothing more is sent (it holds its last command)."""
        if self._closed:
            return
        self._closed = True
        if self.close_env_prompt and self.link is not None:
            self._prompt("Closing the env: the robot holds its last command. Press Enter: ")
        if self.link is not None:
            try:
                self.link.close()
            except Exception:  # noqa: BLE001 - closing must go on
                _logger.debug("robot link did not close cleanly", exc_info=True)
        node = getattr(self, "node", None)
        if node is not None:
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001
                _logger.debug("node did not close cleanly", exc_info=True)
        ctx = getattr(self, "context", None)
        if ctx is not None and getattr(self, "_owns_context", False):
            ctx.try_shutdown()
