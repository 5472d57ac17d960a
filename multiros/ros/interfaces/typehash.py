"""RIHS01 type hashes and type descriptions, computed the way rosidl does (Iron and later).

The hash is SHA-256 over the JSON of the type description: the type itself plus, sorted by name,
every type it references; each field reduced to ``{type_id, capacity, string_capacity,
nested_type_name}`` (defaults, constants and comments are not hashed). Points that decide exactness:

* ``char`` in a ``.msg`` becomes IDL ``uint8`` in rosidl, so its field type id is 3 (UINT8), not 13
  (CHAR). This matters for every service, via ``service_msgs/ServiceEventInfo.client_gid``.
* A struct without fields gets rosidl's ``uint8 structure_needs_at_least_one_member``.
* A service is a struct of ``request_message``, ``response_message`` and ``event_message``; an action
  one of ``goal``, ``result``, ``feedback``, ``send_goal_service``, ``get_result_service`` and
  ``feedback_message`` (rosidl_generator_type_description).
* JSON is ``json.dumps`` with its default ``", "``/``": "`` separators, keys in rosidl's order.
"""

from __future__ import annotations

import hashlib
import json

from .idl import FieldType
from .registry import TypeRegistry, default_registry

__all__ = ["FIELD_TYPE_IDS", "type_description", "type_hash"]

#: type_description_interfaces/msg/FieldType ids of the scalar types (char mapped to UINT8, see above).
FIELD_TYPE_IDS: dict[str, int] = {
    "nested": 1, "int8": 2, "uint8": 3, "char": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7,
    "int64": 8, "uint64": 9, "float32": 10, "float64": 11, "bool": 15, "byte": 16, "string": 17,
    "wstring": 18, "bounded_string": 21, "bounded_wstring": 22,
}
_ARRAY_OFFSET = {"": 0, "fixed": 48, "bounded": 96, "unbounded": 144}
_EMPTY_MEMBER = ("structure_needs_at_least_one_member", FieldType("uint8"))


def _field(name: str, t: FieldType) -> dict:
    if t.is_nested:
        base = FIELD_TYPE_IDS["nested"]
    elif t.string_bound:
        base = FIELD_TYPE_IDS["bounded_" + t.base]
    else:
        base = FIELD_TYPE_IDS[t.base]
    return {
        "name": name,
        "type": {
            "type_id": base + _ARRAY_OFFSET[t.array],
            "capacity": t.size,
            "string_capacity": t.string_bound,
            "nested_type_name": t.base if t.is_nested else "",
        },
    }


def _struct(name: str, fields: list[tuple[str, FieldType]]) -> dict:
    return {"type_name": name, "fields": [_field(n, t) for n, t in (fields or [_EMPTY_MEMBER])]}


def _fields_of(reg: TypeRegistry, full: str) -> list[tuple[str, FieldType]]:
    """Fields of the struct describing ``full``: a message, a service or an action."""
    try:
        spec = reg.message_spec(full)
    except LookupError:
        pass
    else:
        return [(f.name, f.type) for f in spec.fields]
    try:
        s = reg.service_spec(full)
    except LookupError:
        a = reg.action_spec(full)
        fields = [("goal", a.goal.name), ("result", a.result.name), ("feedback", a.feedback.name),
                  ("send_goal_service", a.send_goal.name), ("get_result_service", a.get_result.name),
                  ("feedback_message", a.feedback_message.name)]
    else:
        fields = [("request_message", s.request.name), ("response_message", s.response.name),
                  ("event_message", s.event.name)]
    return [(n, FieldType(t)) for n, t in fields]


def type_description(type_name: str, registry: TypeRegistry | None = None) -> dict:
    """The hashable type description of a message, service or action (rosidl's JSON structure).

    Args:
        type_name: ``pkg/msg/Name``, ``pkg/srv/Name``, ``pkg/action/Name`` (or ``pkg/Name``).
        registry: Where to look types up; default: the shipped definitions.

    Returns:
        ``{"type_description": {...}, "referenced_type_descriptions": [...]}``.
    """
    reg = registry or default_registry()
    full = reg.resolve(type_name)
    top = _fields_of(reg, full)
    referenced: dict[str, dict] = {}

    def visit(t: FieldType) -> None:
        if not t.is_nested or t.base in referenced:
            return
        fields = _fields_of(reg, t.base)
        referenced[t.base] = _struct(t.base, fields)
        for _, ft in fields:
            visit(ft)

    for _, ft in top:
        visit(ft)
    referenced.pop(full, None)
    return {
        "type_description": _struct(full, top),
        "referenced_type_descriptions": [referenced[k] for k in sorted(referenced)],
    }


def type_hash(type_name: str | type, registry: TypeRegistry | None = None) -> str:
    """``RIHS01_<64 hex>`` of a message, service or action, as rosidl computes it.

    Args:
        type_name: ``pkg/msg/Name``, ``pkg/srv/Name``, ``pkg/action/Name`` (or ``pkg/Name``: message
            first, then service, then action), or a generated class (hashed with the registry, so
            the distribution, that made it).
        registry: Where to look types up; default: the class's registry, else the default one.
    """
    if not isinstance(type_name, str):
        cls = type_name
        type_name = getattr(cls, "_type", None)
        if not isinstance(type_name, str):
            raise TypeError(f"type_hash needs a type name or a generated interface class, got {cls!r}")
        registry = registry or getattr(cls, "_registry", None)
    reg = registry or default_registry()
    cache = reg.__dict__.setdefault("_hash_cache", {})
    found = cache.get(type_name)
    if found is None:
        desc = type_description(type_name, reg)
        found = cache[type_name] = "RIHS01_" + hashlib.sha256(json.dumps(desc).encode()).hexdigest()
    return found
