"""The real side of the env core: its constructor knobs, a :class:`~multiros.envs.real.connection.RealConnection`
built from them, and what only a real robot offers (the safety rules' decisions, state ages,
operator prompts).

:class:`RealBaseEnv <multiros.envs.real.envs.RealBaseEnv>` and ``RealGoalEnv`` are this plus their
step template (the simulated envs' own, :mod:`multiros.envs.base_env`): the hooks, action checks,
seeds and episodes are the one env core's (:mod:`multiros.envs.core`).
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from multiros.envs.core import EnvCore
from multiros.envs.knobs import REAL_KNOBS, SIMULATION_ONLY, sort_knobs
from multiros.envs.real.connection import RealConnection
from multiros.envs.real.control_loop import ControlLoop
from multiros.envs.real.errors import UnsafeCommandError
from multiros.envs.real.robot_link import RobotLink
from multiros.envs.real.safety import SafetyDecision, SafetyRules, description_joint_limits
from multiros.robot_state import RobotState

__all__ = ["RealEnvCore", "SIMULATION_KNOBS"]

_env_ids = itertools.count()
#: Knobs of the simulation envs that mean nothing to a robot (a Real env ignores them with a warning).
SIMULATION_KNOBS = SIMULATION_ONLY


class RealEnvCore(EnvCore):
    """The env core on a real robot (shared by :class:`RealBaseEnv` and :class:`RealGoalEnv`).

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
        check_controllers: ask the robot's ros2_control controller manager that they are active
            (default); ``False`` for a driver without one (Niryo's ROS 2 bridge): the arm's command
            topic or action server must still appear.
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
        reset_settle_tolerance: a move that stopped short (a stiff servo under gravity settles a few
            hundredths of a radian from its target) is accepted once the arm is still and within this
            many radians (default 0.05; 0: only ``reset_tolerance``); the episode starts where it settled.
        out_of_range_action: ``"error"`` (default: an action outside the action space raises and
            nothing is sent) or ``"clip"``.
        reset_env_prompt, close_env_prompt: ask the operator (Enter) before each reset / at close.
            Only when stdin is a terminal; otherwise a warning and no wait.
        use_sim_time: read ``/clock`` (when the robot side publishes it) into ``robot_time``.
        context: a ``multiros.ros.Context`` to join (the caller owns it); default a context of its
            own on the graph the environment names (``UNIROS_TRANSPORT``, ``UNIROS_ZENOH_ROUTER``,
            ``ROS_DOMAIN_ID``).
        transport: transport of the context the env creates (default: ``$UNIROS_TRANSPORT``, else
            ``"rclpy"`` when rclpy can be imported, else ``"zenoh"``; ``multiros.ros.transport.wire_transport``).
        seed: seed of the first reset; log_internal_state: log each step's state and safety.
    """

    metadata: dict[str, Any] = {"render_modes": []}
    connection: RealConnection
    action_error = UnsafeCommandError
    ON_ROBOT = True

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
        check_controllers: bool = True,
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
        reset_settle_tolerance: float = 0.05,
        reset_timeout: float = 10.0,
        out_of_range_action: str = "error",
        reset_env_prompt: bool = False,
        close_env_prompt: bool = False,
        use_sim_time: bool = False,
        context: Any = None,
        transport: str | None = None,
        seed: int | None = None,
        log_internal_state: bool = False,
        render_mode: str | None = None,
        **legacy: Any,
    ) -> None:
        given = {k: v for k, v in locals().items() if k not in ("self", "legacy", "__class__")}
        k = sort_knobs(REAL_KNOBS, type(self).__name__, given, legacy)
        self.info = {}
        self._pending_seed = k["seed"]
        if k["render_mode"] is not None:
            raise ValueError(f"{type(self).__name__} cannot render (render_mode={k['render_mode']!r}): use the "
                             "robot's cameras or RViz")
        self.render_mode = None
        if k["arm_controller_type"] not in ("trajectory", "forward"):
            raise ValueError(f"arm_controller_type {k['arm_controller_type']!r} is not 'trajectory' or 'forward'")
        if k["command_interface"] not in ("topic", "action"):
            raise ValueError(f"command_interface {k['command_interface']!r} is not 'topic' or 'action'")
        if k["out_of_range_action"] not in ("error", "clip"):
            raise ValueError(f"out_of_range_action {k['out_of_range_action']!r} is not 'error' or 'clip'")
        if not (math.isfinite(k["reset_settle_tolerance"]) and k["reset_settle_tolerance"] >= 0):
            raise ValueError("reset_settle_tolerance must be a finite number >= 0 rad, got "
                             f"{k['reset_settle_tolerance']!r}")
        if not k["joint_state_timeout"] > 0:
            raise ValueError(f"joint_state_timeout must be > 0 s, got {k['joint_state_timeout']!r}")
        self.out_of_range_action = k["out_of_range_action"]
        ns = (k["namespace"] or "").strip("/")
        arm_joints = tuple(k["arm_joints"])
        safety = k["safety"]
        if safety is None and arm_joints:
            if k["robot_description"] is None:
                raise ValueError(f"{type(self).__name__} commands {list(arm_joints)} but has no joint limits: "
                                 "pass safety=SafetyRules(...) or robot_description= (a URDF)")
            lo, hi = description_joint_limits(k["robot_description"], arm_joints)
            safety = SafetyRules(arm_joints, lower=lo, upper=hi, max_joint_delta=k["max_joint_delta"])
        if safety is not None and tuple(safety.joint_names) != arm_joints:
            raise ValueError(f"safety rules cover {list(safety.joint_names)}, the arm joints are {list(arm_joints)}")
        if arm_joints and not k["arm_controller"]:
            raise ValueError("arm_joints need an arm_controller (the controller commanding them)")
        loop = ControlLoop(k["environment_loop_rate"], k["action_cycle_time"])

        from multiros.ros import Context, Node
        from multiros.ros.transport import wire_transport

        self._owns_context = k["context"] is None
        transport = wire_transport(k["transport"])  # a robot is never in-process: explicit, env, rclpy, zenoh
        self.context = Context(transport=transport).init() if k["context"] is None else k["context"]
        try:
            self.node = Node(f"uniros_real_env_{os.getpid()}_{next(_env_ids)}", context=self.context)
            self.connection = RealConnection(
                self.node, owner=type(self).__name__, namespace="/" + ns if ns else "/",
                robot_name=k["robot_name"] or (ns or "robot"), arm_joints=arm_joints,
                arm_controller=k["arm_controller"], arm_controller_type=k["arm_controller_type"],
                command_interface=k["command_interface"], controllers_list=list(k["controllers_list"] or []),
                load_controllers=k["load_controllers"], check_controllers=k["check_controllers"],
                reset_controllers=k["reset_controllers"],
                reset_controllers_prompt=k["reset_controllers_prompt"], joint_states_topic=k["joint_states_topic"],
                loop=loop, safety=safety, joint_state_timeout=k["joint_state_timeout"],
                startup_timeout=k["startup_timeout"], timeout_sec=k["timeout_sec"],
                reset_joint_speed=k["reset_joint_speed"], reset_tolerance=k["reset_tolerance"],
                reset_settle_tolerance=k["reset_settle_tolerance"],
                reset_timeout=k["reset_timeout"], reset_env_prompt=k["reset_env_prompt"],
                close_env_prompt=k["close_env_prompt"], use_sim_time=k["use_sim_time"],
                log_internal_state=k["log_internal_state"])
            self.robot_name = self.connection.robot_name
        except BaseException:
            self.close()
            raise

    # -- what the robot's connection holds, by its documented names -------------------------------
    @property
    def link(self) -> RobotLink:
        """The robot's standard ROS 2 interfaces (joint states, controller manager, controller topics)."""
        return self.connection.link

    @property
    def safety(self) -> SafetyRules | None:
        """The safety rules every arm command passes."""
        return self.connection.safety

    @safety.setter
    def safety(self, rules: SafetyRules | None) -> None:
        self.connection.safety = rules

    @property
    def loop(self) -> ControlLoop:
        return self.connection.loop

    @property
    def namespace(self) -> str:
        return self.connection.namespace

    @property
    def arm_joints(self) -> tuple[str, ...]:
        return self.connection.arm_joints

    @property
    def arm_controller(self) -> str | None:
        return self.connection.arm_controller

    @property
    def controllers_list(self) -> list[str]:
        return self.connection.controllers_list

    @property
    def last_command(self) -> np.ndarray | None:
        """The last joint target sent to the arm controller."""
        return self.connection.last_command

    @property
    def last_decision(self) -> SafetyDecision | None:
        """The safety rules' decision on the last arm command."""
        return self.connection.last_decision

    @property
    def robot_driver(self) -> str:
        """The one publisher of the robot's ``joint_states`` (``namespace/node``, with its session)."""
        return self.connection.driver()

    @property
    def commands_sent(self) -> int:
        return self.connection.commands_sent

    @property
    def robot_state(self) -> RobotState:
        """The state observed after the last step or reset."""
        return self.connection.state

    @property
    def state_age(self) -> float:
        """Seconds between the observed state's arrival and now."""
        return self.connection.state.age()

    @property
    def robot_time(self) -> float | None:
        """The robot side's ``/clock`` (with ``use_sim_time``), else ``None``."""
        return self.connection.robot_time

    # -- commanding ---------------------------------------------------------------------------------
    def send_joint_targets(self, targets: Sequence[float] | np.ndarray) -> SafetyDecision:
        """Command the arm: the safety rules first, then the arm controller (nothing sent if refused).

        The decision goes to ``info["safety"]``. Raises :class:`UnsafeCommandError` for NaN/infinite or
        wrong-length targets and :class:`StaleStateError` when the state is too old to act on.
        """
        return self.connection.send_joint_targets(targets, self.info)

    def send_command(self, controller: str, command: Sequence[float] | np.ndarray) -> None:
        """Command a controller by name: the arm controller goes through :meth:`send_joint_targets`;
        another (e.g. a gripper's forward command controller) gets finite values on ``<controller>/commands``."""
        if controller == self.connection.arm_controller:
            self.send_joint_targets(command)
            return
        self.connection.command(controller, np.asarray(command, dtype=np.float64))

    def close(self) -> None:
        """Stop talking to the robot; nothing more is sent (it holds its last command)."""
        if getattr(self, "_closed", False):
            return
        self._closed = True
        super().close()
        node = getattr(self, "node", None)
        if node is not None:
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001
                pass
        ctx = getattr(self, "context", None)
        if ctx is not None and getattr(self, "_owns_context", False):
            ctx.try_shutdown()
