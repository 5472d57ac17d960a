"""Parse ROS 2 ``.msg``, ``.srv`` and ``.action`` text into immutable specs.

Hand-written rather than reusing ``rosbags.typesys.get_types_from_msg``: rosbags drops field default
values (``float64 w 1`` in ``geometry_msgs/Quaternion``) and maps ``char`` to its own type, and both
matter here (defaults for keyword construction, ``char`` -> ``uint8`` for rosidl-exact type hashes).
rosbags is also only a test dependency. The grammar is small: one field or constant per line,
``#`` comments, ``---`` separating the parts of services and actions.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass, field

from .errors import InterfaceDefinitionError

__all__ = [
    "PRIMITIVES",
    "ActionSpec",
    "Constant",
    "Field",
    "FieldType",
    "MessageSpec",
    "ServiceSpec",
    "parse_action",
    "parse_message",
    "parse_service",
]

#: Primitive types of the .msg language with their CDR size in bytes (strings: 0 = variable).
PRIMITIVES: dict[str, int] = {
    "bool": 1, "byte": 1, "char": 1, "int8": 1, "uint8": 1,
    "int16": 2, "uint16": 2, "int32": 4, "uint32": 4, "int64": 8, "uint64": 8,
    "float32": 4, "float64": 8, "string": 0, "wstring": 0,
}
INTEGER_RANGES: dict[str, tuple[int, int]] = {
    "byte": (0, 255), "char": (0, 255), "int8": (-(2**7), 2**7 - 1), "uint8": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1), "uint16": (0, 2**16 - 1), "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1), "int64": (-(2**63), 2**63 - 1), "uint64": (0, 2**64 - 1),
}

_FIELD_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
_CONST_NAME = re.compile(r"^[A-Z][A-Z0-9_]*$")
_TYPE = re.compile(
    r"^(?P<base>[A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z][A-Za-z0-9_]*){0,2})"
    r"(?:<=(?P<sbound>\d+))?"
    r"(?:\[(?P<arr>(?:<=)?\d*)\])?$"
)


@dataclass(frozen=True)
class FieldType:
    """The type of one field.

    Attributes:
        base: A primitive name (``float64``, ``string``, ...) or a full nested type name
            (``std_msgs/msg/Header``).
        string_bound: Upper bound of a bounded ``string<=N``/``wstring<=N``; 0 when unbounded.
        array: ``""`` (scalar), ``"fixed"`` (``T[N]``), ``"bounded"`` (``T[<=N]``) or
            ``"unbounded"`` (``T[]``).
        size: Length of a fixed array or bound of a bounded sequence; 0 otherwise.
    """

    base: str
    string_bound: int = 0
    array: str = ""
    size: int = 0

    @property
    def is_nested(self) -> bool:
        """True for a message type, False for a primitive."""
        return "/" in self.base

    @property
    def is_sequence(self) -> bool:
        """True for ``T[]`` and ``T[<=N]``."""
        return self.array in ("bounded", "unbounded")

    def element(self) -> FieldType:
        """The same type without its array part."""
        return FieldType(self.base, self.string_bound)

    def __str__(self) -> str:
        text = self.base
        if self.string_bound:
            text += f"<={self.string_bound}"
        return text + {"": "", "fixed": f"[{self.size}]", "bounded": f"[<={self.size}]",
                       "unbounded": "[]"}[self.array]


@dataclass(frozen=True)
class Field:
    """One field: name, type and the default value given in the definition (None if absent)."""

    name: str
    type: FieldType
    default: object = None


@dataclass(frozen=True)
class Constant:
    """One constant (``uint8 OK = 1``); ``type`` is a primitive name."""

    name: str
    type: str
    value: object


@dataclass(frozen=True)
class MessageSpec:
    """A parsed message type: its full name, fields and constants, in definition order."""

    name: str
    fields: tuple[Field, ...]
    constants: tuple[Constant, ...] = ()

    @property
    def package(self) -> str:
        """The interface package (``sensor_msgs``)."""
        return self.name.split("/", 1)[0]

    def nested_names(self) -> list[str]:
        """Full names of the message types the fields refer to, in field order."""
        return [f.type.base for f in self.fields if f.type.is_nested]


@dataclass(frozen=True)
class ServiceSpec:
    """A parsed service: its name plus request, response and (derived) event message specs."""

    name: str
    request: MessageSpec
    response: MessageSpec
    event: MessageSpec = field(repr=False, default=None)  # type: ignore[assignment]


@dataclass(frozen=True)
class ActionSpec:
    """A parsed action: goal, result, feedback plus the rosidl-derived messages and services."""

    name: str
    goal: MessageSpec
    result: MessageSpec
    feedback: MessageSpec
    feedback_message: MessageSpec
    send_goal: ServiceSpec
    get_result: ServiceSpec


def _strip_comment(line: str) -> str:
    quote = ""
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch == "#":
            return line[:i]
    return line


def _resolve(base: str, package: str) -> str:
    """Full type name of a field type token as written in a definition of ``package``."""
    if base in PRIMITIVES:
        return base
    parts = base.split("/")
    if len(parts) == 1:
        return f"{package}/msg/{base}"
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return base


def _parse_scalar(text: str, base: str, where: str) -> object:
    text = text.strip()
    try:
        if base in ("string", "wstring"):
            if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
                return ast.literal_eval(text)
            return text
        if base == "bool":
            low = text.lower()
            if low in ("true", "1"):
                return True
            if low in ("false", "0"):
                return False
            raise ValueError(text)
        if base in ("float32", "float64"):
            return float(text)
        value = int(text, 0)
    except (ValueError, SyntaxError) as exc:
        raise InterfaceDefinitionError(f"{where}: {text!r} is not a valid {base} value") from exc
    lo, hi = INTEGER_RANGES[base]
    if not lo <= value <= hi:
        raise InterfaceDefinitionError(f"{where}: {value} is out of range for {base} [{lo}, {hi}]")
    return value


def _split_list(text: str) -> list[str]:
    items, cur, quote = [], "", ""
    for ch in text:
        if quote:
            cur += ch
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
            cur += ch
        elif ch == ",":
            items.append(cur)
            cur = ""
        else:
            cur += ch
    if cur.strip():
        items.append(cur)
    return [i.strip() for i in items]


def _parse_default(text: str, ftype: FieldType, where: str) -> object:
    if ftype.is_nested:
        raise InterfaceDefinitionError(f"{where}: nested message fields cannot have default values")
    if not ftype.array:
        return _parse_scalar(text, ftype.base, where)
    text = text.strip()
    if not (text.startswith("[") and text.endswith("]")):
        raise InterfaceDefinitionError(f"{where}: array default must be written [a, b, ...], got {text!r}")
    values = [_parse_scalar(item, ftype.base, where) for item in _split_list(text[1:-1])]
    if ftype.array == "fixed" and len(values) != ftype.size:
        raise InterfaceDefinitionError(f"{where}: default has {len(values)} values, array needs {ftype.size}")
    if ftype.array == "bounded" and len(values) > ftype.size:
        raise InterfaceDefinitionError(f"{where}: default has {len(values)} values, bound is {ftype.size}")
    return tuple(values)


def _parse_type(token: str, package: str, where: str) -> FieldType:
    match = _TYPE.match(token)
    if not match:
        raise InterfaceDefinitionError(f"{where}: cannot parse type {token!r}")
    base = _resolve(match["base"], package)
    sbound = int(match["sbound"]) if match["sbound"] else 0
    if sbound and base not in ("string", "wstring"):
        raise InterfaceDefinitionError(f"{where}: only strings take a '<=N' bound, not {match['base']!r}")
    arr, array, size = match["arr"], "", 0
    if arr is not None:
        if arr == "":
            array = "unbounded"
        elif arr.startswith("<="):
            array, size = "bounded", int(arr[2:])
        else:
            array, size = "fixed", int(arr)
    return FieldType(base, sbound, array, size)


def parse_message(text: str, name: str, source: str = "") -> MessageSpec:
    """Parse the text of one message (or one part of a service/action).

    Args:
        text: ``.msg`` syntax.
        name: Full type name to give the spec, e.g. ``sensor_msgs/msg/JointState``.
        source: File name used in error messages (defaults to ``name``).

    Returns:
        The parsed spec.

    Raises:
        InterfaceDefinitionError: A line does not parse; the message names file and line.
    """
    package = name.split("/", 1)[0]
    fields: list[Field] = []
    constants: list[Constant] = []
    seen: set[str] = set()
    for lineno, raw in enumerate(text.splitlines(), 1):
        where = f"{source or name}:{lineno}"
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        head = line.split(None, 1)
        if len(head) < 2:
            raise InterfaceDefinitionError(f"{where}: expected '<type> <name>', got {line!r}")
        type_token, rest = head[0], head[1].lstrip()
        const_match = re.match(r"^([A-Za-z][A-Za-z0-9_]*)\s*=(.*)$", rest)
        if const_match:
            cname, value_text = const_match[1], const_match[2]
            if type_token not in PRIMITIVES or type_token == "wstring":
                raise InterfaceDefinitionError(f"{where}: constant {cname} must have a primitive type")
            if not _CONST_NAME.match(cname):
                raise InterfaceDefinitionError(f"{where}: constant name {cname!r} must be UPPER_CASE")
            if type_token != "string":
                value_text = _strip_comment(value_text)
            else:
                stripped = value_text.strip()
                if stripped[:1] in ("'", '"'):
                    value_text = _strip_comment(stripped)
                else:
                    value_text = stripped.split("#", 1)[0]
            constants.append(Constant(cname, type_token, _parse_scalar(value_text, type_token, where)))
            continue
        body = _strip_comment(rest).strip()
        parts = body.split(None, 1)
        fname = parts[0]
        if not _FIELD_NAME.match(fname):
            raise InterfaceDefinitionError(f"{where}: field name {fname!r} must match [a-z][a-z0-9_]*")
        if fname in seen:
            raise InterfaceDefinitionError(f"{where}: duplicate field {fname!r}")
        seen.add(fname)
        ftype = _parse_type(type_token, package, where)
        default = _parse_default(parts[1], ftype, where) if len(parts) > 1 else None
        fields.append(Field(fname, ftype, default))
    return MessageSpec(name, tuple(fields), tuple(constants))


def _split_parts(text: str, count: int, source: str) -> list[str]:
    parts: list[list[str]] = [[]]
    for line in text.splitlines():
        if line.strip() == "---":
            parts.append([])
        else:
            parts[-1].append(line)
    if len(parts) != count:
        raise InterfaceDefinitionError(f"{source}: expected {count - 1} '---' separator(s), found {len(parts) - 1}")
    return ["\n".join(p) for p in parts]


def _event_spec(service: str, request: MessageSpec, response: MessageSpec) -> MessageSpec:
    # rosidl adds <Srv>_Event for service introspection; it is part of the service's type hash.
    return MessageSpec(f"{service}_Event", (
        Field("info", FieldType("service_msgs/msg/ServiceEventInfo")),
        Field("request", FieldType(request.name, array="bounded", size=1)),
        Field("response", FieldType(response.name, array="bounded", size=1)),
    ))


def make_service(name: str, request: MessageSpec, response: MessageSpec) -> ServiceSpec:
    """Build a :class:`ServiceSpec` from parsed request and response specs (adds the Event type)."""
    return ServiceSpec(name, request, response, _event_spec(name, request, response))


def parse_service(text: str, name: str, source: str = "") -> ServiceSpec:
    """Parse ``.srv`` text (request, ``---``, response) for service ``pkg/srv/Name``."""
    req, resp = _split_parts(text, 2, source or name)
    return make_service(name, parse_message(req, f"{name}_Request", source),
                        parse_message(resp, f"{name}_Response", source))


def parse_action(text: str, name: str, source: str = "") -> ActionSpec:
    """Parse ``.action`` text (goal, ``---``, result, ``---``, feedback) for ``pkg/action/Name``.

    Also derives, as rosidl does, ``<Name>_SendGoal`` and ``<Name>_GetResult`` services and the
    ``<Name>_FeedbackMessage`` topic type.
    """
    goal_t, result_t, feedback_t = _split_parts(text, 3, source or name)
    goal = parse_message(goal_t, f"{name}_Goal", source)
    result = parse_message(result_t, f"{name}_Result", source)
    feedback = parse_message(feedback_t, f"{name}_Feedback", source)
    uuid = Field("goal_id", FieldType("unique_identifier_msgs/msg/UUID"))
    send_goal = make_service(
        f"{name}_SendGoal",
        MessageSpec(f"{name}_SendGoal_Request", (uuid, Field("goal", FieldType(goal.name)))),
        MessageSpec(f"{name}_SendGoal_Response", (
            Field("accepted", FieldType("bool")), Field("stamp", FieldType("builtin_interfaces/msg/Time")))),
    )
    get_result = make_service(
        f"{name}_GetResult",
        MessageSpec(f"{name}_GetResult_Request", (uuid,)),
        MessageSpec(f"{name}_GetResult_Response", (
            Field("status", FieldType("int8")), Field("result", FieldType(result.name)))),
    )
    feedback_message = MessageSpec(
        f"{name}_FeedbackMessage", (uuid, Field("feedback", FieldType(feedback.name))))
    return ActionSpec(name, goal, result, feedback, feedback_message, send_goal, get_result)
