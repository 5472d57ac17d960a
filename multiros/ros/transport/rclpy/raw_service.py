"""A service's requests taken, and its responses sent, as CDR bytes: rcl and rmw called directly.

rclpy has no raw API for services (``raw=True`` exists for subscriptions only): its
``service_take_request`` converts every request from C into a Python message on the caller's thread,
and ``send_response`` converts the Python response back to C. Both conversions run in C holding the
GIL, and they cost what the message's size makes them cost: a ``SetParameters`` request of 10,000
parameters took 170 ms to become a Python message (then 63 ms more to become CDR again for our
decoder), every thread of the node stalled meanwhile, before a callback could even look at its size.

:class:`RawServiceIO` does without the Python message: it calls ``rcl_take_request_with_info`` into a
C message of the type (created and destroyed with the type's own C functions), ``rmw_serialize`` into
CDR bytes, and the reverse (``rmw_deserialize``, ``rcl_send_response``) for a response. The calls go
through :mod:`ctypes`, which releases the GIL around each one, so the conversions run beside the node's
other threads, and the transport sees a request's size in bytes before decoding a field of it.

The functions are those of the very libraries rclpy loaded (looked up through its own extension
module's handle), with rmw's public struct layouts (``rmw_service_info_t``, ``rmw_request_id_t``,
``rcutils_uint8_array_t``: the same from Humble to Kilted). Where anything of this cannot be set up,
:func:`raw_service_io` answers None and the transport uses rclpy's own conversions.
"""

from __future__ import annotations

import ctypes
import logging
import threading
from typing import Any

__all__ = ["RawServiceIO", "Request", "raw_service_io"]

_log = logging.getLogger(__name__)
_RET_OK = 0
_RET_SERVICE_TAKE_FAILED = 601  # RCL_RET_SERVICE_TAKE_FAILED: nothing to take


class _RequestId(ctypes.Structure):
    _fields_ = [("writer_guid", ctypes.c_int8 * 16), ("sequence_number", ctypes.c_int64)]


class _ServiceInfo(ctypes.Structure):
    _fields_ = [("source_timestamp", ctypes.c_int64), ("received_timestamp", ctypes.c_int64),
                ("request_id", _RequestId)]


class _Allocator(ctypes.Structure):
    _fields_ = [("allocate", ctypes.c_void_p), ("deallocate", ctypes.c_void_p), ("reallocate", ctypes.c_void_p),
                ("zero_allocate", ctypes.c_void_p), ("state", ctypes.c_void_p)]


class _Bytes(ctypes.Structure):  # rcutils_uint8_array_t (rmw_serialized_message_t)
    _fields_ = [("buffer", ctypes.POINTER(ctypes.c_uint8)), ("buffer_length", ctypes.c_size_t),
                ("buffer_capacity", ctypes.c_size_t), ("allocator", _Allocator)]


class Request:
    """A taken request: its CDR bytes and the id the response goes back with."""

    __slots__ = ("data", "request_id")

    def __init__(self, data: bytes, request_id: _RequestId) -> None:
        self.data = data
        self.request_id = request_id

    @property
    def client(self) -> bytes:
        """The GUID of the client's request writer (16 bytes): who sent it."""
        return bytes(bytearray(self.request_id.writer_guid))


class _Lib:
    """The C functions, bound once per process."""

    def __init__(self) -> None:
        from rclpy.impl.implementation_singleton import rclpy_implementation

        # The extension's handle: its symbols and those of the libraries it loaded (rcl, rmw, rcutils).
        lib = ctypes.CDLL(rclpy_implementation.__file__)
        vp, sz = ctypes.c_void_p, ctypes.c_size_t
        self.take = _bind(lib, "rcl_take_request_with_info", ctypes.c_int, vp, ctypes.POINTER(_ServiceInfo), vp)
        self.send = _bind(lib, "rcl_send_response", ctypes.c_int, vp, ctypes.POINTER(_RequestId), vp)
        self.serialize = _bind(lib, "rmw_serialize", ctypes.c_int, vp, vp, ctypes.POINTER(_Bytes))
        self.deserialize = _bind(lib, "rmw_deserialize", ctypes.c_int, ctypes.POINTER(_Bytes), vp, vp)
        self.bytes_init = _bind(lib, "rcutils_uint8_array_init", ctypes.c_int, ctypes.POINTER(_Bytes), sz,
                                ctypes.POINTER(_Allocator))
        self.bytes_fini = _bind(lib, "rcutils_uint8_array_fini", ctypes.c_int, ctypes.POINTER(_Bytes))
        self.reset_error = _bind(lib, "rcutils_reset_error", None)
        default_allocator = _bind(lib, "rcutils_get_default_allocator", _Allocator)
        self.allocator = default_allocator()
        capsule = ctypes.pythonapi.PyCapsule_GetPointer
        capsule.restype, capsule.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
        self.capsule = capsule


def _bind(lib: ctypes.CDLL, name: str, restype: Any, *argtypes: Any) -> Any:
    fn = getattr(lib, name)
    fn.restype, fn.argtypes = restype, list(argtypes)
    return fn


_lib: list[_Lib | None] = []
_lib_lock = threading.Lock()


def _the_lib() -> _Lib | None:
    with _lib_lock:
        if not _lib:
            try:
                _lib.append(_Lib())
            except Exception as exc:  # noqa: BLE001 - any surprise: rclpy's own conversions instead
                _log.info("rclpy transport: services convert through rclpy's Python messages (%s: %s)",
                          type(exc).__name__, exc)
                _lib.append(None)
        return _lib[0]


class _CType:
    """One message type's C side: create, destroy, type support (rosidl's capsules on rclpy's class)."""

    def __init__(self, lib: _Lib, rcls: Any) -> None:
        self.create = ctypes.CFUNCTYPE(ctypes.c_void_p)(lib.capsule(rcls._CREATE_ROS_MESSAGE, None))
        self.destroy = ctypes.CFUNCTYPE(None, ctypes.c_void_p)(lib.capsule(rcls._DESTROY_ROS_MESSAGE, None))
        self.support = lib.capsule(rcls._TYPE_SUPPORT, None)
        if not (self.support and ctypes.cast(self.create, ctypes.c_void_p).value
                and ctypes.cast(self.destroy, ctypes.c_void_p).value):
            raise RuntimeError(f"{rcls.__name__} has no C type support loaded")

    def new(self) -> int:
        msg = self.create()
        if not msg:
            raise MemoryError("could not allocate a C message")
        return int(msg)


class RawServiceIO:
    """Takes the requests of one rclpy service as CDR bytes and sends responses given as CDR bytes.

    ``take`` runs where rclpy's take would (the handle entered: the receive loop holds it); ``send``
    enters the handle itself, so a service destroyed meanwhile is an rclpy ``InvalidHandle`` error.
    """

    def __init__(self, lib: _Lib, srv: Any, rcls: Any) -> None:
        self._lib = lib
        self._srv = srv
        self._request = _CType(lib, rcls.Request)
        self._response = _CType(lib, rcls.Response)

    def take(self) -> Request | None:
        """The next request, or None when there is none. Raises ``RuntimeError`` when rcl fails."""
        lib = self._lib
        info = _ServiceInfo()
        msg = self._request.new()
        try:
            ret = lib.take(self._srv.handle.pointer, ctypes.byref(info), msg)
            if ret == _RET_SERVICE_TAKE_FAILED:
                lib.reset_error()
                return None
            if ret != _RET_OK:
                lib.reset_error()
                raise RuntimeError(f"rcl_take_request failed ({ret})")
            data = _Bytes()
            if lib.bytes_init(ctypes.byref(data), 0, ctypes.byref(lib.allocator)) != _RET_OK:
                lib.reset_error()
                raise MemoryError("could not allocate a serialized message")
            try:
                if lib.serialize(msg, self._request.support, ctypes.byref(data)) != _RET_OK:
                    lib.reset_error()
                    raise RuntimeError("rmw_serialize failed on a taken request")
                raw = ctypes.string_at(data.buffer, data.buffer_length)
            finally:
                lib.bytes_fini(ctypes.byref(data))
        finally:
            self._request.destroy(msg)
        return Request(raw, info.request_id)

    def send(self, data: bytes, request_id: _RequestId) -> None:
        """Send the response ``data`` (CDR) to the request ``request_id``.

        Raises:
            ValueError: ``data`` is not a response of the service's type.
            RuntimeError: rcl could not send it (the client went away, the service was destroyed).
        """
        lib = self._lib
        buffer = ctypes.create_string_buffer(data, len(data))
        cdr = _Bytes(ctypes.cast(buffer, ctypes.POINTER(ctypes.c_uint8)), len(data), len(data), lib.allocator)
        msg = self._response.new()
        try:
            if lib.deserialize(ctypes.byref(cdr), self._response.support, msg) != _RET_OK:
                lib.reset_error()
                raise ValueError("rmw_deserialize refused the encoded response")
            with self._srv.handle:  # not destroyed while rcl uses it
                ret = lib.send(self._srv.handle.pointer, ctypes.byref(request_id), msg)
            if ret != _RET_OK:
                lib.reset_error()
                raise RuntimeError(f"rcl_send_response failed ({ret})")
        finally:
            self._response.destroy(msg)


def raw_service_io(srv: Any, rcls: Any) -> RawServiceIO | None:
    """The raw I/O of rclpy service ``srv`` of type ``rcls``, or None where it cannot be set up."""
    lib = _the_lib()
    if lib is None:
        return None
    try:
        return RawServiceIO(lib, srv, rcls)
    except Exception as exc:  # noqa: BLE001 - rclpy's own conversions instead
        _log.info("rclpy transport: service of %s converts through rclpy's Python messages (%s: %s)",
                  getattr(rcls, "__name__", rcls), type(exc).__name__, exc)
        return None
