"""ROS 2 client layer without rclpy: an rclpy-shaped node API over pluggable transports.

Code written against this module runs on rclpy after changing only the import::

    from multiros import ros as rclpy

    rclpy.init()
    node = rclpy.create_node("talker")
    ...
    rclpy.spin(node)
    rclpy.shutdown()

Transports (``init(transport=...)`` or ``$UNIROS_TRANSPORT``): ``inproc`` (default; nodes in
one process call each other directly) and ``zenoh`` (rmw_zenoh_cpp-compatible wire).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from multiros.ros.client import Client
from multiros.ros.context import Context, _set_default_context, get_default_context
from multiros.ros.exceptions import (
    InvalidNamespaceException,
    InvalidNodeNameException,
    InvalidServiceNameException,
    InvalidTopicNameException,
    NameValidationException,
    NotInitializedException,
    ParameterAlreadyDeclaredException,
    ParameterException,
    ParameterNotDeclaredException,
    RosException,
    ServiceCallError,
    ServiceTimeoutError,
    TransportError,
)
from multiros.ros.executors import Executor, MultiThreadedExecutor, SingleThreadedExecutor
from multiros.ros.node import Node
from multiros.ros.parameters import Parameter, ParameterDescriptor, SetParametersResult
from multiros.ros.publisher import Publisher
from multiros.ros.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_clock,
    qos_profile_parameter_events,
    qos_profile_parameters,
    qos_profile_sensor_data,
    qos_profile_services_default,
    qos_profile_system_default,
)
from multiros.ros.service import Service
from multiros.ros.subscription import Subscription
from multiros.ros.task import Future
from multiros.ros.timer import Timer

__all__ = [
    "init", "shutdown", "try_shutdown", "ok", "create_node", "spin", "spin_once",
    "spin_until_future_complete", "get_default_context",
    "Context", "Node", "Publisher", "Subscription", "Service", "Client", "Timer", "Future",
    "Executor", "SingleThreadedExecutor", "MultiThreadedExecutor",
    "QoSProfile", "HistoryPolicy", "ReliabilityPolicy", "DurabilityPolicy", "LivelinessPolicy",
    "qos_profile_system_default", "qos_profile_sensor_data", "qos_profile_services_default",
    "qos_profile_parameters", "qos_profile_parameter_events", "qos_profile_clock",
    "Parameter", "ParameterDescriptor", "SetParametersResult",
    "RosException", "NotInitializedException", "NameValidationException", "InvalidNodeNameException",
    "InvalidNamespaceException", "InvalidTopicNameException", "InvalidServiceNameException",
    "ParameterException", "ParameterNotDeclaredException", "ParameterAlreadyDeclaredException",
    "ServiceTimeoutError", "ServiceCallError", "TransportError",
]


def init(
    args: Sequence[str] | None = None,
    *,
    context: Context | None = None,
    domain_id: int | None = None,
    transport: str | None = None,
    **transport_options: Any,
) -> Context:
    """Initialise ``context`` (the default context when omitted) and return it.

    Args:
        args: command line; ``--ros-args`` sections give global remaps and parameters.
        context: the context to initialise.
        domain_id: overrides ``$ROS_DOMAIN_ID``.
        transport: ``"inproc"`` or ``"zenoh"``; overrides ``$UNIROS_TRANSPORT``.
        **transport_options: see ``Context``.
    """
    if context is None:
        if transport is not None or transport_options:
            context = Context(transport=transport, domain_id=domain_id, **transport_options)
            _set_default_context(context)
        else:
            context = get_default_context()
    else:
        if transport is not None:
            context.transport_name = transport
        context.transport_options.update(transport_options)
    return context.init(args, domain_id=domain_id)


def shutdown(*, context: Context | None = None) -> None:
    """Shut ``context`` (default: the default context) down.

    Raises:
        RuntimeError: it was not initialised.
    """
    (context or get_default_context()).shutdown()


def try_shutdown(*, context: Context | None = None) -> None:
    """``shutdown`` that ignores an already shut down context."""
    (context or get_default_context()).try_shutdown()


def ok(*, context: Context | None = None) -> bool:
    """Whether the context is initialised."""
    return (context or get_default_context()).ok()


def create_node(node_name: str, **kwargs: Any) -> Node:
    """``Node(node_name, **kwargs)``."""
    return Node(node_name, **kwargs)


def _executor_for(node: Node | None, executor: Executor | None) -> Executor:
    if executor is None:
        ctx = node.context if node is not None else get_default_context()
        if ctx._default_executor is None:
            ctx._default_executor = SingleThreadedExecutor(context=ctx)
        executor = ctx._default_executor
    if node is not None:
        executor.add_node(node)
    return executor


def spin(node: Node | None = None, executor: Executor | None = None) -> None:
    """Run the node's callbacks until the context shuts down."""
    _executor_for(node, executor).spin()


def spin_once(node: Node | None = None, *, executor: Executor | None = None, timeout_sec: float | None = None) -> None:
    """Run at most one callback of the node."""
    _executor_for(node, executor).spin_once(timeout_sec)


def spin_until_future_complete(
    node: Node | None, future: Future, executor: Executor | None = None, timeout_sec: float | None = None
) -> None:
    """Spin the node until ``future`` is done or ``timeout_sec`` passed."""
    _executor_for(node, executor).spin_until_future_complete(future, timeout_sec)
