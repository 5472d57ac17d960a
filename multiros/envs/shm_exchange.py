"""The shared-memory exchange of a vector env whose envs step in worker processes.

The parent process and its K workers share one block of memory (``multiprocessing.shared_memory``)
that holds, as numpy arrays with N rows, the actions, the observations (every key of a Box or
Dict-of-Box space), the rewards, the terminations and the truncations. A vector step writes the
actions there and wakes each worker with a few bytes on its pipe; the worker steps its rows and
answers on the pipe with the step's info dict only. Nothing of the hot path is pickled: an info
of numeric arrays (a step's usual ``{"is_success": ..., "_is_success": ...}``) travels as its arrays'
bytes once both sides know its keys, dtypes and shapes (:class:`InfoCodec`), any other info pickled.

:class:`SharedArrays` lays the arrays out and attaches them on both sides;
:func:`merge_infos` joins the K workers' vector info dicts into the info of all N envs, as
Gymnasium's ``VectorEnv._add_info`` builds it env by env.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from multiprocessing import resource_tracker, shared_memory
from typing import Any

import numpy as np
from gymnasium import spaces

__all__ = ["ArraySpec", "InfoCodec", "PLAIN_INFO", "SharedArrays", "shareable", "layout_for", "merge_infos"]

_ALIGN = 64  # each array starts on its own cache line
#: First byte of a step's answer that holds an info's array bytes (a pickle starts with 0x80)
PLAIN_INFO = b"\x00"


@dataclass(frozen=True)
class ArraySpec:
    """One array of the block: its name, shape (N rows first), dtype and byte offset."""

    name: str
    shape: tuple[int, ...]
    dtype: str
    offset: int

    @property
    def nbytes(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64)) * np.dtype(self.dtype).itemsize


def shareable(space: spaces.Space) -> bool:
    """Whether observations of ``space`` go through shared memory: a Box, or a Dict of Boxes."""
    if isinstance(space, spaces.Box):
        return True
    return isinstance(space, spaces.Dict) and all(isinstance(s, spaces.Box) for s in space.spaces.values())


def layout_for(num_envs: int, observation_space: spaces.Space, action_space: spaces.Box) -> list[ArraySpec]:
    """The arrays of a vector env of ``num_envs`` envs: ``obs`` (or ``obs/<key>``), ``act``, ``rew``,
    ``term``, ``trunc``, packed in one block.

    Raises:
        ValueError: a space that does not go through shared memory (see :func:`shareable`).
    """
    if not shareable(observation_space) or not isinstance(action_space, spaces.Box):
        raise ValueError(f"worker processes exchange Box or Dict-of-Box observations and Box actions through shared "
                         f"memory; got {observation_space} and {action_space}: use workers=0 (in-process)")
    wanted: list[tuple[str, Any, Any]] = []
    if isinstance(observation_space, spaces.Box):
        wanted.append(("obs", observation_space.shape, observation_space.dtype))
    elif isinstance(observation_space, spaces.Dict):
        for key, sub in observation_space.spaces.items():
            wanted.append((f"obs/{key}", sub.shape, sub.dtype))
    wanted += [("act", action_space.shape, action_space.dtype), ("rew", (), np.float64), ("term", (), np.bool_),
               ("trunc", (), np.bool_)]
    out, offset = [], 0
    for name, shape, dtype in wanted:
        spec = ArraySpec(name, (num_envs, *shape), np.dtype(dtype).str, offset)
        out.append(spec)
        offset += -(-spec.nbytes // _ALIGN) * _ALIGN
    return out


class SharedArrays:
    """The arrays of a :func:`layout_for` layout over one shared-memory block.

    ``SharedArrays.create(layout)`` makes the block (the parent, which alone unlinks it);
    ``SharedArrays.attach(name, layout)`` maps it in a worker. ``arrays[name]`` are numpy views.
    """

    def __init__(self, shm: shared_memory.SharedMemory, layout: Sequence[ArraySpec], owner: bool) -> None:
        self.shm, self.layout, self.owner = shm, list(layout), owner
        self.arrays: dict[str, np.ndarray] = {
            spec.name: np.ndarray(spec.shape, dtype=np.dtype(spec.dtype), buffer=shm.buf, offset=spec.offset)
            for spec in self.layout}

    @classmethod
    def create(cls, layout: Sequence[ArraySpec]) -> SharedArrays:
        size = max((spec.offset + spec.nbytes for spec in layout), default=0)
        shm = shared_memory.SharedMemory(create=True, size=max(size, 1))
        return cls(shm, layout, owner=True)

    @classmethod
    def attach(cls, name: str, layout: Sequence[ArraySpec]) -> SharedArrays:
        """Map the block ``name`` in a worker, without tracking it there: the parent owns it.

        Python < 3.13 registers every block it maps with a resource tracker, which in a worker (not
        a ``multiprocessing`` child) would be a tracker process of its own, unlinking the parent's
        block when the worker exits; 3.13 says ``track=False``.
        """
        if sys.version_info >= (3, 13):
            return cls(shared_memory.SharedMemory(name=name, track=False), layout, owner=False)  # type: ignore[call-arg]
        register = resource_tracker.register
        resource_tracker.register = lambda *args, **kwargs: None  # type: ignore[assignment]
        try:  # a worker maps the block once, on its only thread, before it serves requests
            shm = shared_memory.SharedMemory(name=name)
        finally:
            resource_tracker.register = register  # type: ignore[assignment]
        return cls(shm, layout, owner=False)

    @property
    def name(self) -> str:
        return self.shm.name

    def observations(self, rows: slice = slice(None)) -> Any:
        """The observation arrays (rows ``rows``): one array for a Box space, a dict for a Dict space."""
        obs = {name[4:]: arr[rows] for name, arr in self.arrays.items() if name.startswith("obs/")}
        return obs if obs else self.arrays["obs"][rows]

    def close(self) -> None:
        """Drop the views and unmap the block; the owner also unlinks it."""
        self.arrays = {}
        try:
            self.shm.close()
        except BufferError:  # a caller still holds a view (copy=False observations): unmapped at exit
            pass
        if self.owner:
            try:
                self.shm.unlink()
            except FileNotFoundError:
                pass


InfoLayout = tuple[tuple[str, np.dtype, tuple[int, ...]], ...]


class InfoCodec:
    """A step's info dict as raw bytes, on one side of one worker's pipe.

    Pickling ``{"is_success": array, "_is_success": mask}`` and reading it back costs about 13 us per
    vector step, on the path every step waits for. Both sides keep the layout (keys, dtypes, shapes)
    of the last step info that went pickled (:meth:`learn`) and count the layouts learnt; while a
    step's info has that layout the worker sends an 8-byte header (``PLAIN_INFO``, the count modulo
    256) and the arrays' bytes, each at an offset aligned for its dtype (:meth:`pack`), which the
    parent reads back into fresh, aligned, writable arrays (:meth:`unpack`). Any other info (nested
    ``final_info``, objects, a new key) goes pickled and the layout follows it. A message of another
    layout than the parent's (the two sides out of step) is refused, not read under wrong keys.
    """

    HEADER = 8  # PLAIN_INFO, the layout's count, padding: the fields start 8-byte aligned

    def __init__(self) -> None:
        self.layout: InfoLayout | None = None
        self._learnt = 0  # layouts learnt, the second byte of a message
        self._fields: list[tuple[str, np.dtype, int, int, tuple[int, ...]]] = []  # key, dtype, count, offset, shape
        self._pads: list[bytes] = []  # the zeros before each field
        self._size = 0  # the bytes of a message of the layout

    @staticmethod
    def layout_of(info: Mapping[str, Any]) -> InfoLayout | None:
        """``info``'s layout, or ``None`` when a value is not a bool or numeric numpy array."""
        out = []
        for key, value in info.items():
            if type(value) is not np.ndarray or value.dtype.kind not in "biufc" or type(key) is not str:
                return None
            out.append((key, value.dtype, value.shape))
        return tuple(out)

    def learn(self, info: Mapping[str, Any]) -> None:
        """``info`` went pickled: its layout is the one both sides know from now on."""
        self.layout = self.layout_of(info)
        self._learnt = (self._learnt + 1) % 256
        self._fields, self._pads, offset = [], [], self.HEADER
        for key, dtype, shape in self.layout or ():
            start = -(-offset // dtype.alignment) * dtype.alignment
            count = int(np.prod(shape, dtype=np.int64))
            self._pads.append(bytes(start - offset))
            self._fields.append((key, dtype, count, start, shape))
            offset = start + count * dtype.itemsize
        self._size = offset

    def _header(self) -> bytes:
        return PLAIN_INFO + bytes([self._learnt]) + bytes(self.HEADER - 2)

    def pack(self, info: Mapping[str, Any]) -> bytes | None:
        """The message for ``info`` when it has the known layout, else ``None`` (send it pickled)."""
        if self.layout is None or self.layout_of(info) != self.layout:
            return None
        parts = [self._header()]
        for pad, value in zip(self._pads, info.values()):
            parts += (pad, value.tobytes())
        return b"".join(parts)

    def unpack(self, data: bytes) -> dict[str, Any]:
        """The info of a ``PLAIN_INFO`` message, in writable arrays of its own.

        Raises:
            ValueError: no layout known, a message of another layout, or bytes that do not fill it.
        """
        if self.layout is None:
            raise ValueError("a step info came as raw bytes before any came pickled")
        if data[1:2] != bytes([self._learnt]) or len(data) != self._size:
            raise ValueError(f"a step info of {len(data)} bytes, layout {data[1:2].hex() or 'none'}, where this "
                             f"side's layout {self._learnt} ({self.layout}) makes {self._size}")
        buf = bytearray(data)
        return {key: np.frombuffer(buf, dtype, count, offset).reshape(shape)
                for key, dtype, count, offset, shape in self._fields}


def merge_infos(parts: Sequence[tuple[int, Mapping[str, Any]]], num_envs: int) -> dict[str, Any]:
    """The vector info of ``num_envs`` envs from the infos of workers, each ``(first row, info)``.

    Every value of a vector info is an array with one row per env of its worker, or a dict of such
    (``final_info``); a key one worker lacks gets the fill ``_add_info`` gives (zeros, ``None``,
    masks ``False``) in that worker's rows.
    """
    alike = _merge_alike(parts, num_envs)
    if alike is not None:
        return alike
    sizes = [(start, _rows(info)) for start, info in parts]
    return _merge([(start, n, info) for (start, info), (_, n) in zip(parts, sizes)], num_envs)


def _merge_alike(parts: Sequence[tuple[int, Mapping[str, Any]]], num_envs: int) -> dict[str, Any] | None:
    """The usual step's merge, quickly (what :func:`_merge` gives for it): every worker's info has the
    same keys, each a numpy array of one dtype whose rows add up to ``num_envs``; else ``None``."""
    if len(parts) < 2:
        return None
    keys = tuple(parts[0][1])
    if not keys or any(tuple(info) != keys for _, info in parts):
        return None
    ordered = sorted(parts, key=lambda part: part[0])
    out: dict[str, Any] = {}
    for key in keys:
        values = [info[key] for _, info in ordered]
        dtype = values[0].dtype if type(values[0]) is np.ndarray else None
        if dtype is None or any(type(v) is not np.ndarray or v.dtype != dtype or v.ndim == 0 for v in values) \
                or sum(len(v) for v in values) != num_envs:
            return None
        out[key] = np.concatenate(values)
    return out


def _rows(info: Mapping[str, Any]) -> int:
    for value in info.values():
        if isinstance(value, Mapping):
            n = _rows(value)
            if n >= 0:
                return n
        else:
            return len(value)
    return -1


def _merge(parts: Sequence[tuple[int, int, Mapping[str, Any]]], num_envs: int) -> dict[str, Any]:
    present = [p for p in parts if p[2]]
    if len(present) == 1 and present[0][1] == num_envs:
        return dict(present[0][2])  # one worker holds every row
    keys: dict[str, None] = {}
    for _, _, info in present:
        keys.update(dict.fromkeys(info))
    out: dict[str, Any] = {}
    for key in keys:
        values = [(start, n, info[key]) for start, n, info in present if key in info]
        if any(isinstance(v, Mapping) for _, _, v in values):
            out[key] = _merge([(start, n, v if isinstance(v, Mapping) else {}) for start, n, v in values], num_envs)
            continue
        first = np.asarray(values[0][2])
        if len(values) == len(parts) and all(np.asarray(v).dtype == first.dtype for _, _, v in values) \
                and sum(n for _, n, _ in values) == num_envs:
            out[key] = np.concatenate([np.asarray(v) for _, _, v in sorted(values, key=lambda t: t[0])])
            continue
        merged = np.full(num_envs, None, dtype=object) if first.dtype == object else np.zeros(num_envs, first.dtype)
        for start, n, v in values:
            merged[start:start + n] = v
        out[key] = merged
    return out
