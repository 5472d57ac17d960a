"""Serve every supported ROS 2 distribution's variant of a service at once.

A service's rmw_zenoh key ends in the RIHS01 hash of its definition, so the variants of one
service (Jazzy's ``SpawnEntity`` and Rolling's, say) live side by side under one service name.
The node's callbacks are written against one variant, :data:`NATIVE_DISTRO` (Rolling: its
``simulation_interfaces`` 2.x is a superset in meaning: a ``Resource`` for uri/string and explicit
``set_pose``/``set_twist`` flags). :func:`create_services` creates the native service plus one
per distinct other hash, whose requests are converted to the native type and whose responses are
converted back:

* generic, field by field (same names, nested messages and sequences converted recursively,
  fields the target lacks dropped, fields the source lacks left at their defaults);
* explicit where meaning differs: Jazzy/Kilted's top-level ``uri``/``resource_string`` (SpawnEntity,
  LoadWorld) and ``uri`` (Spawnable) against Rolling's ``Resource`` field, and Jazzy/Kilted's
  SetEntityState, which sets everything (Rolling: ``set_pose = set_twist = set_acceleration = True``).

Types whose definitions are identical in two distributions are the same class (see
:mod:`multiros.ros.interfaces.registry`), so conversion is a no-op for them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from multiros.ros.interfaces import (
    SUPPORTED_DISTROS,
    UnknownTypeError,
    registry_for,
    type_hash,
)

__all__ = [
    "NATIVE_DISTRO",
    "SERVED_DISTROS",
    "convert_message",
    "create_services",
    "get_message",
    "get_service",
    "service_variants",
]

#: The variant the node's callbacks are written against.
NATIVE_DISTRO = "rolling"
#: Every distribution whose variants the node serves.
SERVED_DISTROS: tuple[str, ...] = SUPPORTED_DISTROS

_NATIVE = registry_for(NATIVE_DISTRO)

# Rolling-shape type -> its Resource field; the older shape has top-level uri (and resource_string).
_RESOURCE_FIELDS = {
    "simulation_interfaces/srv/SpawnEntity_Request": "entity_resource",
    "simulation_interfaces/srv/LoadWorld_Request": "world_resource",
    "simulation_interfaces/msg/Spawnable": "entity_resource",
}
_SET_FLAGS = ("set_pose", "set_twist", "set_acceleration")


def get_message(name: str) -> type:
    """A message class of the node's native distribution (:data:`NATIVE_DISTRO`)."""
    return _NATIVE.message_class(name)


def get_service(name: str) -> type:
    """A service class of the node's native distribution (:data:`NATIVE_DISTRO`)."""
    return _NATIVE.service_class(name)


def service_variants(type_name: str, distros: Iterable[str] = SERVED_DISTROS) -> list[tuple[str, type]]:
    """``(distro, class)`` for the native variant first, then one per other distinct type hash.

    A distribution without the type is skipped; so is one whose variant hashes like one listed.
    """
    native = get_service(type_name)
    out = [(NATIVE_DISTRO, native)]
    seen = {type_hash(native)}
    for distro in distros:
        try:
            cls = registry_for(distro).service_class(type_name)
        except UnknownTypeError:
            continue
        digest = type_hash(cls)
        if digest not in seen:
            seen.add(digest)
            out.append((distro, cls))
    return out


def _fields(cls: type) -> dict[str, Any]:
    return {f.name: f for f in cls._spec.fields}


def convert_message(msg: Any, target: type) -> Any:
    """``msg`` as an instance of ``target``, another distribution's variant of the same type.

    Returns ``msg`` itself when it already is a ``target``.
    """
    source = type(msg)
    if source is target:
        return msg
    out = target()
    src_fields = _fields(source)
    for name, field in _fields(target).items():
        if name not in src_fields:
            continue
        value = getattr(msg, name)
        if field.type.is_nested:
            cls = target._registry.message_class(field.type.base)
            if field.type.array:
                value = [convert_message(v, cls) for v in value]
            else:
                value = convert_message(value, cls)
        setattr(out, name, value)
    _adapt_meaning(msg, out, src_fields)
    return out


def _adapt_meaning(src: Any, out: Any, src_fields: dict[str, Any]) -> None:
    """The explicit part: fields whose shape differs between the variants."""
    out_fields = _fields(type(out))
    kind = type(out)._type
    res_field = _RESOURCE_FIELDS.get(kind)
    if res_field is not None:
        if res_field in out_fields and res_field not in src_fields:  # older shape -> Resource
            resource = getattr(out, res_field)
            resource.uri = src.uri
            if "resource_string" in src_fields:
                resource.resource_string = src.resource_string
        elif res_field in src_fields and res_field not in out_fields:  # Resource -> older shape
            resource = getattr(src, res_field)
            out.uri = resource.uri
            if "resource_string" in out_fields:
                out.resource_string = resource.resource_string
    if kind == "simulation_interfaces/srv/SetEntityState_Request" and "set_pose" not in src_fields:
        for flag in _SET_FLAGS:  # without flags the request sets the whole state
            if flag in out_fields:
                setattr(out, flag, True)


def adapt_callback(callback: Callable[[Any, Any], Any], variant: type, native: type) -> Callable[[Any, Any], Any]:
    """A service callback for ``variant`` that runs ``callback`` (written for ``native``)."""
    native_response = native.Response
    variant_response = variant.Response
    native_request = native.Request

    def call(request: Any, response: Any) -> Any:
        result = callback(convert_message(request, native_request), native_response())
        if result is None:
            return None
        return convert_message(result, variant_response)

    call.__name__ = f"{getattr(callback, '__name__', 'callback')}_{variant._registry.distro}"
    return call


def create_services(node: Any, type_name: str, srv_name: str, callback: Callable[[Any, Any], Any],
                    **kwargs: Any) -> list[Any]:
    """Create ``srv_name`` for every served distribution's variant of ``type_name``.

    ``callback`` is written against the native variant; the others go through
    :func:`adapt_callback`. Returns the services, native first.
    """
    variants = service_variants(type_name)
    native = variants[0][1]
    services = [node.create_service(native, srv_name, callback, **kwargs)]
    for _distro, cls in variants[1:]:
        services.append(node.create_service(cls, srv_name, adapt_callback(callback, cls, native), **kwargs))
    return services
