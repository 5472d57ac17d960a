"""A node's parameters over the wire: the six ``rcl_interfaces`` services rclpy and rclcpp nodes serve.

``ros2 param list/get/set/describe/dump`` talk to ``<node>/list_parameters``, ``get_parameters``,
``get_parameter_types``, ``describe_parameters``, ``set_parameters`` and
``set_parameters_atomically``. :class:`ParameterServices` serves them from a node's own
:class:`~multiros.ros.parameters.ParameterStore`, so settings a node declares (the simulation node's
``max_steps_per_call`` and ``max_robots``, ``use_sim_time``) are real ROS parameters: read-only
ones refuse a set with the reason (``parameter 'max_robots' is read-only``), a wrong type says
which type it is. Nodes start them on transports whose graph ROS tools reach
(``Transport.serves_parameters``); ``start_parameter_services=False`` leaves them out, as in rclpy.

Requests are hostile input like any other: an unknown type code or a value that does not fit its
type is a refused parameter with the reason, never an exception out of the service. What one request
may cost is bounded, so a flood takes its turn without holding the node's other services back: at most
:data:`MAX_REQUEST_BYTES` bytes a request where the transport sees its size before decoding it (rclpy's:
a larger request is refused without being decoded, :meth:`~multiros.ros.service.Service.bound_requests`),
at most :data:`MAX_NAMES` names, prefixes or parameters a request (more: one refused result that says so,
or empty answers), values of at most :data:`MAX_ARRAY` elements and :data:`MAX_TEXT` characters, reasons
of at most :data:`MAX_REASON` characters.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from multiros.excerpt import excerpt
from multiros.ros.interfaces import get_message, get_service
from multiros.ros.parameters import Parameter

if TYPE_CHECKING:
    from multiros.ros.node import Node

__all__ = ["MAX_ARRAY", "MAX_NAMES", "MAX_REASON", "MAX_REQUEST_BYTES", "MAX_TEXT", "PARAMETER_SERVICES",
           "ParameterServices", "from_value_msg", "to_value_msg"]

#: Name under the node (``~/<name>``) -> service type.
PARAMETER_SERVICES: dict[str, str] = {
    "describe_parameters": "rcl_interfaces/srv/DescribeParameters",
    "get_parameter_types": "rcl_interfaces/srv/GetParameterTypes",
    "get_parameters": "rcl_interfaces/srv/GetParameters",
    "list_parameters": "rcl_interfaces/srv/ListParameters",
    "set_parameters": "rcl_interfaces/srv/SetParameters",
    "set_parameters_atomically": "rcl_interfaces/srv/SetParametersAtomically",
}
_SEPARATOR = "."
MAX_NAMES = 256  # names or parameters one request may carry
MAX_ARRAY = 10_000  # elements of an array value
MAX_TEXT = 65_536  # characters of a string value, bytes of a byte array
MAX_REASON = 300  # characters of a refusal's reason
# Bytes (CDR) of one request: MAX_NAMES parameters of names and small values (~20 KB), or one array of
# MAX_ARRAY doubles (80 KB), or a string of MAX_TEXT, with room to spare. A SetParameters of 10,000
# parameters is 720 KB, a GetParameters of 100,000 names 2 MB: refused before they are decoded.
MAX_REQUEST_BYTES = 256 * 1024
# ParameterValue's field for each type code (rcl_interfaces/msg/ParameterType).
_FIELDS = {1: "bool_value", 2: "integer_value", 3: "double_value", 4: "string_value", 5: "byte_array_value",
           6: "bool_array_value", 7: "integer_array_value", 8: "double_array_value", 9: "string_array_value"}


def to_value_msg(param: Parameter) -> Any:
    """``rcl_interfaces/msg/ParameterValue`` of ``param``."""
    msg = get_message("rcl_interfaces/msg/ParameterValue")()
    code = int(param.type_)
    msg.type = code
    if code in _FIELDS and param.value is not None:
        value = param.value
        if code == 5:
            value = bytes(value)
        elif code >= 6:
            value = list(value)
        setattr(msg, _FIELDS[code], value)
    return msg


def from_value_msg(name: str, msg: Any) -> Parameter:
    """The :class:`Parameter` a ``ParameterValue`` carries.

    Raises:
        ValueError: an unknown type code, or a value its type cannot hold (the message says which).
    """
    code = int(msg.type)
    if code == 0:
        return Parameter(name, Parameter.Type.NOT_SET, None)
    if code not in _FIELDS:
        raise ValueError(f"parameter '{name}': unknown ParameterValue type {code} (0-9 are defined)")
    value = getattr(msg, _FIELDS[code])
    if code == 5:
        value = bytes(value)
    elif code >= 6:
        value = list(value.tolist() if hasattr(value, "tolist") else value)
        if code == 7:
            value = [int(v) for v in value]
        elif code == 8:
            value = [float(v) for v in value]
    try:
        return Parameter(name, Parameter.Type(code), value)
    except Exception as exc:  # noqa: BLE001 - whatever the value was, say so
        raise ValueError(f"parameter '{name}': {exc}") from exc


def _check_size(name: str, msg: Any) -> None:
    """Refuse a value larger than the bounds before it is decoded (the wire gave it already)."""
    code = int(msg.type)
    if code == 4 and len(msg.string_value) > MAX_TEXT:
        raise ValueError(f"parameter '{name[:80]}': a string of {len(msg.string_value):,} characters; at most "
                         f"{MAX_TEXT:,}")
    if code in _FIELDS and code >= 5:
        size = len(getattr(msg, _FIELDS[code]))
        limit = MAX_TEXT if code == 5 else MAX_ARRAY
        if size > limit:
            raise ValueError(f"parameter '{name[:80]}': {size:,} elements; at most {limit:,}")
        if code == 9 and any(len(v) > MAX_TEXT for v in msg.string_array_value):
            raise ValueError(f"parameter '{name[:80]}': a string longer than {MAX_TEXT:,} characters")


def _refuse_oversize(why: str, response: Any) -> Any:
    """The answer to a request over :data:`MAX_REQUEST_BYTES` or :data:`MAX_NAMES`, never decoded (``why``
    says which): for a set, one refused result that says so; for the other services an empty answer (as a
    decoded request over :data:`MAX_NAMES` gets)."""
    reason = f"refused: {why}"
    if hasattr(response, "results"):  # SetParameters
        response.results = [get_message("rcl_interfaces/msg/SetParametersResult")(successful=False, reason=reason)]
    elif hasattr(response, "result") and hasattr(response.result, "successful"):  # SetParametersAtomically
        response.result.successful, response.result.reason = False, reason
    return response


def list_names(names: Iterable[str], prefixes: list[str], depth: int) -> tuple[list[str], list[str]]:
    """``(names, prefixes)`` of ``ListParameters``: the names under any of ``prefixes`` (all without
    one) at most ``depth`` levels below it (0: any depth), and the prefixes those names have."""
    out: list[str] = []
    found: list[str] = []
    for name in sorted(names):
        if prefixes:
            bases = [p for p in prefixes if name == p or name.startswith(p + _SEPARATOR)]
            if not bases:
                continue
            below = min(name[len(p):].count(_SEPARATOR) for p in bases)
        else:
            below = name.count(_SEPARATOR) + 1
        if depth and below > depth:
            continue
        out.append(name)
        prefix = name.rpartition(_SEPARATOR)[0]
        if prefix and prefix not in found:
            found.append(prefix)
    return out, found


class ParameterServices:
    """The parameter services of one node (created at once; :meth:`destroy` removes them)."""

    def __init__(self, node: Node) -> None:
        self.node = node
        handlers = {
            "describe_parameters": self._describe, "get_parameter_types": self._types,
            "get_parameters": self._get, "list_parameters": self._list,
            "set_parameters": self._set, "set_parameters_atomically": self._set_atomically,
        }
        self.services = [node.create_service(get_service(type_name), f"~/{name}", handlers[name])
                         for name, type_name in PARAMETER_SERVICES.items()]
        for srv in self.services:
            # every parameter request starts with its sequence of names, parameters or prefixes
            srv.bound_requests(MAX_REQUEST_BYTES, _refuse_oversize, max_items=MAX_NAMES)

    def destroy(self) -> None:
        for srv in self.services:
            self.node.destroy_service(srv)
        self.services = []

    # -- handlers (under the node's callback lock) --------------------------------------------
    def _store(self) -> Any:
        return self.node._parameters

    def _describe(self, request: Any, response: Any) -> Any:
        if len(request.names) > MAX_NAMES:  # refused: no descriptors (a request of at most MAX_NAMES is answered)
            return response
        store = self._store()
        cls = get_message("rcl_interfaces/msg/ParameterDescriptor")
        for name in request.names:
            d = store.descriptors.get(name)
            msg = cls(name=name)
            if d is not None:
                msg.type = int(d.type)
                msg.description = d.description
                msg.additional_constraints = d.additional_constraints
                msg.read_only = bool(d.read_only)
                msg.dynamic_typing = bool(d.dynamic_typing)
            response.descriptors.append(msg)
        return response

    def _types(self, request: Any, response: Any) -> Any:
        if len(request.names) > MAX_NAMES:
            return response
        values = self._store().values
        response.types = [int(values[n].type_) if n in values else 0 for n in request.names]
        return response

    def _get(self, request: Any, response: Any) -> Any:
        if len(request.names) > MAX_NAMES:
            return response
        values = self._store().values
        response.values = [to_value_msg(values[n]) if n in values else to_value_msg(Parameter(n))
                           for n in request.names]
        return response

    def _list(self, request: Any, response: Any) -> Any:
        if len(request.prefixes) > MAX_NAMES:  # refused: each name is matched against every prefix
            return response
        names, prefixes = list_names(list(self._store().values), list(request.prefixes), int(request.depth))
        response.result.names = names
        response.result.prefixes = prefixes
        return response

    def _parameters(self, msgs: Any) -> tuple[list[Parameter | None], list[str]]:
        params: list[Parameter | None] = []
        errors: list[str] = []
        for msg in msgs:
            try:
                _check_size(msg.name, msg.value)
                param = from_value_msg(msg.name, msg.value)
                if param.type_ == Parameter.Type.NOT_SET:
                    raise ValueError(f"parameter '{msg.name}': a value of type NOT_SET would undeclare it, which "
                                     "this node does not allow")
                params.append(param)
                errors.append("")
            except ValueError as exc:
                params.append(None)
                errors.append(excerpt(str(exc), MAX_REASON))
        return params, errors

    def _set(self, request: Any, response: Any) -> Any:
        cls = get_message("rcl_interfaces/msg/SetParametersResult")
        if len(request.parameters) > MAX_NAMES:  # refused at once, in one result: a result per parameter would
            # make the answer as costly as the request (10,000 results: ~70 ms to encode and decode over rclpy)
            response.results = [cls(successful=False, reason=f"refused: a request sets at most {MAX_NAMES} "
                                                             f"parameters, this one {len(request.parameters):,}")]
            return response
        params, errors = self._parameters(request.parameters)
        for param, error in zip(params, errors):
            if param is None:
                response.results.append(cls(successful=False, reason=error))
                continue
            result = self.node.set_parameters([param])[0]
            reason = excerpt(result.reason, MAX_REASON)
            response.results.append(cls(successful=bool(result.successful), reason=reason))
        return response

    def _set_atomically(self, request: Any, response: Any) -> Any:
        if len(request.parameters) > MAX_NAMES:
            response.result.successful = False
            response.result.reason = (f"refused: a request sets at most {MAX_NAMES} parameters, this one "
                                      f"{len(request.parameters):,}")
            return response
        params, errors = self._parameters(request.parameters)
        bad = [e for e in errors if e]
        if bad:
            response.result.successful, response.result.reason = False, excerpt("; ".join(bad), MAX_REASON)
            return response
        result = self.node.set_parameters_atomically([p for p in params if p is not None])
        response.result.successful = bool(result.successful)
        response.result.reason = excerpt(result.reason, MAX_REASON)
        return response
