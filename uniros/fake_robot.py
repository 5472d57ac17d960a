"""``uniros-fake-robot``, also from an arm file: ``uniros-fake-robot --arm PATH``.

The fake ros2_control robot (:mod:`multiros.hardware.fake_robot`) knows robots by their description
and controllers YAML; an arm file (:mod:`rl_environments.arm_file`) also says how the arm's vendor
driver names things (its ``real:`` section). This module, in the layer that knows arm files, turns one
into the fake robot's :class:`~multiros.hardware.robot_spec.RobotSpec`, so the fake robot serves
what the arm's Real twins (``<NAME><task>Real-v0``) expect of the real driver, by the same names:

* ``joint_states`` on ``real.joint_states_topic`` (default ``<namespace>/joint_states``), every
  joint of the description (``description.uri`` with ``xacro_args``);
* the controller manager in ``real.namespace``;
* ``real.arm_controller`` as a JointTrajectoryController over ``arm.joints``, with its
  ``joint_trajectory`` topic and ``follow_joint_trajectory`` action (its parameters, tolerances
  included, from the description's controllers YAML when that defines it as one over those joints);
* the gripper controller as ``real.gripper_interface`` says: ``trajectory`` (a JointTrajectoryController
  on ``real.gripper_joint``, default the first finger joint), ``forward`` (a JointGroupPositionController),
  ``gripper_action`` (a ``control_msgs/action/GripperCommand`` server on ``<controller>/gripper_cmd``,
  the goal's position mapped from ``real.gripper_range`` onto the fingers' closed..open), and none for
  ``none`` and ``niryo_tool`` (Niryo's tool commander, whose interface uniros does not ship);
* each of ``real.controllers`` the YAML defines as it defines it, any other as a placeholder that is
  listed active and claims no joint (the Real twin only checks that it is active).

The joints start at the arm file's ``arm.home`` (``--start init``: ``reach.init_joint_pos``, the
pose a reset moves to). ``--gap PROFILE`` works as without ``--arm``, its ``droop_joints`` indexing
``arm.joints``. Without ``--arm`` the command is the lower layer's, unchanged.
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from multiros.bounded_yaml import YamlBoundsError, read_yaml_bounded
from multiros.hardware import fake_robot as _fake
from multiros.hardware.robot_spec import RobotSpec, load_robot_spec, parse_assignments
from multiros.ros.names import split_ros_arguments
from multiros.ros.processes import start_child_program
from multiros.sim.errors import SimError

if TYPE_CHECKING:  # imported when used: rl_environments registers every ID on import
    from rl_environments.arm_file import ArmFile

__all__ = ["ArmRobotError", "GripperActionServer", "arm_robot_spec", "build_parser", "gripper_joint", "main",
           "vendor_controllers"]

_JTC = "joint_trajectory_controller/JointTrajectoryController"
_FORWARD = "position_controllers/JointGroupPositionController"
_BROADCASTER = "joint_state_broadcaster/JointStateBroadcaster"
#: Options the arm file answers; with ``--arm`` they are errors.
_ARM_ANSWERS = {"robot": "--robot", "description": "--description", "xacro_arg": "--xacro-arg",
                "controllers_file": "--controllers-file", "controller_name": "--controller-name"}


class ArmRobotError(ValueError):
    """An arm file the fake robot cannot serve (one line: the file, the key, the fix)."""


def _yaml_controllers(arm: ArmFile) -> dict[str, Any]:
    """The description's controllers YAML (``description.controllers``) as a mapping ({} if unreadable)."""
    from multiros.excerpt import error_line
    from multiros.sim.packages import default_index

    uri = arm.controllers_file
    try:
        path = default_index().resolve_uri(uri) if uri.startswith("package://") else Path(uri)
        data = read_yaml_bounded(path) or {}
    except (OSError, YamlBoundsError, SimError) as exc:
        raise ArmRobotError(f"{arm.path}: key 'description.controllers' ({uri}): cannot be read: "
                            f"{error_line(exc)}") from None
    if not isinstance(data, dict):
        raise ArmRobotError(f"{arm.path}: key 'description.controllers' ({uri}) is not a ros2_control YAML mapping")
    return data


def _defined(config: Mapping[str, Any], name: str) -> tuple[str | None, dict[str, Any]]:
    """A controller's type and parameters in a ros2_control YAML (``(None, {})`` when it is not there)."""
    cm = (config.get("controller_manager") or {}).get("ros__parameters") or {}
    entry = cm.get(name)
    if not isinstance(entry, Mapping) or "type" not in entry:
        return None, {}
    params = (config.get(name) or {}).get("ros__parameters") or {}
    return str(entry["type"]), dict(params) if isinstance(params, Mapping) else {}


def gripper_joint(arm: ArmFile) -> str | None:
    """The joint the real gripper controller commands (``real.gripper_joint``, else the first finger)."""
    if arm.gripper is None:
        return None
    return arm.real.gripper_joint or arm.gripper.joints[0]


def vendor_controllers(arm: ArmFile, yaml_config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The ros2_control YAML (as a mapping) of the arm's real driver, as its ``real:`` section names it.

    Args:
        arm: a loaded :class:`~rl_environments.arm_file.ArmFile`.
        yaml_config: the description's controllers YAML (default: read from ``description.controllers``);
            a controller it defines under a ``real:`` name lends its parameters.
    """
    real = arm.real
    config = _yaml_controllers(arm) if yaml_config is None else yaml_config
    cm: dict[str, Any] = {"update_rate": 100, "joint_state_broadcaster": {"type": _BROADCASTER}}
    out: dict[str, Any] = {}

    def add(name: str, type_name: str, params: Mapping[str, Any]) -> None:
        if name in cm:
            raise ArmRobotError(f"{arm.path}: key 'real' names controller {name!r} twice (arm, gripper and "
                                "real.controllers must be different controllers)")
        cm[name] = {"type": type_name}
        out[name] = {"ros__parameters": dict(params)}

    kind, params = _defined(config, real.arm_controller)
    if kind != _JTC or list(params.get("joints") or []) != list(arm.joints):
        params = {}
    add(real.arm_controller, _JTC, {"command_interfaces": ["position"], "state_interfaces": ["position", "velocity"],
                                    **params, "joints": list(arm.joints)})
    joint = gripper_joint(arm)
    interface = real.gripper_interface if arm.gripper is not None else "none"
    if interface in ("trajectory", "forward", "gripper_action"):
        if not real.gripper_controller:
            raise ArmRobotError(f"{arm.path}: key 'real.gripper_controller' is empty but real.gripper_interface is "
                                f"{interface!r}: name the driver's gripper controller")
        kind, params = _defined(config, real.gripper_controller)
        wanted = _JTC if interface == "trajectory" else _FORWARD
        assert arm.gripper is not None
        # Two independently driven fingers: the driver's trajectory or forward controller takes both.
        joints = [joint, arm.gripper.joints[1]] if arm.gripper.independent and interface != "gripper_action" \
            else [joint]
        if kind != wanted or list(params.get("joints") or []) != joints:
            params = {}
        if interface == "trajectory":
            params = {"command_interfaces": ["position"], "state_interfaces": ["position", "velocity"], **params}
        # A GripperActionController is served as a position controller on the joint plus the action
        # (GripperActionServer): the fake robot's controller manager has no such controller type.
        add(real.gripper_controller, wanted, {**params, "joints": joints})
    for name in real.controllers:
        if name in cm:
            continue
        kind, params = _defined(config, name)
        if kind is None or kind == _BROADCASTER:
            add(name, _BROADCASTER, {})  # a placeholder: listed, activated, claims no joint
        else:
            add(name, kind, params)
    return {"controller_manager": {"ros__parameters": cm}, **out}


def arm_robot_spec(arm: ArmFile, *, start: str = "home", namespace: str | None = None,
                   initial_positions: Mapping[str, float] | None = None) -> RobotSpec:
    """The fake robot of an arm file (see the module docstring).

    Args:
        arm: a loaded :class:`~rl_environments.arm_file.ArmFile`.
        start: ``"home"`` (``arm.home``) or ``"init"`` (``reach.init_joint_pos``).
        namespace: overrides ``real.namespace``.
        initial_positions: start positions overriding ``start``'s, per joint.

    Raises:
        ArmRobotError: the description cannot be loaded, or the ``real:`` names do not fit it.
    """
    from multiros.excerpt import error_line

    if start not in ("home", "init"):
        raise ArmRobotError(f"start must be 'home' or 'init', got {start!r}")
    pose = arm.home if start == "home" else tuple(arm.reach["init_joint_pos"])
    initial = {**dict(zip(arm.joints, pose)), **dict(initial_positions or {})}
    try:
        spec = load_robot_spec(None, description=arm.description_uri, xacro_args=dict(arm.xacro_args),
                               controllers_file="", namespace=arm.real.namespace if namespace is None else namespace,
                               initial_positions=initial)
    except ValueError as exc:
        if initial_positions and "unknown joints" in str(exc):
            raise ArmRobotError(f"--initial: {exc}") from None
        raise ArmRobotError(f"{arm.path}: key 'arm.joints': {exc}") from None
    except (OSError, SimError) as exc:
        raise ArmRobotError(f"{arm.path}: key 'description.uri' ({arm.description_uri}): {error_line(exc)}") \
            from None
    joints = [j.name for j in spec.joints]
    mimics = [m.name for m in spec.mimics]
    missing = [j for j in arm.joints if j not in joints]
    if missing:
        where = "mimic joints" if set(missing) & set(mimics) else "not hardware joints"
        raise ArmRobotError(f"{arm.path}: key 'arm.joints': {missing} are {where} of the description "
                            f"(its ros2_control joints: {joints})")
    joint = gripper_joint(arm)
    if joint is not None and arm.real.gripper_interface not in ("none", "niryo_tool") and joint not in joints:
        key = "real.gripper_joint" if arm.real.gripper_joint else "gripper.joints"
        raise ArmRobotError(f"{arm.path}: key {key!r}: {joint!r} is not a commandable joint of the description "
                            f"(its ros2_control joints: {joints})")
    spec.controllers = vendor_controllers(arm)
    spec.name = arm.robot_name
    spec.arm_joints = list(arm.joints)  # what --gap's droop_joints index into
    return spec


class GripperActionServer:
    """``<ns>/<controller>/gripper_cmd`` (``control_msgs/action/GripperCommand``) of a fake robot, over
    the position controller of the same name: a goal's position (the driver's units, ``real_range``
    at the fingers' ``(closed, open)``) becomes the finger joint's target; the goal succeeds once the
    joint is within ``tolerance`` of it, or reports ``stalled`` when the joint stops short (a cube
    between the fingers) for ``stall_timeout`` seconds, as ros2_control's GripperActionController
    does; it aborts after ``goal_timeout`` seconds otherwise, or when a newer goal preempts it.
    """

    def __init__(self, robot: Any, controller: str, joint: str, finger_range: Sequence[float],
                 real_range: Sequence[float] | None = None, *, tolerance: float = 1e-3,
                 stall_timeout: float = 1.0, goal_timeout: float = 30.0) -> None:
        from multiros.ros.action import ActionServer, CancelResponse
        from multiros.ros.interfaces import get_action

        self.robot, self.controller, self.joint = robot, controller, joint
        self.finger_range = (float(finger_range[0]), float(finger_range[1]))
        self.real_range = self.finger_range if real_range is None else (float(real_range[0]), float(real_range[1]))
        if self.real_range[0] == self.real_range[1] or self.finger_range[0] == self.finger_range[1]:
            raise ValueError(f"gripper ranges must not be empty: fingers {self.finger_range}, driver {self.real_range}")
        self.tolerance, self.stall_timeout = float(tolerance), float(stall_timeout)
        self.goal_timeout = float(goal_timeout)
        self._type = get_action("control_msgs/action/GripperCommand")
        self._index = list(robot.hardware.joint_names(robot.spec.name)).index(joint)
        self._lock = threading.Lock()
        self._latest: Any = None
        self._server = ActionServer(robot.node, self._type, f"{robot.ns}/{controller}/gripper_cmd", self._execute,
                                    goal_callback=self._accept, handle_accepted_callback=self._start,
                                    cancel_callback=lambda handle: CancelResponse.ACCEPT)

    def to_joint(self, value: float) -> float:
        """The finger joint's position for the driver's ``value`` (linear, clipped to closed..open)."""
        (lo, hi), (rlo, rhi) = self.finger_range, self.real_range
        finger = lo + (float(value) - rlo) / (rhi - rlo) * (hi - lo)
        return float(min(max(finger, min(lo, hi)), max(lo, hi)))

    def to_driver(self, finger: float) -> float:
        (lo, hi), (rlo, rhi) = self.finger_range, self.real_range
        return rlo + (float(finger) - lo) / (hi - lo) * (rhi - rlo)

    def _accept(self, goal: Any) -> Any:
        from multiros.ros.action import GoalResponse

        if not math.isfinite(goal.command.position) or not math.isfinite(goal.command.max_effort):
            self.robot.node.get_logger().warning("%s/%s/gripper_cmd: goal rejected: position %r, max_effort %r "
                                                 "must be finite", self.robot.ns, self.controller,
                                                 goal.command.position, goal.command.max_effort)
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _start(self, handle: Any) -> None:
        with self._lock:
            self._latest = handle  # a new goal preempts the running one
        handle.execute()

    def _position(self) -> tuple[float, float]:
        with self.robot.hardware.lock:
            state = self.robot.hardware.joint_state()
        return float(state.position[self._index]), float(state.velocity[self._index])

    def _execute(self, handle: Any) -> Any:
        target = self.to_joint(handle.request.command.position)
        result = self._type.Result()
        hw = self.robot.hardware
        try:
            with hw.lock:
                hw.set_command(self.robot.spec.name, self.controller, [target])
        except Exception as exc:  # noqa: BLE001 - an inactive controller: abort, keep serving
            self.robot.node.get_logger().warning("%s/%s/gripper_cmd: %s", self.robot.ns, self.controller, exc)
            handle.abort()
            return result
        still_since = None
        deadline = time.monotonic() + self.goal_timeout
        while True:
            position, velocity = self._position()
            result.position, result.effort = self.to_driver(position), 0.0
            if handle.is_cancel_requested:
                handle.canceled()
                return result
            with self._lock:
                preempted = self._latest is not handle
            if preempted:
                handle.abort()
                return result
            if abs(position - target) <= self.tolerance:
                result.reached_goal = True
                handle.succeed()
                return result
            now = time.monotonic()
            if now > deadline:  # neither there nor stalled (a joint still creeping): give up, as a driver would
                handle.abort()
                return result
            still_since = (still_since or now) if abs(velocity) < 1e-4 else None
            if still_since is not None and now - still_since >= self.stall_timeout:
                result.stalled = True
                handle.succeed()
                return result
            feedback = self._type.Feedback()
            feedback.position, feedback.effort = result.position, 0.0
            handle.publish_feedback(feedback)
            time.sleep(0.02)

    def destroy(self) -> None:
        self._server.destroy(timeout_sec=1.0)


def build_parser() -> argparse.ArgumentParser:
    """``uniros-fake-robot``'s command line: the lower layer's, with ``--arm`` and ``--start``."""
    parser = _fake.build_parser()
    parser.description = (parser.description or "") + (
        " With --arm PATH, the robot of an arm file, named as its vendor driver names things (its real: section).")
    parser.add_argument("--arm", metavar="PATH", help="an arm file (config/arms/*.yaml, or yours): its description, "
                                                       "namespace, controllers and joint_states topic as its "
                                                       "real: section names them")
    parser.add_argument("--start", choices=["home", "init"], default=None,
                        help="with --arm: start at arm.home (default) or at reach.init_joint_pos")
    physics = parser.add_argument_group(
        "physics mode (with --arm)", "the robot in a MuJoCo world of its own with the task's table and object, "
        "the object's pose on the tracker topic the Real twins read (docs/fake_robot.md, Physics mode)")
    physics.add_argument("--physics", metavar="TASK", default=None,
                         help="push, pnp or slide: the Sim twin's scene of that task")
    physics.add_argument("--physics-perturb", action="append", default=[], metavar="KEY=SCALE",
                         help="scale a physical value (KEY=SCALE or KEY=LOW:HIGH, drawn once from --physics-seed; "
                              "keys: object_mass, object_friction, object_size, table_friction, link_mass, "
                              "joint_damping, joint_friction, joint_armature, actuator_gain), a profile (mild, "
                              "hard) or a YAML file of them; repeatable, later ones win")
    physics.add_argument("--physics-seed", type=int, default=0, metavar="N",
                         help="seed of the perturbations' draws, the object's start poses and the tracker's noise (0)")
    physics.add_argument("--physics-reset", default="random", metavar="MODE",
                         help="where the object is put back when the arm returns to the task's start pose: random "
                              "(in the start box, default), spawn (the box's centre) or none")
    physics.add_argument("--physics-timestep", type=float, default=0.004, metavar="SEC",
                         help="physics time step (0.004 s, the Sim twins')")
    physics.add_argument("--object-topic", default="/object_pose", metavar="TOPIC",
                         help="the tracker's PoseStamped topic (%(default)s, the Real twins' object_pose_topic)")
    physics.add_argument("--tracker-rate", type=float, default=50.0, metavar="HZ", help="tracker rate (%(default)s)")
    physics.add_argument("--tracker-noise", type=float, default=0.0, metavar="M",
                         help="std of Gaussian noise on the tracked position, m (0)")
    physics.add_argument("--tracker-latency", type=float, default=0.0, metavar="SEC",
                         help="seconds from a pose's capture to its message (0)")
    for action in parser._actions:
        if action.dest == "robot":
            action.help = f"{action.help}; also the shipped arm files' robots (vx300s, ur5e, ned2: as --arm <file>)"
    return parser


def _attach(arm: ArmFile) -> Callable[[Any], Callable[[], None] | None]:
    """The GripperCommand server of an arm whose driver takes the gripper through one."""

    def attach(robot: Any) -> Callable[[], None] | None:
        joint, gripper = gripper_joint(arm), arm.gripper
        if joint is None or gripper is None or arm.real.gripper_interface != "gripper_action":
            return None
        server = GripperActionServer(robot, arm.real.gripper_controller, joint, (gripper.closed, gripper.open),
                                     arm.real.gripper_range)
        return server.destroy

    return attach


def _physics(arm: ArmFile, spec: RobotSpec, opts: argparse.Namespace,
             fail: Callable[[str], None]) -> tuple[Callable[[Any, int], Any], Callable[[Any], Any]]:
    """``--physics``: the hardware factory and the attach of the physics stand-in (bad options: ``fail``)."""
    import numpy as np

    from uniros import physics_stand_in as ps

    try:
        if opts.time_constant is not None:
            raise ps.PhysicsOptionError("--time-constant: with --physics the physics' servos are the joints' own "
                                        "(a lag: --gap-set time_constant=SEC)")
        if opts.physics_reset not in ps.RESET_MODES:
            raise ps.PhysicsOptionError(f"--physics-reset {opts.physics_reset!r}: one of {', '.join(ps.RESET_MODES)}")
        if not (math.isfinite(opts.physics_timestep) and 1e-4 <= opts.physics_timestep <= 0.02):
            raise ps.PhysicsOptionError(f"--physics-timestep must be within [0.0001, 0.02] s, got "
                                        f"{opts.physics_timestep}")
        for flag, value, lo, hi in (("--tracker-rate", opts.tracker_rate, 0.1, 1000.0),
                                    ("--tracker-noise", opts.tracker_noise, 0.0, 1.0),
                                    ("--tracker-latency", opts.tracker_latency, 0.0, 2.0)):
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ps.PhysicsOptionError(f"{flag} must be within [{lo:g}, {hi:g}], got {value}")
        if not opts.object_topic.strip("/") or any(c.isspace() for c in opts.object_topic):
            raise ps.PhysicsOptionError(f"--object-topic {opts.object_topic!r} is not a topic name")
        scene = ps.physics_scene(arm, opts.physics)
        ranges = ps.parse_perturbation(opts.physics_perturb)
    except ps.PhysicsOptionError as exc:
        fail(str(exc))
        raise  # not reached: fail exits
    perturb, placing, tracking = np.random.SeedSequence(opts.physics_seed).spawn(3)
    scales = ps.draw_scales(ranges, np.random.default_rng(perturb))
    made: list[Any] = []

    def hardware(gap: Any, seed: int) -> Any:
        made.append(ps.physics_hardware(spec, arm, scene, scales, gap=gap, seed=seed,
                                        timestep=opts.physics_timestep))
        return made[-1]

    def attach(robot: Any) -> Callable[[], None] | None:
        from multiros.hardware.tracker import PoseTracker

        close_gripper = _attach(arm)(robot)
        hw = made[-1]
        helper = ps.LabHelper(hw, scene, arm.joints, opts.physics_reset, np.random.default_rng(placing))
        topic = opts.object_topic if opts.object_topic.startswith("/") else f"{robot.ns}/{opts.object_topic}"
        tracker = PoseTracker(robot.node, hw, scene.object.name, topic, scene.frame_id, scene.base,
                              rate=opts.tracker_rate, noise=opts.tracker_noise, latency=opts.tracker_latency,
                              rng=np.random.default_rng(tracking), on_tick=helper.check)
        unlisten = ps.place_object_listener(robot.node, f"{robot.ns}/physics/place_object", helper, scene.frame_id)
        tracker.start()
        print(f"uniros-fake-robot: physics {opts.physics}: object on {topic} (frame {scene.frame_id}), perturbed "
              f"{ {k: round(v, 4) for k, v in scales.items()} }, put back: {opts.physics_reset}", file=sys.stderr)

        def detach() -> None:
            tracker.destroy()
            unlisten()
            if close_gripper is not None:
                close_gripper()
            hw.close()

        return detach

    return hardware, attach


def _shipped_arm_as_arm(args: list[str]) -> list[str]:
    """``--robot vx300s`` (a shipped arm file's robot, not a preset of the lower layer) as ``--arm <its file>``
    (not beside an ``--arm`` of its own: that stays the error it is). ``args``: the program's own arguments
    (the ROS ones split off)."""
    if any(arg == "--arm" or arg.startswith("--arm=") for arg in args):
        return args
    for i, arg in enumerate(args):
        name = (args[i + 1] if arg == "--robot" and i + 1 < len(args)
                else arg[len("--robot="):] if arg.startswith("--robot=") else None)
        if name is None or name in _fake.PRESETS:
            continue
        from rl_environments import shipped_arm_file

        path = shipped_arm_file(f"{name}.yaml")
        if path is not None:
            return [*args[:i], "--arm", str(path), *args[i + (2 if arg == "--robot" else 1):]]
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """``uniros-fake-robot``: ``--arm PATH`` serves an arm file's robot; anything else is the lower layer's."""
    parser = build_parser()
    args = list(sys.argv[1:] if argv is None else argv)
    own, ros_args = split_ros_arguments(args)
    own = _shipped_arm_as_arm(own)  # with --arm the lower layer's main is not reached: `args` is not used
    opts = parser.parse_args(own)
    if not opts.arm:
        if opts.start is not None:
            parser.error("--start needs --arm")
        if opts.physics is not None:
            parser.error("--physics needs --arm")
        return _fake.main(args)
    given = [flag for key, flag in _ARM_ANSWERS.items() if getattr(opts, key)]
    if given:
        parser.error(f"{', '.join(given)}: the arm file names the description and the controllers; give --arm alone "
                     "(--namespace, --initial and --activate still override)")
    stop = start_child_program(opts)
    from rl_environments.arm_file import ArmFileError, load_arm_file

    try:
        arm = load_arm_file(opts.arm)
        initial = {k: float(v) for k, v in parse_assignments(opts.initial, "--initial").items()}
        spec = arm_robot_spec(arm, start=opts.start or "home", namespace=opts.namespace, initial_positions=initial)
    except (ArmFileError, ArmRobotError, ValueError) as exc:
        parser.exit(2, f"uniros-fake-robot: {exc}\n")
    if opts.physics is None:
        return _fake.serve(spec, opts, parser, stop, joint_states_topic=arm.real.joint_states_topic,
                           attach=_attach(arm), ros_args=ros_args)
    hardware, attach = _physics(arm, spec, opts, lambda line: parser.exit(2, f"uniros-fake-robot: {line}\n"))
    return _fake.serve(spec, opts, parser, stop, joint_states_topic=arm.real.joint_states_topic, attach=attach,
                       ros_args=ros_args, hardware=hardware)


if __name__ == "__main__":
    sys.exit(main())
