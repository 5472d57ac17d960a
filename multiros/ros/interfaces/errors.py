"""Exceptions raised by the interface layer: one hierarchy rooted at :class:`InterfaceError`.

Each exception also derives from the builtin a caller would naturally catch (``LookupError`` for an
unknown name, ``TypeError``/``ValueError`` for a bad field, ``ValueError`` for bad bytes), so code
written against rclpy's behaviour keeps working.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = [
    "DeserializationError",
    "FieldError",
    "FieldValueError",
    "InterfaceDefinitionError",
    "InterfaceError",
    "UnknownTypeError",
    "UnsupportedDistroError",
]


class InterfaceError(Exception):
    """Base class of every error raised by :mod:`multiros.ros.interfaces`."""


class UnknownTypeError(InterfaceError, LookupError):
    """A type name that no shipped (or registered) interface definition provides.

    The message may be given as a function that writes it, called when the message is first read:
    a lookup that is expected to miss (another distribution without the type, a name tried as a
    message before a service) raises and catches this without searching every known name for the
    "did you mean" hint (a few milliseconds each, hundreds of times per env made).
    """

    def __init__(self, message: str | Callable[[], str] = "") -> None:
        self._write = None if isinstance(message, str) else message
        super().__init__(*((message,) if isinstance(message, str) else ()))

    def __str__(self) -> str:  # LookupError would quote the message like a dict key
        if self._write is not None:
            self.args, self._write = (self._write(),), None
        return str(self.args[0]) if self.args else ""

    def __reduce__(self) -> tuple[Any, ...]:  # pickled (to another process) with its message written
        return type(self), (str(self),)


class InterfaceDefinitionError(InterfaceError, ValueError):
    """A ``.msg``/``.srv``/``.action`` text that does not parse; the message names file and line."""


class FieldError(InterfaceError, TypeError):
    """A message field holds a value of the wrong type (or an unknown field was given).

    Attributes:
        type_name: Full type name, e.g. ``sensor_msgs/msg/JointState``.
        field: Dotted path of the offending field inside that type (``header.stamp.sec``).
    """

    def __init__(self, type_name: str, field: str, reason: str) -> None:
        self.type_name = type_name
        self.field = field
        self.reason = reason
        super().__init__(f"{type_name}.{field}: {reason}" if field else f"{type_name}: {reason}")


class FieldValueError(FieldError, ValueError):
    """A field value of the right type but outside what the type allows.

    Out-of-range integers, strings longer than their bound, sequences over their bound and fixed
    arrays of the wrong length raise this. It is both a :class:`FieldError` (a ``TypeError``) and a
    ``ValueError``.
    """


class DeserializationError(InterfaceError, ValueError):
    """Bytes that are not a valid CDR encoding of the requested type.

    Attributes:
        type_name: The requested type.
        field: Dotted path of the field being decoded when the problem was found ('' if none).
        reason: What was wrong (truncated, bad length, trailing bytes, ...).
    """

    def __init__(self, type_name: str, field: str, reason: str) -> None:
        self.type_name = type_name
        self.field = field
        self.reason = reason
        where = f"{type_name}.{field}" if field else type_name
        super().__init__(f"cannot deserialize {where}: {reason}")


class UnsupportedDistroError(InterfaceError, ValueError):
    """A ROS 2 distribution (``ROS_DISTRO`` or an argument) whose definitions or wire uniros lacks."""
