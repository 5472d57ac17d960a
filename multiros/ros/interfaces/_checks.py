"""Field validation and conversion used by generated message classes and codecs.

The generated ``__init__`` tests the common case inline (``type(v) is float``) and calls these only
when a value needs converting or is wrong, so the hot path stays a few attribute stores.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable

import numpy as np

from .errors import FieldError, FieldValueError

_NUMBER_TYPES = (int, float, np.integer, np.floating)


def unknown_fields(type_name: str, extra: dict, fields: tuple[str, ...]) -> None:
    """Raise for keyword arguments that are not fields of the type."""
    names = ", ".join(sorted(extra))
    raise FieldError(type_name, names, f"no such field; fields are: {', '.join(fields) or '(none)'}")


def to_float(value: object, type_name: str, field: str) -> float:
    """Convert an int/float/numpy number to float; reject bool, str and others."""
    if isinstance(value, _NUMBER_TYPES) and not isinstance(value, (bool, np.bool_)):
        return float(value)
    raise FieldError(type_name, field, f"expected a float, got {type(value).__name__} {value!r:.60}")


def to_int(value: object, lo: int, hi: int, type_name: str, field: str) -> int:
    """Check an integer value (int or numpy integer, not bool or float) against ``[lo, hi]``."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        value = int(value)
        if lo <= value <= hi:
            return value
        raise FieldValueError(type_name, field, f"{value} is out of range [{lo}, {hi}]")
    raise FieldError(type_name, field, f"expected an int, got {type(value).__name__} {value!r:.60}")


def to_bool(value: object, type_name: str, field: str) -> bool:
    """Accept bool and numpy bool only (0/1 ints are a likely mistake for another field)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise FieldError(type_name, field, f"expected a bool, got {type(value).__name__} {value!r:.60}")


def to_str(value: object, bound: int, type_name: str, field: str) -> str:
    """Check a string and its UTF-8 length against ``bound`` (0 = unbounded)."""
    if not isinstance(value, str):
        raise FieldError(type_name, field, f"expected a str, got {type(value).__name__} {value!r:.60}")
    if bound and len(value.encode()) > bound:
        raise FieldValueError(type_name, field, f"string of {len(value.encode())} bytes exceeds bound {bound}")
    return str(value)


def to_nested(value: object, cls: type, type_name: str, field: str) -> object:
    """Accept an instance of ``cls`` or a dict of its fields."""
    if type(value) is cls:
        return value
    if isinstance(value, dict):
        try:
            return cls(**value)
        except FieldError as exc:
            raise type(exc)(type_name, f"{field}.{exc.field}", exc.reason) from None
    raise FieldError(type_name, field, f"expected {cls._type}, got {type(value).__name__}")


def check_length(n: int, array: str, size: int, type_name: str, field: str) -> None:
    """Check a sequence length against a fixed size or upper bound."""
    if array == "fixed" and n != size:
        raise FieldValueError(type_name, field, f"fixed array needs exactly {size} elements, got {n}")
    if array == "bounded" and n > size:
        raise FieldValueError(type_name, field, f"sequence of {n} elements exceeds bound {size}")


def to_array(value: object, dtype: np.dtype, array: str, size: int, type_name: str, field: str) -> np.ndarray:
    """Convert a sequence of numbers to a 1-D numpy array of ``dtype``, checking kind and range."""
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__"):
        raise FieldError(type_name, field, f"expected a sequence of numbers, got {type(value).__name__}")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError) as exc:
        raise FieldError(type_name, field, f"expected a sequence of numbers: {exc}") from None
    if arr.ndim != 1:
        if arr.size == 0:
            arr = arr.reshape(0)
        else:
            raise FieldValueError(type_name, field, f"expected a 1-D sequence, got shape {arr.shape}")
    kind = arr.dtype.kind
    if arr.size and dtype.kind == "f":
        if kind not in "fiu":
            raise FieldError(type_name, field, f"expected numbers, got elements of dtype {arr.dtype}")
    elif arr.size:
        if kind not in "iu":
            raise FieldError(type_name, field, f"expected integers, got elements of dtype {arr.dtype}")
        info = np.iinfo(dtype)
        lo, hi = int(arr.min()), int(arr.max())
        if lo < info.min or hi > info.max:
            bad = lo if lo < info.min else hi
            raise FieldValueError(type_name, field, f"element {bad} is out of range [{info.min}, {info.max}]")
    check_length(len(arr), array, size, type_name, field)
    return arr.astype(dtype)


def to_bytes(value: object, array: str, size: int, type_name: str, field: str) -> bytes:
    """Convert bytes-like or a sequence of ints in [0, 255] to ``bytes``."""
    if isinstance(value, np.ndarray) and value.dtype.kind in "iu":
        value = to_array(value, np.dtype(np.uint8), array, size, type_name, field)
    if isinstance(value, str) or not isinstance(value, (bytes, bytearray, memoryview, np.ndarray, Iterable)):
        raise FieldError(type_name, field, f"expected bytes or a sequence of ints, got {type(value).__name__}")
    try:
        data = bytes(value)
    except (TypeError, ValueError) as exc:
        cls = FieldValueError if isinstance(exc, ValueError) else FieldError
        raise cls(type_name, field, f"expected bytes or ints in [0, 255]: {exc}") from None
    check_length(len(data), array, size, type_name, field)
    return data


def to_list(value: object, convert, array: str, size: int, type_name: str, field: str) -> list:
    """Convert each element with ``convert(element, field_path)`` and check the length."""
    if isinstance(value, (str, bytes, dict)) or not isinstance(value, Iterable):
        raise FieldError(type_name, field, f"expected a list, got {type(value).__name__}")
    out = [convert(v, f"{field}[{i}]") for i, v in enumerate(value)]
    check_length(len(out), array, size, type_name, field)
    return out


def find_pack_error(msg: object, items: tuple, endian: str, type_name: str, exc: Exception) -> FieldError:
    """Locate which value of a packed run of primitives failed and build the error for it."""
    for path, code in items:
        if code is None:
            continue
        obj = msg
        try:
            for part in path.split("."):
                obj = getattr(obj, part)
            struct.pack(endian + code, obj)
        except (struct.error, TypeError, ValueError, OverflowError) as err:
            return pack_error(type_name, path, err, obj)
        except AttributeError as err:
            return FieldError(type_name, path, str(err))
    return FieldError(type_name, ", ".join(p for p, _ in items), f"{type(exc).__name__}: {exc}")


def pack_error(type_name: str, field: str, exc: Exception, value: object = None) -> FieldError:
    """Translate a ``struct``/numpy error while serializing ``field`` into a FieldError."""
    text = str(exc)
    if isinstance(exc, OverflowError) or "requires" in text or "range" in text or "too large" in text:
        return FieldValueError(type_name, field, f"value {value!r:.60} out of range ({text})")
    return FieldError(type_name, field, f"bad value {value!r:.60} of type {type(value).__name__} ({text})")
