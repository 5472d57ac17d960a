"""The ROS surface of one robot's ros2_control controller manager, in the robot's namespace.

* controller-manager services: ``controller_manager/list_controllers``, ``load_controller``,
  ``configure_controller``, ``switch_controller``, ``unload_controller``, and what ``ros2 control``
  asks besides: ``list_hardware_interfaces`` (every joint's position, velocity and effort
  interfaces, claimed or not), ``list_hardware_components`` (one system per robot, always active),
  ``list_controller_types`` and ``set_hardware_component_state`` (only ``active`` is accepted:
  the simulated hardware cannot be switched off) (every served distribution's variant,
  :mod:`multiros.sim.distro_adapters`);
* controller command topics: ``<controller>/commands`` (``std_msgs/Float64MultiArray``) for forward
  command controllers, ``<controller>/joint_trajectory`` (``trajectory_msgs/JointTrajectory``) plus
  the ``follow_joint_trajectory`` action (:class:`~multiros.sim.actions.TrajectoryActions`) for
  trajectory controllers; malformed commands are ignored with a log line.

Shared by the simulation node (:mod:`multiros.sim.robot_io`, over a :class:`~multiros.sim.world.World`)
and the fake robot (:mod:`multiros.hardware.fake_robot`, over its ``FakeHardware``): both pass a
"world" offering ``controller_manager(robot)``, ``controllers_changed(robot)``,
``set_command(robot, controller, values)`` and ``time``.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

from multiros.ros.logging import LogThrottle
from multiros.sim.actions import TrajectoryActions
from multiros.sim.controllers import CONTROLLER_TYPES, JointTrajectoryController
from multiros.sim.distro_adapters import create_services, get_message, get_service
from multiros.sim.errors import CommandError, ControllerError
from multiros.sim.services import CONTROLLER_SERVICES

__all__ = ["ControllerInterfaces"]

Float64MultiArray = get_message("std_msgs/msg/Float64MultiArray")
JointTrajectory = get_message("trajectory_msgs/msg/JointTrajectory")
ControllerState = get_message("controller_manager_msgs/msg/ControllerState")
SwitchController = get_service(CONTROLLER_SERVICES["switch_controller"])
HardwareInterface = get_message("controller_manager_msgs/msg/HardwareInterface")
HardwareComponentState = get_message("controller_manager_msgs/msg/HardwareComponentState")
LifecycleState = get_message("lifecycle_msgs/msg/State")
_COMMAND_INTERFACES = ("position", "velocity", "effort")  # what every simulated joint takes
_ACTIVE = (3, "active")  # lifecycle_msgs/State PRIMARY_STATE_ACTIVE


class ControllerInterfaces:
    """Controller-manager services and controller command topics of one robot.

    Args:
        node: the node serving them.
        world: the robot's world (see the module docstring for what it must offer).
        robot: the robot's entity name in ``world``.
        ns: the robot's namespace (``""`` or ``/name``).
        lock: held around every access to ``world``.
        actions: the robot's FollowJointTrajectory servers; trajectory controllers are added to it.
    """

    def __init__(self, node: Any, world: Any, robot: str, ns: str, lock: threading.RLock,
                 actions: TrajectoryActions) -> None:
        self.node = node
        self.world = world
        self.robot = robot
        self.ns = ns
        self.lock = lock
        self._ignored = LogThrottle()  # bad commands from the wire: a few lines, then one per interval
        self.actions = actions
        self._command_subs: dict[str, Any] = {}
        self._services: list[Any] = []

    def serve(self) -> None:
        """Create the controller-manager services (once)."""
        if self._services:
            return
        cm = f"{self.ns}/controller_manager"
        handlers = {"list_controllers": self._list, "load_controller": self._load,
                    "configure_controller": self._configure, "switch_controller": self._switch,
                    "unload_controller": self._unload, "list_hardware_interfaces": self._interfaces,
                    "list_hardware_components": self._components, "list_controller_types": self._types,
                    "set_hardware_component_state": self._set_component_state}
        self._services = [  # every served distribution's variant (multiros.sim.distro_adapters)
            srv for name, type_name in CONTROLLER_SERVICES.items()
            for srv in create_services(self.node, type_name, f"{cm}/{name}", handlers[name])
        ]

    def subscribe_all(self) -> None:
        """Command topics for every loaded controller (call with the lock held when others may run)."""
        for controller in self.world.controller_manager(self.robot).list_controllers():
            self.subscribe_commands(controller.name)

    # -- controller command topics ----------------------------------------------------------
    def subscribe_commands(self, controller: str) -> None:
        """The command topic (and action, for trajectory controllers) of one controller."""
        if controller in self._command_subs:
            return
        ctrl = self.world.controller_manager(self.robot).get(controller)
        if not ctrl.command_interfaces:
            return
        if isinstance(ctrl, JointTrajectoryController):
            self.actions.add(controller, ctrl)
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

    def unsubscribe_commands(self, controller: str) -> None:
        self.actions.remove(controller)
        sub = self._command_subs.pop(controller, None)
        if sub is not None:
            self.node.destroy_subscription(sub)

    def _on_command(self, controller: str, msg: Any) -> None:
        with self.lock:
            try:
                self.world.set_command(self.robot, controller, msg.data)
            except (CommandError, ControllerError) as exc:
                self._ignored.log(self.node.get_logger(), logging.WARNING, "%s/%s/commands: %s (ignored)", self.ns,
                                  controller, exc)

    def _on_trajectory(self, controller: str, msg: Any) -> None:
        times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points]
        velocities = [p.velocities for p in msg.points] if all(len(p.velocities) for p in msg.points) else None
        with self.lock:
            try:
                ctrl = self.world.controller_manager(self.robot).get(controller)
                if ctrl.state != "active":
                    raise ControllerError(f"controller '{controller}' is {ctrl.state}")
                ctrl.set_trajectory(list(msg.joint_names), [p.positions for p in msg.points], times, velocities,
                                    time=self.world.time)
                self.world.controllers_changed(self.robot)
            except (CommandError, ControllerError) as exc:
                self._ignored.log(self.node.get_logger(), logging.WARNING, "%s/%s/joint_trajectory: %s (ignored)",
                                  self.ns, controller, exc)

    # -- controller manager services ----------------------------------------------------------
    def _list(self, request: Any, response: Any) -> Any:
        with self.lock:
            infos = self.world.controller_manager(self.robot).list_controllers()
        response.controller = [
            ControllerState(
                name=i.name, state=i.state, type=i.type, claimed_interfaces=list(i.claimed_interfaces),
                required_command_interfaces=list(i.required_command_interfaces),
                required_state_interfaces=list(i.required_state_interfaces),
            )
            for i in infos
        ]
        return response

    def _hardware(self) -> tuple[list[Any], list[Any]]:
        """The robot's command and state interfaces, claimed ones marked (lock held)."""
        cm = self.world.controller_manager(self.robot)
        claimed = {i for info in cm.list_controllers() for i in info.claimed_interfaces}
        joints = cm.hw.joint_names
        command = [HardwareInterface(name=f"{j}/{i}", data_type="double", is_available=True,
                                     is_claimed=f"{j}/{i}" in claimed) for j in joints for i in _COMMAND_INTERFACES]
        state = [HardwareInterface(name=f"{j}/{i}", data_type="double", is_available=True, is_claimed=False)
                 for j in joints for i in _COMMAND_INTERFACES]
        return command, state

    def _interfaces(self, request: Any, response: Any) -> Any:
        with self.lock:
            response.command_interfaces, response.state_interfaces = self._hardware()
        return response

    def _component_name(self) -> str:
        return f"{self.robot}_system"

    def _components(self, request: Any, response: Any) -> Any:
        with self.lock:
            command, state = self._hardware()
        component = HardwareComponentState(name=self._component_name(), type="system",
                                           state=LifecycleState(id=_ACTIVE[0], label=_ACTIVE[1]),
                                           command_interfaces=command, state_interfaces=state)
        if hasattr(component, "plugin_name"):  # Jazzy on
            component.plugin_name = getattr(self.world, "hardware_plugin", "uniros/MujocoSystem")
        response.component = [component]
        return response

    def _types(self, request: Any, response: Any) -> Any:
        response.types = sorted(CONTROLLER_TYPES)
        response.base_classes = ["controller_interface::ControllerInterface"] * len(response.types)
        return response

    def _set_component_state(self, request: Any, response: Any) -> Any:
        target = request.target_state
        wanted = int(target.id) == _ACTIVE[0] or str(target.label).strip().lower() == _ACTIVE[1]
        response.ok = request.name == self._component_name() and wanted
        response.state = LifecycleState(id=_ACTIVE[0], label=_ACTIVE[1])
        if not response.ok:
            self._ignored.log(self.node.get_logger(), logging.WARNING,
                              "%s/controller_manager: set_hardware_component_state %r -> %r refused: the only "
                              "component is %r, and it stays active", self.ns, request.name,
                              target.label or target.id, self._component_name())
        return response

    def _manage(self, response: Any, action: Any) -> Any:
        with self.lock:
            try:
                action(self.world.controller_manager(self.robot))
                self.world.controllers_changed(self.robot)
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
            self.subscribe_commands(request.name)

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
            self.unsubscribe_commands(request.name)

        return self._manage(response, unload)

    # -- teardown ---------------------------------------------------------------------------
    def destroy(self) -> None:
        """Destroy every command subscription, action and service."""
        self.actions.destroy()
        for name in list(self._command_subs):
            self.unsubscribe_commands(name)
        for srv in self._services:
            self.node.destroy_service(srv)
        self._services = []
