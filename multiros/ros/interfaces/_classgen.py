"""Generate a Python message class from a :class:`MessageSpec` (source text, then ``exec``).

Generated rather than one generic class with ``__setattr__`` hooks because construction is on the hot
path (a StepRobot response per env step): the generated ``__init__`` is straight-line code with one
inline type test per field and calls into :mod:`._checks` only for values that need converting.

Python representation of field values (documented once here, relied on by the codec):

* ``float32``/``float64`` -> ``float``; integer types, ``byte`` and ``char`` -> ``int``; ``bool`` -> ``bool``;
  ``string``/``wstring`` -> ``str``; nested message -> instance of its class.
* sequences and fixed arrays of ``uint8``, ``byte`` and ``char`` -> ``bytes`` (``Image.data``, UUIDs,
  GIDs); of other numbers -> 1-D ``numpy.ndarray`` of the matching dtype (``float64[]`` -> float64);
  of ``bool`` -> ``list[bool]``; of strings -> ``list[str]``; of messages -> ``list`` of instances.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from . import _checks
from .idl import INTEGER_RANGES, FieldType, MessageSpec

__all__ = ["BYTES_BASES", "NP_DTYPES", "build_message_class", "rclpy_type_string", "value_kind"]

NP_DTYPES: dict[str, np.dtype] = {
    name: np.dtype(code) for name, code in {
        "int8": "<i1", "int16": "<i2", "uint16": "<u2", "int32": "<i4", "uint32": "<u4",
        "int64": "<i8", "uint64": "<u8", "float32": "<f4", "float64": "<f8",
    }.items()
}
BYTES_BASES = frozenset({"uint8", "byte", "char"})
_RCLPY_NAMES = {"bool": "boolean", "byte": "octet", "char": "uint8", "float32": "float", "float64": "double"}


class _Unset:
    __slots__ = ()

    def __repr__(self) -> str:
        return "<default>"


_UNSET = _Unset()


def value_kind(ftype: FieldType) -> str:
    """How a field is held in Python: see the module docstring."""
    if ftype.array:
        if ftype.is_nested:
            return "list_nested"
        if ftype.base in BYTES_BASES:
            return "bytes"
        if ftype.base in NP_DTYPES:
            return "ndarray"
        return "list_bool" if ftype.base == "bool" else "list_str"
    if ftype.is_nested:
        return "nested"
    if ftype.base in ("float32", "float64"):
        return "float"
    if ftype.base == "bool":
        return "bool"
    return "str" if ftype.base in ("string", "wstring") else "int"


def rclpy_type_string(ftype: FieldType) -> str:
    """The type string rclpy's ``get_fields_and_field_types()`` uses for this field."""
    if ftype.is_nested:
        pkg, _, name = ftype.base.split("/")
        base = f"{pkg}/{name}"
    elif ftype.string_bound:
        base = f"{ftype.base}<{ftype.string_bound}>"
    else:
        base = _RCLPY_NAMES.get(ftype.base, ftype.base)
    if ftype.array == "fixed":
        return f"{base}[{ftype.size}]"
    if ftype.array == "bounded":
        return f"sequence<{base}, {ftype.size}>"
    return f"sequence<{base}>" if ftype.array else base


def _arrays_equal(a: object, b: object) -> bool:
    if a is b:
        return True
    if type(a) is np.ndarray and type(b) is np.ndarray:
        return a.shape == b.shape and bool((a == b).all())
    return bool(np.array_equal(a, b))


def _rebuild(type_name: str, values: tuple) -> object:
    from .registry import default_registry  # late: registry imports this module

    cls = default_registry().message_class(type_name)
    obj = cls.__new__(cls)
    for name, value in zip(cls._fields, values):
        setattr(obj, name, value)
    return obj


def _readonly_empty(dtype: np.dtype) -> np.ndarray:
    arr = np.empty(0, dtype)
    arr.flags.writeable = False
    return arr


def _field_init(f, ns: dict, class_of: Callable[[str], type]) -> str:
    """One line of ``__init__`` assigning field ``f`` from the keyword argument of the same name."""
    n, t, kind = f.name, f.type, value_kind(f.type)
    arg = (repr(t.array), t.size, "_T", repr(n))
    if kind == "float":
        d = float(f.default or 0.0)
        return f"self.{n} = {d!r} if {n} is _U else ({n} if _ty({n}) is _float else _to_float({n}, _T, {n!r}))"
    if kind == "int":
        lo, hi = INTEGER_RANGES[t.base]
        d = int(f.default or 0)
        return (f"self.{n} = {d} if {n} is _U else ({n} if _ty({n}) is _int and {lo} <= {n} <= {hi} "
                f"else _to_int({n}, {lo}, {hi}, _T, {n!r}))")
    if kind == "bool":
        return (f"self.{n} = {bool(f.default)} if {n} is _U else "
                f"({n} if _ty({n}) is _bool else _to_bool({n}, _T, {n!r}))")
    if kind == "str":
        d = f.default or ""
        fast = f"_ty({n}) is _str" + (f" and _len({n}) * 4 <= {t.string_bound}" if t.string_bound else "")
        return f"self.{n} = {d!r} if {n} is _U else ({n} if {fast} else _to_str({n}, {t.string_bound}, _T, {n!r}))"
    if kind == "nested":
        ns[f"_C_{n}"] = class_of(t.base)
        return (f"self.{n} = _C_{n}() if {n} is _U else "
                f"({n} if _ty({n}) is _C_{n} else _to_nested({n}, _C_{n}, _T, {n!r}))")
    length = {"fixed": f" and _len({n}) == {t.size}", "bounded": f" and _len({n}) <= {t.size}",
              "unbounded": ""}[t.array]
    if kind == "ndarray":
        ns[f"_DT_{n}"] = NP_DTYPES[t.base]
        if f.default is not None:
            ns[f"_DEF_{n}"] = f.default
            default = f"_np.array(_DEF_{n}, _DT_{n})"
        elif t.array == "fixed":
            default = f"_np.zeros({t.size}, _DT_{n})"
        else:
            ns[f"_E_{n}"] = _readonly_empty(NP_DTYPES[t.base])
            default = f"_E_{n}"
        return (f"self.{n} = {default} if {n} is _U else ({n} if _ty({n}) is _nd and {n}.dtype == _DT_{n} "
                f"and {n}.ndim == 1{length} else _to_array({n}, _DT_{n}, {', '.join(map(str, arg))}))")
    if kind == "bytes":
        ns[f"_DEF_{n}"] = bytes(f.default) if f.default is not None else bytes(t.size if t.array == "fixed" else 0)
        return (f"self.{n} = _DEF_{n} if {n} is _U else ({n} if _ty({n}) is _bytes{length} "
                f"else _to_bytes({n}, {', '.join(map(str, arg))}))")
    # lists: validate every element through a per-field converter
    if kind == "list_bool":
        ns[f"_cv_{n}"] = lambda v, p: v if type(v) is bool else _checks.to_bool(v, ns["_T"], p)
        filler = "False"
    elif kind == "list_str":
        bound = t.string_bound
        ns[f"_cv_{n}"] = lambda v, p, b=bound: v if type(v) is str and not b else _checks.to_str(v, b, ns["_T"], p)
        filler = "''"
    else:
        cls = class_of(t.base)
        ns[f"_C_{n}"] = cls
        ns[f"_cv_{n}"] = lambda v, p, c=cls: v if type(v) is c else _checks.to_nested(v, c, ns["_T"], p)
        filler = None
    if f.default is not None:
        ns[f"_DEF_{n}"] = tuple(f.default)
        default = f"_list(_DEF_{n})"
    elif t.array == "fixed":
        default = f"[{filler}] * {t.size}" if filler else f"[_C_{n}() for _ in _range({t.size})]"
    else:
        default = "[]"
    return f"self.{n} = {default} if {n} is _U else _to_list({n}, _cv_{n}, {', '.join(map(str, arg))})"


def build_message_class(spec: MessageSpec, class_of: Callable[[str], type]) -> type:
    """Generate, compile and return the class for ``spec``.

    Args:
        spec: The parsed message.
        class_of: Returns the (already built or built on demand) class of a nested type name.

    Returns:
        A class with ``__slots__``, keyword-only ``__init__`` taking ROS defaults, constants as class
        attributes, ``_type``, ``__eq__``, ``__repr__`` and ``get_fields_and_field_types()``.
    """
    pkg, kind, name = spec.name.split("/")
    names = tuple(f.name for f in spec.fields)
    ns: dict = {
        "_U": _UNSET, "_T": spec.name, "_np": np, "_nd": np.ndarray, "_aeq": _arrays_equal, "_rebuild": _rebuild,
        "_to_float": _checks.to_float, "_to_int": _checks.to_int, "_to_bool": _checks.to_bool,
        "_to_str": _checks.to_str, "_to_nested": _checks.to_nested, "_to_array": _checks.to_array,
        "_to_bytes": _checks.to_bytes, "_to_list": _checks.to_list, "_unknown": _checks.unknown_fields,
        "_FIELDS": names, "_ty": type, "_len": len, "_list": list, "_float": float, "_int": int,
        "_bool": bool, "_str": str, "_bytes": bytes, "_range": range,
    }
    params = ", *" + "".join(f", {n}=_U" for n in names) if names else ""
    lines = [f"def __init__(self{params}, **_extra):", "    if _extra: _unknown(_T, _extra, _FIELDS)"]
    lines += [f"    {_field_init(f, ns, class_of)}" for f in spec.fields]
    lines.append("    return None")
    compare = ["type(other) is type(self)"] + [
        f"_aeq(self.{f.name}, other.{f.name})" if value_kind(f.type) == "ndarray"
        else f"self.{f.name} == other.{f.name}"
        for f in spec.fields
    ]
    lines += [
        "def __eq__(self, other):",
        "    if not isinstance(other, type(self)): return NotImplemented",
        f"    return {' and '.join(compare)}",
        "def __reduce__(self):",
        f"    return (_rebuild, (_T, ({''.join(f'self.{n}, ' for n in names)})))",
    ]
    exec(compile("\n".join(lines), f"<ros message {spec.name}>", "exec"), ns)  # noqa: S102

    pyname = f"{pkg}.{kind}.{name}"

    def __repr__(self) -> str:  # noqa: N807
        return f"{pyname}({', '.join(f'{n}={getattr(self, n)!r}' for n in names)})"

    field_types = {f.name: rclpy_type_string(f.type) for f in spec.fields}

    def get_fields_and_field_types(cls) -> dict[str, str]:
        """Field names mapped to rclpy-style type strings, in definition order."""
        return dict(field_types)

    attrs = {
        "__slots__": names, "__init__": ns["__init__"], "__eq__": ns["__eq__"], "__hash__": None,
        "__reduce__": ns["__reduce__"], "__repr__": __repr__, "__module__": f"multiros.ros.interfaces.{pkg}.{kind}",
        "__doc__": f"ROS 2 message ``{spec.name}`` (generated).",
        "_type": spec.name, "_fields": names, "_spec": spec,
        "get_fields_and_field_types": classmethod(get_fields_and_field_types),
    }
    attrs.update({c.name: c.value for c in spec.constants})
    return type(name, (), attrs)
