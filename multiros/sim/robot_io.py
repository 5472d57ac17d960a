"""The ROS interfaces of one robot in the simulation node, in the robot's namespace.

* ``joint_states`` (``sensor_msgs/JointState``) and ``robot_description`` (``std_msgs/String``,
  transient local); its links' transforms go out on the node's ``/tf`` and ``/tf_static``
  (:mod:`multiros.sim.tf_publisher`);
* the controller manager's services, controller command topics and trajectory actions
  (:class:`~multiros.sim.controller_io.ControllerInterfaces`, shared with the fake robot).

State topics are published only when someone subscribes, so the lockstep hot path pays nothing
for them.
"""

from __future__ import annotations

import threading
from typing import Any

from multiros.ros.qos import DurabilityPolicy, QoSProfile
from multiros.sim import convert
from multiros.sim.actions import TrajectoryActions
from multiros.sim.controller_io import ControllerInterfaces
from multiros.sim.distro_adapters import get_message

JointState = get_message("sensor_msgs/msg/JointState")
String = get_message("std_msgs/msg/String")

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
        self._joint_pub = node.create_publisher(JointState, f"{ns}/joint_states", 10)
        self._description_pub = node.create_publisher(String, f"{ns}/robot_description", _LATCHED)
        self._description_pub.publish(String(data=info.description))
        self._actions = TrajectoryActions(node, world, info.name, ns, lock)  # follow_joint_trajectory
        self.controllers = ControllerInterfaces(node, world, info.name, ns, lock, self._actions)
        self.controllers.serve()
        self.controllers.subscribe_all()

    # -- state topics -----------------------------------------------------------------------
    def fill_joint_state(self, msg: Any) -> Any:
        """Write the robot's joint state (copies) into a ``sensor_msgs/JointState``."""
        msg.header.stamp = convert.time_msg(self.world.time)
        msg.name = self._names
        msg.position, msg.velocity, msg.effort = self.world.joint_state_arrays(self.name)
        return msg

    def on_step(self) -> None:
        """The world advanced: the robot's running trajectory goals check their tolerances (caller holds the lock)."""
        self._actions.on_step()

    def publish_state(self) -> bool:
        """Publish ``joint_states`` if anyone listens (caller holds the lock); whether anyone does."""
        joints = self._joint_pub.has_subscribers()
        if joints:
            self._joint_pub.publish(self.fill_joint_state(JointState()))
        return joints

    def on_reset(self) -> None:
        """Called after a world reset (state topics are refreshed on the next step)."""

    # -- teardown ---------------------------------------------------------------------------
    def destroy(self) -> None:
        """Destroy every publisher, subscription, service and action of this robot."""
        self.controllers.destroy()
        for pub in (self._joint_pub, self._description_pub):
            self.node.destroy_publisher(pub)


__all__ = ["RobotInterfaces"]
