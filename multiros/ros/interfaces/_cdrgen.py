"""Generate per-type CDR (XCDR1) serializers and deserializers as Python source using ``struct``.

Why generated code and not rosbags' codec: rosbags is a test-only dependency here, and a generated
codec that knows the Python representation of our classes (see :mod:`._classgen`) is faster. The
generator tracks alignment statically where it can (``pos`` modulo 8 is known after fixed-size
fields), so runs of primitives, nested fixed-size structs included, become one ``struct`` call with
the padding folded in as ``x`` bytes. Alignment counts from the end of the 4-byte encapsulation
header; empty sequences get no element padding (as Fast CDR and Cyclone do); an empty struct is one
``uint8`` (rosidl's ``structure_needs_at_least_one_member``).

Each type gets a *top* function (message at the start of the body, alignment known) and an *elem*
function (message inside a sequence, alignment unknown). Serializers append to a ``bytearray``
that starts with the header; deserializers read ``bytes`` from absolute position ``pos``.
"""

from __future__ import annotations

import struct
import sys
from collections.abc import Callable

import numpy as np

from . import _checks
from ._classgen import NP_DTYPES, value_kind
from .errors import DeserializationError, FieldError, FieldValueError
from .idl import PRIMITIVES, FieldType, MessageSpec

__all__ = ["build_deserializer", "build_serializer"]

_CODES = {"bool": "?", "byte": "B", "char": "B", "uint8": "B", "int8": "b", "int16": "h", "uint16": "H",
          "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q", "float32": "f", "float64": "d"}
_PADS = tuple(b"\x00" * i for i in range(8))
_LITTLE_HOST = sys.byteorder == "little"
_SER_ERRORS = (struct.error, TypeError, ValueError, AttributeError, OverflowError)
_DES_ERRORS = (struct.error, ValueError, UnicodeDecodeError, IndexError, OverflowError, TypeError, MemoryError)


def _des_reason(exc: Exception) -> str:
    if isinstance(exc, struct.error):
        return f"truncated ({exc})"
    if isinstance(exc, UnicodeDecodeError):
        return f"string is not valid UTF-8 ({exc.reason} at byte {exc.start})"
    return f"{type(exc).__name__}: {exc}"


class _Gen:
    """Accumulates lines of one function, tracking alignment and pending primitive runs."""

    def __init__(self, serialize: bool, endian: str, lookup: Callable[[str], tuple[MessageSpec, type]],
                 fns: Callable[[str], Callable]) -> None:
        self.ser, self.endian, self.lookup, self.fns = serialize, endian, lookup, fns
        self.lines: list[str] = []
        self.ns: dict = {
            "_np": np, "_nd": np.ndarray, "_fb": np.frombuffer, "_PADS": _PADS, "_DErr": DeserializationError,
            "_FE": FieldError, "_FVE": FieldValueError, "_checks": _checks, "_find": _checks.find_pack_error,
            "_perr": _checks.pack_error, "_why": _des_reason, "_SERR": _SER_ERRORS, "_DERR": _DES_ERRORS,
            "_U32p": struct.Struct(endian + "I").pack, "_U32u": struct.Struct(endian + "I").unpack_from,
        }
        self.depth = 1
        self.count = 0
        self.mod, self.modulus = 0, 8
        self.run: list[tuple[str, str, str | None]] = []  # (code incl. pad, expr/target, path, item code)
        self.run_fmt = ""
        self.run_items: list[tuple[str, str | None]] = []
        self.run_size = 0
        self.runs: list[tuple] = []

    # -- plumbing -------------------------------------------------------------------------------
    def new(self, prefix: str) -> str:
        self.count += 1
        return f"_{prefix}{self.count}"

    def const(self, value: object, prefix: str = "K") -> str:
        name = self.new(prefix)
        self.ns[name] = value
        return name

    def emit(self, line: str) -> None:
        self.lines.append("    " * self.depth + line)

    def unknown(self) -> None:
        self.mod, self.modulus = 0, 1

    def prim(self, code: str, size: int, expr: str, path: str, item_code: str | None) -> None:
        """Queue one primitive; consecutive ones become one struct call."""
        if self.modulus >= size:
            pad = -self.mod % size
        else:
            self.flush()
            self.dynamic_pad(size)
            pad = 0
        self.run_fmt += "x" * pad + code
        self.run.append(expr)
        self.run_items.append((path, item_code))
        self.run_size += pad + size
        self.mod = (self.mod + pad + size) % self.modulus

    def dynamic_pad(self, align: int) -> None:
        if align > 1:
            if self.ser:
                self.emit(f"buf += _PADS[(4 - len(buf)) % {align}]")
            else:
                self.emit(f"pos += (4 - pos) % {align}")
        self.mod, self.modulus = 0, align

    def align(self, align: int) -> None:
        """Flush, then pad to ``align`` (a constant when the position is known modulo ``align``)."""
        self.flush()
        if self.modulus >= align:
            pad = -self.mod % align
            if pad:
                self.emit(f"buf += {_PADS[pad]!r}" if self.ser else f"pos += {pad}")
            self.mod = (self.mod + pad) % self.modulus
        else:
            self.dynamic_pad(align)

    def flush(self) -> None:
        if not self.run:
            return
        fmt = struct.Struct(self.endian + self.run_fmt)
        if self.ser:
            self.runs.append(tuple(self.run_items))
            self.emit(f"fld = {len(self.runs) - 1}")
            self.emit(f"buf += {self.const(fmt.pack, 'P')}({', '.join(self.run)})")
        else:
            first, last = self.run_items[0][0], self.run_items[-1][0]
            self.emit(f"fld = {first if first == last else f'{first}..{last}'!r}")
            self.emit(f"{', '.join(self.run)}, = {self.const(fmt.unpack_from, 'S')}(buf, pos)")
            self.emit(f"pos += {fmt.size}")
        self.run, self.run_items, self.run_fmt, self.run_size = [], [], "", 0

    def after_sequence(self, elem_size: int) -> None:
        # count (u32, so pos % 4 == 0) then n elements: 0 elements keep that, n > 0 end elem-aligned.
        self.mod, self.modulus = 0, min(elem_size, 4) if elem_size else 1

    def length_checks(self, t: FieldType, n: str, path: str) -> None:
        if t.array == "fixed":
            self.emit(f"if len({n}) != {t.size}: _checks.check_length(len({n}), 'fixed', {t.size}, _T, {path!r})")
        elif t.array == "bounded":
            self.emit(f"if len({n}) > {t.size}: _checks.check_length(len({n}), 'bounded', {t.size}, _T, {path!r})")

    # -- serializer -----------------------------------------------------------------------------
    def ser_struct(self, spec: MessageSpec, obj: str, prefix: str) -> None:
        if not spec.fields:
            self.prim("B", 1, "0", prefix + "structure_needs_at_least_one_member", None)
        for f in spec.fields:
            self.ser_field(f.type, f"{obj}.{f.name}", prefix + f.name)

    def ser_string(self, src: str, bound: int, path: str, in_loop: bool) -> None:
        s = "_s" if in_loop else self.new("s")
        self.emit(f"{s} = {src}.encode()")
        if bound:
            self.emit(f"if len({s}) > {bound}: raise _FVE(_T, {path!r}, "
                      f"f'string of {{len({s})}} bytes exceeds bound {bound}')")
        if in_loop:
            self.emit(f"buf += _PADS[(4 - len(buf)) % 4]; buf += _U32p(len({s}) + 1); buf += {s}; buf.append(0)")
        else:
            self.prim("I", 4, f"len({s}) + 1", path, None)
            self.flush()
            self.emit(f"buf += {s}; buf.append(0)")
        self.unknown()

    def ser_field(self, t: FieldType, expr: str, path: str) -> None:
        kind = value_kind(t)
        if kind in ("float", "int", "bool"):
            code = _CODES[t.base]
            self.prim(code, PRIMITIVES[t.base], expr, path, code)
            return
        if kind == "nested":
            spec, cls = self.lookup(t.base)
            o, c = self.new("o"), self.const(cls, "C")
            self.emit(f"{o} = {expr}")
            self.emit(f"if type({o}) is not {c}: raise _FE(_T, {path!r}, "
                      f"f'expected {cls._type}, got {{type({o}).__name__}}')")
            self.ser_struct(spec, o, path + ".")
            return
        self.emit(f"fld = {path!r}")
        if kind == "str":
            self.ser_string(expr, t.string_bound, path, in_loop=False)
            return
        v = self.new("v")
        self.emit(f"{v} = {expr}")
        args = f"{t.array!r}, {t.size}, _T, {path!r}"
        seq = t.array != "fixed"
        if kind == "ndarray":
            dt = self.const(NP_DTYPES[t.base], "DT")
            size = PRIMITIVES[t.base]
            self.emit(f"if type({v}) is not _nd or {v}.dtype != {dt} or {v}.ndim != 1: "
                      f"{v} = _checks.to_array({v}, {dt}, {args})")
            self.length_checks(t, v, path)
            data = f"{v}.tobytes()" if _LITTLE_HOST else f"{v}.astype({dt}).tobytes()"
            if seq:
                self.prim("I", 4, f"len({v})", path, None)
                self.flush()
                if self.modulus >= size:
                    pad = f"buf += {_PADS[-self.mod % size]!r}; " if self.mod % size else ""
                else:
                    pad = f"buf += _PADS[(4 - len(buf)) % {size}]; "
                self.emit(f"if len({v}): {pad}buf += {data}")
                self.after_sequence(size)
            else:
                self.align(size)
                self.emit(f"buf += {data}")
                self.mod = (self.mod + size * t.size) % self.modulus
            return
        if kind in ("bytes", "list_bool"):
            if kind == "bytes":
                self.emit(f"if type({v}) is not bytes: {v} = _checks.to_bytes({v}, {args})")
                data = v
            else:
                cv = self.const(lambda x, p: x if type(x) is bool else _checks.to_bool(x, self.ns["_T"], p), "cv")
                self.emit(f"if type({v}) is not list or not all(type(_x) is bool for _x in {v}): "
                          f"{v} = _checks.to_list({v}, {cv}, {args})")
                data = f"bytes({v})"
            self.length_checks(t, v, path)
            if seq:
                self.prim("I", 4, f"len({v})", path, None)
            self.flush()
            self.emit(f"buf += {data}")
            if seq:
                self.unknown()
            else:
                self.mod = (self.mod + t.size) % self.modulus
            return
        # lists of strings or messages: element loop
        self.emit(f"if type({v}) is not list and not isinstance({v}, (list, tuple)): "
                  f"{v} = _checks.to_list({v}, lambda x, p: x, {args})")
        self.length_checks(t, v, path)
        if seq:
            self.prim("I", 4, f"len({v})", path, None)
        self.flush()
        if kind == "list_str":
            self.emit(f"for _x in {v}:")
            self.depth += 1
            self.ser_string("_x", t.string_bound, path, in_loop=True)
        else:
            spec, cls = self.lookup(t.base)
            c, fn = self.const(cls, "C"), self.const(self.fns(t.base), "F")
            self.emit(f"for _i, _x in enumerate({v}):")
            self.depth += 1
            self.emit(f"if type(_x) is not {c}: raise _FE(_T, f'{path}[{{_i}}]', "
                      f"f'expected {cls._type}, got {{type(_x).__name__}}')")
            self.emit(f"try: {fn}(_x, buf)")
            self.emit(f"except _FE as _e: raise type(_e)(_T, f'{path}[{{_i}}].' + _e.field, _e.reason) from None")
        self.depth -= 1
        self.unknown()

    # -- deserializer ---------------------------------------------------------------------------
    def des_struct(self, spec: MessageSpec, obj: str, prefix: str) -> None:
        if not spec.fields:
            self.prim("B", 1, "_", prefix + "structure_needs_at_least_one_member", None)
        for f in spec.fields:
            self.des_field(f.type, f"{obj}.{f.name}", prefix + f.name)

    def des_string(self, n: str, target: str, bound: int, path: str) -> None:
        if bound:
            self.emit(f"if {n} - 1 > {bound}: raise _DErr(_T, {path!r}, "
                      f"f'string of {{{n} - 1}} bytes exceeds bound {bound}')")
        self.emit(f"if {n}:")
        self.emit(f"    _e = pos + {n}")
        self.emit(f"    if _e > _L: raise _DErr(_T, {path!r}, f'string length {{{n}}} exceeds the "
                  f"{{_L - pos}} remaining bytes')")
        self.emit(f"    if buf[_e - 1]: raise _DErr(_T, {path!r}, 'string is not NUL-terminated')")
        self.emit(f"    {target} = buf[pos:_e - 1].decode(); pos = _e")
        self.emit(f"else: {target} = ''")
        self.unknown()

    def des_count(self, t: FieldType, path: str, min_elem: int) -> str:
        n = self.new("n")
        self.prim("I", 4, n, path, None)
        self.flush()
        if t.array == "bounded":
            self.emit(f"if {n} > {t.size}: raise _DErr(_T, {path!r}, "
                      f"f'sequence of {{{n}}} elements exceeds bound {t.size}')")
        self.emit(f"if {n} * {min_elem} > _L - pos: raise _DErr(_T, {path!r}, "
                  f"f'sequence of {{{n}}} elements needs more than the {{_L - pos}} remaining bytes')")
        return n

    def des_field(self, t: FieldType, target: str, path: str) -> None:
        kind = value_kind(t)
        if kind in ("float", "int", "bool"):
            self.prim(_CODES[t.base], PRIMITIVES[t.base], target, path, None)
            return
        if kind == "nested":
            spec, cls = self.lookup(t.base)
            o, c = self.new("o"), self.const(cls, "C")
            self.emit(f"{o} = {c}.__new__({c}); {target} = {o}")
            self.des_struct(spec, o, path + ".")
            return
        if kind == "str":
            n = self.new("n")
            self.prim("I", 4, n, path, None)
            self.flush()
            self.emit(f"fld = {path!r}")
            self.des_string(n, target, t.string_bound, path)
            return
        seq = t.array != "fixed"
        if kind == "ndarray":
            size = PRIMITIVES[t.base]
            wire = NP_DTYPES[t.base].newbyteorder(self.endian)
            dt = self.const(wire, "DT")
            native = NP_DTYPES[t.base] if wire == NP_DTYPES[t.base] else NP_DTYPES[t.base].newbyteorder("=")
            conv = ".copy()" if wire.isnative else f".astype({self.const(native, 'DT')})"
            if seq:
                n = self.des_count(t, path, size)
                empty = self.const(np.empty(0, NP_DTYPES[t.base]), "E")
                self.ns[empty].flags.writeable = False
                pad = (f"pos += {-self.mod % size}; " if self.mod % size else "") if self.modulus >= size else (
                    f"pos += (4 - pos) % {size}; ")
                self.emit(f"if {n}:")
                self.emit(f"    {pad}_e = pos + {n} * {size}")
                self.emit(f"    if _e > _L: raise _DErr(_T, {path!r}, f'{{{n}}} elements exceed the remaining bytes')")
                self.emit(f"    {target} = _fb(buf, {dt}, {n}, pos){conv}; pos = _e")
                self.emit(f"else: {target} = {empty}")
                self.after_sequence(size)
            else:
                self.align(size)
                self.emit(f"fld = {path!r}; _e = pos + {size * t.size}")
                self.emit(f"if _e > _L: raise _DErr(_T, {path!r}, 'truncated array')")
                self.emit(f"{target} = _fb(buf, {dt}, {t.size}, pos){conv}; pos = _e")
                self.mod = (self.mod + size * t.size) % self.modulus
            return
        if kind in ("bytes", "list_bool"):
            if seq:
                n = self.des_count(t, path, 1)
            else:
                self.flush()
                n = str(t.size)
                self.emit(f"fld = {path!r}")
                self.emit(f"if pos + {n} > _L: raise _DErr(_T, {path!r}, 'truncated array')")
            data = f"buf[pos:pos + {n}]" if kind == "bytes" else f"[_b != 0 for _b in buf[pos:pos + {n}]]"
            self.emit(f"{target} = {data}; pos += {n}")
            if seq:
                self.unknown()
            else:
                self.mod = (self.mod + t.size) % self.modulus
            return
        if seq:
            n = self.des_count(t, path, 4 if kind == "list_str" else 1)
        else:
            self.flush()
            n = str(t.size)
            self.emit(f"fld = {path!r}")
        self.emit("_l = []")
        self.emit(f"for _i in range({n}):")
        self.depth += 1
        if kind == "list_str":
            self.emit("pos += (4 - pos) % 4")
            self.emit(f"if pos + 4 > _L: raise _DErr(_T, f'{path}[{{_i}}]', 'truncated')")
            self.emit("_k, = _U32u(buf, pos); pos += 4")
            self.des_string("_k", "_x", t.string_bound, f"{path}[]")
        else:
            fn = self.const(self.fns(t.base), "F")
            self.emit(f"try: _x, pos = {fn}(buf, pos, _L)")
            self.emit(f"except _DErr as _e: raise _DErr(_T, f'{path}[{{_i}}].' + _e.field, _e.reason) from None")
        self.emit("_l.append(_x)")
        self.depth -= 1
        self.emit(f"{target} = _l")
        self.unknown()


def build_serializer(spec: MessageSpec, cls: type, top: bool,
                     lookup: Callable[[str], tuple[MessageSpec, type]], fns: Callable[[str], Callable]) -> Callable:
    """Compile a serializer for ``spec``.

    Returns:
        ``top``: ``f(msg) -> bytes`` (header included). Otherwise ``f(msg, buf)`` appending the
        struct at an unknown alignment (used for sequence elements).
    """
    g = _Gen(True, "<", lookup, fns)
    g.ns.update(_T=spec.name, _C=cls)
    if top:
        g.emit("buf = bytearray(b'\\x00\\x01\\x00\\x00')")
    else:
        g.unknown()
    g.emit("fld = ''")
    g.emit("try:")
    g.depth += 1
    g.ser_struct(spec, "m", "")
    g.flush()
    g.emit("return bytes(buf)" if top else "return None")
    g.depth -= 1
    g.ns["_RUNS"] = tuple(g.runs)
    g.lines += [
        "    except _FE: raise",
        "    except _SERR as e:",
        "        if type(fld) is int: raise _find(m, _RUNS[fld], '<', _T, e) from None",
        "        raise _perr(_T, fld, e) from None",
    ]
    head = "def _f(m):" if top else "def _f(m, buf):"
    source = head + "\n" + "\n".join(g.lines)
    exec(compile(source, f"<cdr serializer {spec.name}>", "exec"), g.ns)  # noqa: S102
    g.ns["_f"].source = source  # for debugging: print(fn.source)
    return g.ns["_f"]


def build_deserializer(spec: MessageSpec, cls: type, top: bool, endian: str,
                       lookup: Callable[[str], tuple[MessageSpec, type]], fns: Callable[[str], Callable]) -> Callable:
    """Compile a deserializer ``f(buf: bytes, pos: int, length: int) -> (msg, new_pos)`` for ``spec``.

    ``top`` assumes ``pos`` is the start of the body (alignment known); otherwise alignment is computed.
    """
    g = _Gen(False, endian, lookup, fns)
    g.ns.update(_T=spec.name, _C=cls)
    if not top:
        g.unknown()
    g.emit("fld = ''")
    g.emit("try:")
    g.depth += 1
    g.emit("m = _C.__new__(_C)")
    g.des_struct(spec, "m", "")
    g.flush()
    g.emit("return m, pos")
    g.depth -= 1
    g.lines += [
        "    except _DErr: raise",
        "    except _DERR as e: raise _DErr(_T, fld, _why(e)) from None",
    ]
    source = "def _f(buf, pos, _L):\n" + "\n".join(g.lines)
    exec(compile(source, f"<cdr deserializer {spec.name}>", "exec"), g.ns)  # noqa: S102
    g.ns["_f"].source = source  # for debugging: print(fn.source)
    return g.ns["_f"]
