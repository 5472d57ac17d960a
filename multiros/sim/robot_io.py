"""The ROS interfaces of one robot in the simulation node, in the robot's namespace.

* ``joint_states`` (``sensor_msgs/JointState``), ``/tf`` (its links in the ``world`` frame) and
  ``robot_description`` (``std_msgs/String``, transient local);
* controller command topics in ros2_control style: ``<controller>/commands``
  (``std_msgs/Float64MultiArray``) for forward command controllers and
  ``<controller>/joint_trajectory`` (``trajectory_msgs/JointTrajectory``) for trajectory controllers;
* controller-manager services: ``controller_manager/list_controllers``, ``load_controller``,
  ``configure_controller``, ``switch_controller``, ``unload_controller``.

State topics are published only when someone subscribes, so the lockstep hot path pays nothing
for them.
"""

from __future__ import annotations

import threading
from typing import Any

from multiros.ros.qos import DurabilityPolicy, QoSProfile
from multiros.sim import convert
from multiros.sim.actions import TrajectoryActions
from multiros.sim.controllers import JointTrajectoryController
from multiros.sim.distro_adapters import create_services, get_message, get_service
from multiros.sim.errors import CommandError, ControllerError
from multiros.sim.services import CONTROLLER_SERVICES

JointState = get_message("sensor_msgs/msg/JointState")
String = get_message("std_msgs/msg/String")
Float64MultiArray = get_message("std_msgs/msg/Float64MultiArray")
JointTrajectory = get_message("trajectory_msgs/msg/JointTrajectory")
TFMessage = get_message("tf2_msgs/msg/TFMessage")
TransformStamped = get_message("geometry_msgs/msg/TransformStamped")
ControllerState = get_message("controller_manager_msgs/msg/ControllerState")
ListControllers = get_service(CONTROLLER_SERVICES["list_controllers"])
LoadController = get_service(CONTROLLER_SERVICES["load_controller"])
ConfigureController = get_service(CONTROLLER_SERVICES["configure_controller"])
SwitchController = get_service(CONTROLLER_SERVICES["switch_controller"])
UnloadController = get_service(CONTROLLER_SERVICES["unload_controller"])

_LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class RobotInterfaces:
    """Topics and controller services of one robot entity.

    Args:
        node: the simulation node.
        world: its world.
        info: the robot's :class:`~multiros.sim.world.EntityInfo`.
        lock: the node's lock, held around every world access.
    """

    def __init__(self, node: Any, world: Any, info: Any, lock: threading.RLock) -> None:
        self.node = node
        self.world = world
        self.name = info.name
        self.lock = lock
        ns = info.namespace.rstrip("/") or ""
        self.ns = ns
        self._names = list(world.joint_names(info.name))
        self._frames = world.frame_set(info.frames, info.name) if info.frames else None
        self._frame_names = [f"{info.name}/{f}" for f in info.frames]
        self._joint_pub = node.create_publisher(JointState, f"{ns}/joint_states", 10)
        self._tf_pub = node.create_publisher(TFMessage, "/tf", 100)
        self._description_pub = node.create_publisher(String, f"{ns}/robot_description", _LATCHED)
        self._description_pub.publish(String(data=info.description))
        self._command_subs: dict[str, Any] = {}
        self._actions = TrajectoryActions(node, world, info.name, ns, lock)  # follow_joint_trajectory
        cm = f"{ns}/controller_manager"
        handlers = {"list_controllers": self._list, "load_controller": self._load,
                    "configure_controller": self._configure, "switch_controller": self._switch,
                    "unload_controller": self._unload}
        self._services = [  # every served distribution's variant (multiros.sim.distro_adapters)
            srv for name, type_name in CONTROLLER_SERVICES.items()
            for srv in create_services(node, type_name, f"{cm}/{name}", handlers[name])
        ]
        for controller in world.controller_manager(info.name).list_controllers():
            self._subscribe_commands(controller.name)

    # -- state topics -----------------------------------------------------------------------
    def fill_joint_state(self, msg: Any) -> Any:
        """Write the robot's joint state (copies) into a ``sensor_msgs/JointState``."""
        js = self.world.joint_state(self.name)
        msg.header.stamp = convert.time_msg(self.world.time)
        msg.name = self._names
        msg.position = js.position.copy()
        msg.velocity = js.velocity.copy()
        msg.effort = js.effort.copy()
        return msg

    def publish_state(self) -> None:
        """Publish ``joint_states`` and ``/tf`` if anyone listens (caller holds the lock)."""
        self._actions.on_step()
        if self._joint_pub.get_subscription_count() > 0:
            self._joint_pub.publish(self.fill_joint_state(JointState()))
        if self._frames is not None and self._tf_pub.get_subscription_count() > 0:
            stamp = convert.time_msg(self.world.time)
            transforms = []
            for child, row in zip(self._frame_names, self._frames.poses()):
                tf = TransformStamped()
                tf.header.stamp = stamp
                tf.header.frame_id = "world"
                tf.child_frame_id = child
                t, r = tf.transform.translation, tf.transform.rotation
                t.x, t.y, t.z = float(row[0]), float(row[1]), float(row[2])
                r.w, r.x, r.y, r.z = float(row[3]), float(row[4]), float(row[5]), float(row[6])
                transforms.append(tf)
            self._tf_pub.publish(TFMessage(transforms=transforms))

    def on_reset(self) -> None:
        """Called after a world reset (state topics are refreshed on the next step)."""

    # -- controller command topics ----------------------------------------------------------
    def _subscribe_commands(self, controller: str) -> None:
        if controller in self._command_subs:
            return
        ctrl = self.world.controller_manager(self.name).get(controller)
        if not ctrl.command_interfaces:
            return
        if isinstance(ctrl, JointTrajectoryController):
            self._actions.add(controller, ctrl)
            sub = self.node.create_subscription(
                JointTrajectory, f"{self.ns}/{controller}/joint_trajectory",
                lambda msg, c=controller: self._on_trajectory(c, msg), 10,
            )
        else:
            sub = self.node.create_subscription(
                Float64MultiArray, f"{self.ns}/{controller}/commands",
                lambda msg, c=controller: self._on_command(c, msg), 10,
            )
        self._command_subs[controller] = sub

    def _unsubscribe_commands(self, controller: str) -> None:
        self._actions.remove(controller)
        sub = self._command_subs.pop(controller, None)
        if sub is not None:
            self.node.destroy_subscription(sub)

    def _on_command(self, controller: str, msg: Any) -> None:
        with self.lock:
            try:
                self.world.set_command(self.name, controller, msg.data)
            except (CommandError, ControllerError) as exc:
                self.node.get_logger().warning("%s/%s/commands: %s (ignored)", self.ns, controller, exc)

    def _on_trajectory(self, controller: str, msg: Any) -> None:
        times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points]
        velocities = [p.velocities for p in msg.points] if all(len(p.velocities) for p in msg.points) else None
        with self.lock:
            try:
                ctrl = self.world.controller_manager(self.name).get(controller)
                if ctrl.state != "active":
                    raise ControllerError(f"controller '{controller}' is {ctrl.state}")
                ctrl.set_trajectory(list(msg.joint_names), [p.positions for p in msg.points], times, velocities,
                                    time=self.world.time)
                self.world.controllers_changed(self.name)
            except (CommandError, ControllerError) as exc:
                self.node.get_logger().warning("%s/%s/joint_trajectory: %s (ignored)", self.ns, controller, exc)

    # -- controller manager services ----------------------------------------------------------
    def _list(self, request: Any, response: Any) -> Any:
        with self.lock:
            infos = self.world.controller_manager(self.name).list_controllers()
        response.controller = [
            ControllerState(
                name=i.name, state=i.state, type=i.type, claimed_interfaces=list(i.claimed_interfaces),
                required_command_interfaces=list(i.required_command_interfaces),
                required_state_interfaces=list(i.required_state_interfaces),
            )
            for i in infos
        ]
        return response

    def _manage(self, response: Any, action: Any) -> Any:
        with self.lock:
            try:
                action(self.world.controller_manager(self.name))
                self.world.controllers_changed(self.name)
                response.ok = True
            except ControllerError as exc:
                self.node.get_logger().warning("%s/controller_manager: %s", self.ns, exc)
                response.ok = False
                if hasattr(response, "message"):  # SwitchController since ros2_control 4 (Jazzy)
                    response.message = str(exc)
        return response

    def _load(self, request: Any, response: Any) -> Any:
        def load(cm: Any) -> None:
            cm.load(request.name)
            self._subscribe_commands(request.name)

        return self._manage(response, load)

    def _configure(self, request: Any, response: Any) -> Any:
        return self._manage(response, lambda cm: cm.configure(request.name))

    def _switch(self, request: Any, response: Any) -> Any:
        strict = int(request.strictness) != SwitchController.Request.BEST_EFFORT
        return self._manage(
            response,
            lambda cm: cm.switch(list(request.activate_controllers), list(request.deactivate_controllers),
                                 strict=strict, time=self.world.time),
        )

    def _unload(self, request: Any, response: Any) -> Any:
        def unload(cm: Any) -> None:
            cm.unload(request.name)
            self._unsubscribe_commands(request.name)

        return self._manage(response, unload)

    # -- teardown ---------------------------------------------------------------------------
    def destroy(self) -> None:
        """Destroy every publisher, subscription, service and action of this robot."""
        self._actions.destroy()
        for name in list(self._command_subs):
            self._unsubscribe_commands(name)
        for srv in self._services:
            self.node.destroy_service(srv)
        self._services = []
        for pub in (self._joint_pub, self._tf_pub, self._description_pub):
            self.node.destroy_publisher(pub)


__all__ = ["RobotInterfaces"]
