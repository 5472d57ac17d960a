"""A plain rclpy peer for the rclpy-transport tests: rclpy and message packages only, no uniros.

What any ROS 2 user's own program does: one node spun by a ``SingleThreadedExecutor`` on a thread
of its own, with helpers that wait for graph entities, call services, collect topic messages and
send action goals, every wait bounded.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions


def wait_until(predicate: Callable[[], Any], timeout: float, what: str, period: float = 0.02) -> Any:
    """``predicate()`` once it is truthy; ``AssertionError`` naming ``what`` after ``timeout``."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(period)


class PlainPeer:
    """One rclpy node of its own context, spinning on a background thread."""

    def __init__(self, name: str) -> None:
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=2.0)

    def __enter__(self) -> PlainPeer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- graph -------------------------------------------------------------------------------
    def nodes(self) -> list[str]:
        return [(ns.rstrip("/") + "/" + n) for n, ns in self.node.get_node_names_and_namespaces()]

    def wait_for_node(self, fqn: str, timeout: float = 30.0) -> None:
        wait_until(lambda: fqn in self.nodes(), timeout, f"node {fqn} in the graph (seen: {self.nodes()})")

    # -- services ----------------------------------------------------------------------------
    def call(self, srv_type: Any, name: str, request: Any, timeout: float = 10.0) -> Any:
        client = self.node.create_client(srv_type, name)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise AssertionError(f"service {name} not available within {timeout:g} s")
            future = client.call_async(request)
            wait_until(future.done, timeout, f"the answer of {name}", period=0.005)
            return future.result()
        finally:
            self.node.destroy_client(client)

    # -- topics ------------------------------------------------------------------------------
    def collect(self, msg_type: Any, topic: str, *, best_effort: bool = False) -> tuple[list[Any], Any]:
        """Subscribe; returns (messages list, subscription)."""
        got: list[Any] = []
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT if best_effort
                         else ReliabilityPolicy.RELIABLE)
        sub = self.node.create_subscription(msg_type, topic, got.append, qos)
        return got, sub

    def publisher(self, msg_type: Any, topic: str) -> Any:
        return self.node.create_publisher(msg_type, topic, 10)

    # -- actions -----------------------------------------------------------------------------
    def send_goal(self, action_type: Any, name: str, goal: Any, timeout: float = 30.0) -> tuple[Any, list[Any], Any]:
        """Send ``goal``; returns (goal handle, feedback messages, result response)."""
        client = ActionClient(self.node, action_type, name)
        feedback: list[Any] = []
        try:
            if not client.wait_for_server(timeout_sec=timeout):
                raise AssertionError(f"action server {name} not available within {timeout:g} s")
            sent = client.send_goal_async(goal, feedback_callback=feedback.append)
            wait_until(sent.done, timeout, f"the goal answer of {name}", period=0.005)
            handle = sent.result()
            if not handle.accepted:
                return handle, feedback, None
            result = handle.get_result_async()
            wait_until(result.done, timeout, f"the result of {name}", period=0.005)
            return handle, feedback, result.result()
        finally:
            client.destroy()
