"""Test helpers: random non-default messages, and conversion to rosbags objects (the oracle)."""

from __future__ import annotations

import random

import numpy as np

from multiros.ros.interfaces import default_registry
from multiros.ros.interfaces._classgen import NP_DTYPES, value_kind
from multiros.ros.interfaces.idl import INTEGER_RANGES, FieldType

_ALPHABET = "abcXYZ019_ /-éß€"


def _scalar(rng: random.Random, t: FieldType) -> object:
    base = t.base
    if base == "float64":
        return rng.choice([rng.uniform(-1e6, 1e6), rng.random(), -0.0, 1e-300])
    if base == "float32":
        return float(np.float32(rng.uniform(-1e4, 1e4)))
    if base == "bool":
        return rng.random() < 0.5
    if base in ("string", "wstring"):
        limit = 8 if not t.string_bound else min(8, t.string_bound // 4)
        return "".join(rng.choice(_ALPHABET) for _ in range(rng.randint(0, limit)))
    lo, hi = INTEGER_RANGES[base]
    return rng.choice([lo, hi, rng.randint(lo, hi)])


def _length(rng: random.Random, t: FieldType, nested: bool) -> int:
    if t.array == "fixed":
        return t.size
    top = 2 if nested else 5
    return rng.randint(0, min(top, t.size) if t.array == "bounded" else top)


def random_message(type_name: str, rng: random.Random, depth: int = 0) -> object:
    """A message of ``type_name`` with random values in every field (sequences 0-5 long)."""
    reg = default_registry()
    spec, cls = reg.message_spec(type_name), reg.message_class(type_name)
    values = {}
    for f in spec.fields:
        t, kind = f.type, value_kind(f.type)
        if kind == "nested":
            values[f.name] = random_message(t.base, rng, depth + 1)
        elif not t.array:
            values[f.name] = _scalar(rng, t)
        else:
            n = _length(rng, t, t.is_nested or depth > 2)
            elem = t.element()
            if kind == "list_nested":
                values[f.name] = [random_message(t.base, rng, depth + 1) for _ in range(n)]
            elif kind == "bytes":
                values[f.name] = bytes(rng.randrange(256) for _ in range(n))
            elif kind == "ndarray":
                values[f.name] = np.array([_scalar(rng, elem) for _ in range(n)], dtype=NP_DTYPES[t.base])
            else:
                values[f.name] = [_scalar(rng, elem) for _ in range(n)]
    return cls(**values)


def to_rosbags(msg: object, typestore) -> object:
    """The rosbags object equal to our message ``msg`` (numpy arrays where rosbags expects them)."""
    spec = type(msg)._spec
    values = {}
    for f in spec.fields:
        v, kind = getattr(msg, f.name), value_kind(f.type)
        if kind == "nested":
            v = to_rosbags(v, typestore)
        elif kind == "list_nested":
            v = [to_rosbags(x, typestore) for x in v]
        elif kind == "bytes":
            v = np.frombuffer(v, dtype=np.uint8).copy()
        elif f.type.base == "byte" and kind == "int":
            v = v - 256 if v > 127 else v  # rosbags reads byte as int8 (ROS 1 heritage); same bits
        elif kind == "list_bool":
            v = np.array(v, dtype=bool)
        values[f.name] = v
    return typestore.types[spec.name](**values)
