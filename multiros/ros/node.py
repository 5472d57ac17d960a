"""``Node``: the rclpy-shaped entry point for publishers, subscriptions, services, clients,
timers, parameters and graph queries.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import Any

from multiros.ros.callback_groups import CallbackGroup
from multiros.ros.client import Client
from multiros.ros.clock import Clock
from multiros.ros.context import Context, get_default_context
from multiros.ros.exceptions import NotInitializedException
from multiros.ros.graph import CLIENT, PUBLISHER, SERVICE, SUBSCRIPTION
from multiros.ros.logging import RosLogger, get_logger, release_logger
from multiros.ros.names import (
    expand_topic_name,
    normalize_namespace,
    parse_ros_arguments,
    resolve_name,
    validate_node_name,
)
from multiros.ros.parameters import (
    Parameter,
    ParameterDescriptor,
    ParameterStore,
    SetParametersResult,
    merge_overrides,
    parameters_from_yaml,
)
from multiros.ros.publisher import Publisher
from multiros.ros.qos import QoSProfile, as_qos_profile, qos_profile_services_default
from multiros.ros.service import Service
from multiros.ros.subscription import Subscription
from multiros.ros.timer import Timer

__all__ = ["Node"]


class Node:
    """A ROS 2 node.

    Args:
        node_name: the node's name (``[A-Za-z_][A-Za-z0-9_]*``); ``-r __node:=x`` renames it.
        context: the context to live in; the default context (``init()``) when omitted.
        cli_args: node-specific command line (``["--ros-args", "-r", "a:=b", "-p", "x:=1",
            "--params-file", "f.yaml"]``), applied before the context's global arguments.
        namespace: the node's namespace (``robot1`` or ``/robot1``); ``-r __ns:=/y`` overrides it.
        use_global_arguments: also apply the arguments given to ``init(args=...)``.
        parameter_overrides: ``Parameter`` list overriding declared defaults (wins over YAML/``-p``).
        allow_undeclared_parameters: allow get/set of parameters never declared.
        automatically_declare_parameters_from_overrides: declare every override at creation.

    Raises:
        InvalidNodeNameException, InvalidNamespaceException: a bad name or namespace.
        NotInitializedException: the context is not initialised.
    """

    def __init__(
        self,
        node_name: str,
        *,
        context: Context | None = None,
        cli_args: Sequence[str] | None = None,
        namespace: str | None = None,
        use_global_arguments: bool = True,
        enable_rosout: bool = True,
        start_parameter_services: bool = True,
        parameter_overrides: Sequence[Parameter] | None = None,
        allow_undeclared_parameters: bool = False,
        automatically_declare_parameters_from_overrides: bool = False,
    ) -> None:
        self.context = context if context is not None else get_default_context()
        if not self.context.ok():
            raise NotInitializedException(f"the context of node '{node_name}'")
        args = parse_ros_arguments(list(cli_args) if cli_args else None)
        if use_global_arguments:
            args = args.extend(self.context.arguments)
        self._arguments = args
        validate_node_name(node_name)
        self._name = args.node_name_for(node_name)
        self._namespace = args.namespace_for(self._name, normalize_namespace(namespace))
        self._logger = get_logger(self.get_fully_qualified_name(), node=True)
        self._clock = Clock()
        # Reentrant: a callback of this node may call a service of this same node in-process.
        self._callback_lock = threading.RLock()
        self.publishers: list[Publisher] = []
        self.subscriptions: list[Subscription] = []
        self.services: list[Service] = []
        self.clients: list[Client] = []
        self.timers: list[Timer] = []
        self.waitables: list[Any] = []  # action servers and clients (anything with destroy())
        self._destroyed = False

        fqn = self.get_fully_qualified_name()
        file_values: dict[str, Any] = {}
        for path in args.params_files:
            file_values.update(parameters_from_yaml(path, fqn))
        overrides = merge_overrides(
            file_values,
            args.parameters,
            args.node_parameters.get(self._name, {}),
            args.node_parameters.get(fqn, {}),
            parameter_overrides,
        )
        self._parameters = ParameterStore(fqn, overrides, allow_undeclared_parameters)
        self.declare_parameter("use_sim_time", False)
        if automatically_declare_parameters_from_overrides:
            for name, value in overrides.items():
                if not self.has_parameter(name):
                    self.declare_parameter(name, value)

        self.context._add_node(self)
        try:
            self._wire = self.context.transport.add_node(self)
        except BaseException:  # e.g. rcl refused the node: the context must not try to destroy it later
            self.context._remove_node(self)
            raise
        self._parameter_services: Any = None
        if start_parameter_services and self.context.transport.serves_parameters:
            from multiros.ros.parameter_services import ParameterServices

            self._parameter_services = ParameterServices(self)

    # -- identity ----------------------------------------------------------------------------
    def get_name(self) -> str:
        return self._name

    def get_namespace(self) -> str:
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        return self._namespace.rstrip("/") + "/" + self._name

    @property
    def name(self) -> str:
        return self._name

    @property
    def namespace(self) -> str:
        return self._namespace

    def get_logger(self) -> RosLogger:
        """A standard ``logging`` logger named ``ros.<ns>.<node>`` (with rclpy's ``warn``/``fatal``)."""
        return self._logger

    def get_clock(self) -> Clock:
        return self._clock

    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str:
        """Expand ``topic`` for this node and apply remapping (unless ``only_expand``)."""
        if only_expand:
            return expand_topic_name(topic, self._name, self._namespace)
        return resolve_name(topic, self._name, self._namespace, self._arguments)

    def resolve_service_name(self, service: str, *, only_expand: bool = False) -> str:
        """Expand ``service`` for this node and apply remapping (unless ``only_expand``)."""
        if only_expand:
            return expand_topic_name(service, self._name, self._namespace, is_service=True)
        return resolve_name(service, self._name, self._namespace, self._arguments, is_service=True)

    # -- entities ----------------------------------------------------------------------------
    def _check_alive(self) -> None:
        if self._destroyed:
            raise RuntimeError(f"node '{self.get_fully_qualified_name()}' was destroyed")
        if not self.context.ok():
            raise NotInitializedException(f"the context of node '{self.get_fully_qualified_name()}'")

    def create_publisher(
        self, msg_type: type, topic: str, qos_profile: QoSProfile | int, **_kwargs: Any
    ) -> Publisher:
        """Create a publisher on ``topic`` (relative, absolute or ``~/`` private)."""
        self._check_alive()
        pub = Publisher(self, msg_type, self.resolve_topic_name(topic), as_qos_profile(qos_profile))
        pub._wire = self.context.transport.add_publisher(pub)
        self.context.registry.add_publisher(pub)
        self.publishers.append(pub)
        return pub

    def create_subscription(
        self, msg_type: type, topic: str, callback: Callable[..., None],
        qos_profile: QoSProfile | int, *, with_source: bool = False, **_kwargs: Any,
    ) -> Subscription:
        """Create a subscription; ``callback(msg)`` runs when an executor spins this node
        (``with_source``: ``callback(msg, source)``, the publisher's identity, see :class:`Subscription`)."""
        self._check_alive()
        sub = Subscription(self, msg_type, self.resolve_topic_name(topic), callback, as_qos_profile(qos_profile),
                           with_source)
        self.subscriptions.append(sub)
        self.context.registry.add_subscription(sub)
        sub._wire = self.context.transport.add_subscription(sub)
        return sub

    def create_service(
        self, srv_type: Any, srv_name: str, callback: Callable[[Any, Any], Any], *,
        qos_profile: QoSProfile = qos_profile_services_default, callback_group: CallbackGroup | None = None,
        **_kwargs: Any,
    ) -> Service:
        """Create a service; ``callback(request, response)`` must return the response.

        ``callback_group``: a :class:`~multiros.ros.callback_groups.ReentrantCallbackGroup` lets
        calls run concurrently (the callback guards its own state); default: under the node's lock.
        """
        self._check_alive()
        srv = Service(self, srv_type, self.resolve_service_name(srv_name), callback, qos_profile, callback_group)
        self.context.registry.add_service(srv)
        srv._wire = self.context.transport.add_service(srv)
        self.services.append(srv)
        self.context.notify()
        return srv

    def create_client(
        self, srv_type: Any, srv_name: str, *, qos_profile: QoSProfile = qos_profile_services_default,
        **_kwargs: Any,
    ) -> Client:
        """Create a client for ``srv_name``."""
        self._check_alive()
        cli = Client(self, srv_type, self.resolve_service_name(srv_name), qos_profile)
        self.context.registry.add_client(cli)
        cli._wire = self.context.transport.add_client(cli)
        self.clients.append(cli)
        return cli

    def create_timer(self, timer_period_sec: float, callback: Callable[[], None], **_kwargs: Any) -> Timer:
        """Call ``callback()`` every ``timer_period_sec`` while an executor spins this node."""
        self._check_alive()
        timer = Timer(callback, timer_period_sec, self)
        self.timers.append(timer)
        self.context.notify()
        return timer

    def destroy_publisher(self, publisher: Publisher) -> bool:
        if publisher not in self.publishers:
            return False
        self.publishers.remove(publisher)
        publisher._destroyed = True
        self.context.registry.remove_publisher(publisher)
        _close(publisher)
        return True

    def destroy_subscription(self, subscription: Subscription) -> bool:
        if subscription not in self.subscriptions:
            return False
        self.subscriptions.remove(subscription)
        subscription._destroyed = True
        self.context.registry.remove_subscription(subscription)
        _close(subscription)
        return True

    def destroy_service(self, service: Service) -> bool:
        if service not in self.services:
            return False
        self.services.remove(service)
        self.context.registry.remove_service(service)
        _close(service)
        return True

    def destroy_client(self, client: Client) -> bool:
        if client not in self.clients:
            return False
        self.clients.remove(client)
        self.context.registry.remove_client(client)
        _close(client)
        return True

    def destroy_timer(self, timer: Timer) -> bool:
        if timer not in self.timers:
            return False
        self.timers.remove(timer)
        timer.destroy()
        return True

    def add_waitable(self, waitable: Any) -> None:
        """Own ``waitable`` (an action server or client): ``destroy_node`` destroys it first."""
        if waitable not in self.waitables:
            self.waitables.append(waitable)

    def remove_waitable(self, waitable: Any) -> None:
        if waitable in self.waitables:
            self.waitables.remove(waitable)

    def destroy_node(self) -> None:
        """Destroy every entity of this node and remove it from the graph."""
        if self._destroyed:
            return
        for waitable in list(self.waitables):
            try:
                waitable.destroy()
            except Exception:  # noqa: BLE001 - destroying the node must finish
                self._logger.exception("destroying %r failed", waitable)
        self.waitables.clear()
        for pub in list(self.publishers):
            self.destroy_publisher(pub)
        for sub in list(self.subscriptions):
            self.destroy_subscription(sub)
        for srv in list(self.services):
            self.destroy_service(srv)
        for cli in list(self.clients):
            self.destroy_client(cli)
        for timer in list(self.timers):
            self.destroy_timer(timer)
        self._destroyed = True
        if self._wire is not None:
            self._wire.close()
            self._wire = None
        self.context._remove_node(self)
        release_logger(self.get_fully_qualified_name())  # a node named with a counter leaves no logger behind

    def __enter__(self) -> Node:
        return self

    def __exit__(self, *exc: object) -> None:
        self.destroy_node()

    # -- parameters --------------------------------------------------------------------------
    def declare_parameter(
        self, name: str, value: Any = None, descriptor: ParameterDescriptor | None = None,
        ignore_override: bool = False,
    ) -> Parameter:
        """Declare a parameter with a default; YAML/``-p``/``parameter_overrides`` values win."""
        return self._parameters.declare(name, value, descriptor, ignore_override)

    def declare_parameters(
        self, namespace: str, parameters: Sequence[tuple[Any, ...]], ignore_override: bool = False
    ) -> list[Parameter]:
        """Declare several ``(name, value[, descriptor])`` under ``namespace`` (``""`` for none)."""
        out = []
        for entry in parameters:
            name = f"{namespace}.{entry[0]}" if namespace else entry[0]
            value = entry[1] if len(entry) > 1 else None
            descriptor = entry[2] if len(entry) > 2 else None
            out.append(self.declare_parameter(name, value, descriptor, ignore_override))
        return out

    def undeclare_parameter(self, name: str) -> None:
        self.get_parameter(name)
        self._parameters.values.pop(name, None)
        self._parameters.descriptors.pop(name, None)

    def has_parameter(self, name: str) -> bool:
        return name in self._parameters.values

    def get_parameter(self, name: str) -> Parameter:
        """The parameter ``name``.

        Raises:
            ParameterNotDeclaredException: it was never declared.
        """
        return self._parameters.get(name)

    def get_parameter_or(self, name: str, alternative_value: Parameter | None = None) -> Parameter:
        if not self.has_parameter(name):
            return alternative_value if alternative_value is not None else Parameter(name)
        return self.get_parameter(name)

    def get_parameters(self, names: Sequence[str]) -> list[Parameter]:
        return [self.get_parameter(n) for n in names]

    def get_parameters_by_prefix(self, prefix: str) -> dict[str, Parameter]:
        start = f"{prefix}." if prefix else ""
        return {k[len(start):]: v for k, v in self._parameters.values.items() if k.startswith(start)}

    def set_parameters(self, parameter_list: Sequence[Parameter]) -> list[SetParametersResult]:
        """Set parameters; one result per parameter says whether it was accepted and why not."""
        return self._parameters.set(parameter_list)

    def set_parameters_atomically(self, parameter_list: Sequence[Parameter]) -> SetParametersResult:
        saved = dict(self._parameters.values)
        results = self._parameters.set(parameter_list)
        failed = [r for r in results if not r.successful]
        if failed:
            self._parameters.values = saved
            return SetParametersResult(False, "; ".join(r.reason for r in failed))
        return SetParametersResult(True, "")

    def add_on_set_parameters_callback(self, callback: Callable[[list[Parameter]], SetParametersResult]) -> None:
        self._parameters.callbacks.append(callback)

    def describe_parameter(self, name: str) -> ParameterDescriptor:
        self.get_parameter(name)
        return self._parameters.descriptors[name]

    # -- graph -------------------------------------------------------------------------------
    def get_node_names(self) -> list[str]:
        return [n for n, _ in self.context.graph().node_names_and_namespaces()]

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        return self.context.graph().node_names_and_namespaces()

    def get_topic_names_and_types(self, no_demangle: bool = False) -> list[tuple[str, list[str]]]:
        return self.context.graph().topic_names_and_types()

    def get_service_names_and_types(self) -> list[tuple[str, list[str]]]:
        return self.context.graph().service_names_and_types()

    def get_publisher_names_and_types_by_node(self, node_name: str, node_namespace: str) -> list:
        return self.context.graph().by_node(PUBLISHER, node_name, node_namespace)

    def get_subscriber_names_and_types_by_node(self, node_name: str, node_namespace: str) -> list:
        return self.context.graph().by_node(SUBSCRIPTION, node_name, node_namespace)

    def get_service_names_and_types_by_node(self, node_name: str, node_namespace: str) -> list:
        return self.context.graph().by_node(SERVICE, node_name, node_namespace)

    def get_client_names_and_types_by_node(self, node_name: str, node_namespace: str) -> list:
        return self.context.graph().by_node(CLIENT, node_name, node_namespace)

    def count_publishers(self, topic_name: str) -> int:
        return self.context.transport.count(PUBLISHER, self.resolve_topic_name(topic_name, only_expand=True))

    def count_subscribers(self, topic_name: str) -> int:
        return self.context.transport.count(SUBSCRIPTION, self.resolve_topic_name(topic_name, only_expand=True))

    def get_publishers_info_by_topic(self, topic_name: str) -> list:
        """The graph's publishers of ``topic_name`` (rclpy's name): their node, namespace, type and
        session (``origin``; ``""`` for this context's own), as :class:`~multiros.ros.graph.Endpoint` records."""
        return self.context.graph().endpoints_of(PUBLISHER, self.resolve_topic_name(topic_name, only_expand=True))

    def get_subscriptions_info_by_topic(self, topic_name: str) -> list:
        """The graph's subscriptions of ``topic_name`` (rclpy's name), as
        :class:`~multiros.ros.graph.Endpoint` records."""
        return self.context.graph().endpoints_of(SUBSCRIPTION, self.resolve_topic_name(topic_name, only_expand=True))

    def count_services(self, service_name: str) -> int:
        return self.context.transport.count(SERVICE, self.resolve_service_name(service_name, only_expand=True))

    def __repr__(self) -> str:
        return f"Node({self.get_fully_qualified_name()!r})"


def _close(entity: Any) -> None:
    wire = getattr(entity, "_wire", None)
    if wire is not None:
        entity._wire = None
        wire.close()
    entity.context.notify() if hasattr(entity, "context") else entity.node.context.notify()
