"""Exception hierarchy of the ROS client layer, shaped like ``rclpy.exceptions``.

Every error names the entity that is wrong (topic, service, node, parameter) and what to do.
"""

from __future__ import annotations

__all__ = [
    "RosException",
    "NotInitializedException",
    "NameValidationException",
    "InvalidNodeNameException",
    "InvalidNamespaceException",
    "InvalidTopicNameException",
    "InvalidServiceNameException",
    "ParameterException",
    "ParameterNotDeclaredException",
    "ParameterAlreadyDeclaredException",
    "InvalidParameterTypeException",
    "InvalidParameterValueException",
    "ServiceTimeoutError",
    "ServiceCallError",
    "TransportError",
]


class RosException(Exception):
    """Base class of every error raised by ``multiros.ros``."""


class NotInitializedException(RosException):
    """The context was not initialised or was already shut down."""

    def __init__(self, what: str = "the context") -> None:
        super().__init__(
            f"{what} is not initialised or already shut down: call multiros.ros.init() "
            "(or use `with Context(...) as ctx:`) before creating nodes"
        )


class NameValidationException(RosException):
    """A ROS name is invalid; the message shows the name with a caret under the bad character."""

    kind = "name"

    def __init__(self, name: str, reason: str, index: int | None = None) -> None:
        self.name = name
        self.reason = reason
        self.index = index
        msg = f"invalid {self.kind} '{name}': {reason}"
        if index is not None and 0 <= index <= len(name):
            msg += f"\n  '{name}'\n   {' ' * index}^"
        super().__init__(msg)


class InvalidNodeNameException(NameValidationException):
    """A node name is invalid."""

    kind = "node name"


class InvalidNamespaceException(NameValidationException):
    """A namespace is invalid."""

    kind = "namespace"


class InvalidTopicNameException(NameValidationException):
    """A topic name is invalid."""

    kind = "topic name"


class InvalidServiceNameException(NameValidationException):
    """A service name is invalid."""

    kind = "service name"


class ParameterException(RosException):
    """Base class of parameter errors."""


class ParameterNotDeclaredException(ParameterException):
    """A parameter was read or set before it was declared."""

    def __init__(self, name: str, node: str = "") -> None:
        where = f" on node '{node}'" if node else ""
        super().__init__(
            f"parameter '{name}' is not declared{where}: call declare_parameter('{name}', default) "
            "first, or create the node with allow_undeclared_parameters=True"
        )


class ParameterAlreadyDeclaredException(ParameterException):
    """A parameter was declared twice."""

    def __init__(self, name: str, node: str = "") -> None:
        where = f" on node '{node}'" if node else ""
        super().__init__(f"parameter '{name}' is already declared{where}")


class InvalidParameterTypeException(ParameterException):
    """A parameter was set to a value of another type than declared."""


class InvalidParameterValueException(ParameterException):
    """A parameter value was rejected (read-only, or by a parameter callback)."""


class ServiceTimeoutError(TimeoutError, RosException):
    """A service call or a wait for a service did not complete in time."""

    def __init__(self, service: str, seconds: float, detail: str = "") -> None:
        self.service = service
        self.seconds = seconds
        extra = f" ({detail})" if detail else ""
        super().__init__(
            f"service '{service}' did not answer within {seconds:.3g} s{extra}: check that its server "
            "is running and reachable (ros graph: Node.get_service_names_and_types())"
        )


class ServiceCallError(RosException, RuntimeError):
    """The service server raised, replied with an error, or went away during the call."""

    def __init__(self, service: str, detail: str) -> None:
        self.service = service
        self.detail = detail
        super().__init__(f"service '{service}' failed: {detail}")


class TransportError(RosException):
    """A transport could not be created or used (bad configuration, router unreachable, ...)."""
