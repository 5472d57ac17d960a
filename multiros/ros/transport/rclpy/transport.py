"""``rclpy``: uniros nodes in the ROS 2 graph of the user's own rclpy, on whatever middleware it loads.

Each uniros node gets an rclpy node of the same name and namespace; each publisher, subscription,
service and client an rclpy entity on it, so ``ros2 node list``, ``ros2 topic echo``, rviz2 and
``ros2 service call`` see them on the default middleware (Fast DDS on Humble/Jazzy). Actions need
nothing more: ours are built from services and topics with rcl_action's names and types.

One rclpy context per uniros context, one receive thread waiting on all its entities at once
(``loop.py``; rclpy's executors cost time per entity on every wake-up, which a node with dozens of
services pays on every call). That thread stays short: a message is decoded and queued for the
subscription's executor, a response completes a future, a service request is queued in the lane
of the client that sent it (``lanes.py``): worker threads run each client's requests in order and
different clients' side by side, so a long request of one client (seconds of stepping) holds up
neither the receive thread nor another client, whose request gets its turn as over Zenoh. A
callback that defers its answer (a ``Future``, as an action's ``get_result``) frees its worker at
once: the reply is sent when the future completes, from the thread that completes it.

Services and clients keep every request and response until taken (``KEEP_ALL``), whatever depth
their profile names: rclpy's default (``KEEP_LAST`` 10) dropped all but 10-21 of 200 parallel
calls of one client. History is not part of DDS's request/offer matching, so any peer's profile
still matches.

Message conversion: uniros classes and the installed ones encode to the same CDR bytes when
their type hashes agree (``types.py`` checks that), so conversion goes through CDR bytes, not
through fields:

* topics never build an rclpy message: ``publish`` hands our CDR to ``publish_raw`` and
  subscriptions are ``raw=True`` (measured for a 6-joint JointState: our serializer 5.9 us
  against 12.2 us to copy it into an rclpy message field by field, before rclpy converts that
  message to C again to publish it);
* services: rclpy gives and takes message objects (it has no raw service API), and converting a
  large one holds the GIL for as long as it takes (a 10,000-parameter request: 170 ms to take, 63 ms
  more to serialize). ``raw_service.py`` takes requests and sends responses as CDR bytes through rcl
  and rmw themselves (ctypes, the GIL released), so a request's size is known before any decoding
  (``Service.bound_requests``: the parameter services refuse one over 256 KiB without decoding it).
  Where that cannot be set up, requests cross as rclpy messages, ``rclpy.serialization`` CDR and our
  codec. Clients still send and take rclpy messages: our requests, our size.

Topics within one context go through rclpy too (it delivers to subscriptions of its own process),
not through the context's registry: rclpy cannot drop a process's own publications, so routing
both ways would deliver twice. Service calls within one context stay direct calls.
"""

from __future__ import annotations

import ctypes
import heapq
import itertools
import logging
import os
import sys
import threading
import time
from collections.abc import Hashable
from typing import TYPE_CHECKING, Any

from multiros.ros import native_memory
from multiros.ros.exceptions import ServiceCallError, ServiceTimeoutError, TransportError
from multiros.ros.graph import CLIENT, NODE, PUBLISHER, SERVICE, SUBSCRIPTION, Endpoint
from multiros.ros.logging import LogThrottle
from multiros.ros.qos import DurabilityPolicy, HistoryPolicy, QoSProfile
from multiros.ros.task import Future
from multiros.ros.transport.base import Transport
from multiros.ros.transport.rclpy import loop as wire_loop
from multiros.ros.transport.rclpy.lanes import ServiceLanes
from multiros.ros.transport.rclpy.loader import import_rclpy
from multiros.ros.transport.rclpy.raw_service import raw_service_io
from multiros.ros.transport.rclpy.types import PRIVATE_PACKAGES, InstalledTypes, MissingInterfacePackageError

if TYPE_CHECKING:
    from multiros.ros.client import Client
    from multiros.ros.context import Context
    from multiros.ros.node import Node
    from multiros.ros.publisher import Publisher
    from multiros.ros.service import Service
    from multiros.ros.subscription import Subscription

__all__ = ["RclpyTransport"]

_log = logging.getLogger(__name__)
_SERVER_CHECK_SEC = 0.25  # how often a pending call checks that its server is still in the graph
_TAKE_PER_WAKE = 64  # most messages/requests/responses taken from one entity per wake-up


class RclpyTransport(Transport):
    """The rclpy transport of one context."""

    name = "rclpy"
    delivers_local_topics = True  # the context's registry leaves topic delivery to rclpy
    serves_parameters = True  # `ros2 param` reaches uniros nodes (multiros.ros.parameter_services)
    poll_sec = 0.02  # rclpy tells nobody about graph changes: waits re-check this often

    def __init__(self, context: Context) -> None:
        super().__init__(context)
        self.types = InstalledTypes()
        self._rclpy: Any = None
        self._ser: Any = None
        self._rctx: Any = None
        self.loop: wire_loop.WireLoop | None = None
        self._lock = threading.Lock()
        self._handles: set[Any] = set()
        self._closed = False
        self._skipped_private: set[str] = set()
        self.deadlines = _Deadlines()
        self.lanes = ServiceLanes()

    # -- lifecycle ---------------------------------------------------------------------------
    def open(self) -> None:
        rclpy = import_rclpy()
        from rclpy.signals import SignalHandlerOptions

        self._rclpy = rclpy
        self._ser = rclpy.serialization
        self._rctx = rclpy.Context()
        # Only the context's --ros-args reach rcl (enclave, log levels; remaps and parameters uniros
        # applies itself, so nodes ignore rcl's global ones), never this process's sys.argv. No
        # signal handlers: the program's own Ctrl-C handling stays in charge.
        args = ["uniros", *self.context.ros_argv]
        try:
            _with_environment(self.context.env, lambda: rclpy.init(
                args=args, context=self._rctx, domain_id=self.context.domain_id,
                signal_handler_options=SignalHandlerOptions.NO))
        except Exception as exc:  # noqa: BLE001 - rclpy raises its own RCLError
            raise TransportError(f"rclpy could not start a ROS context on domain {self.context.domain_id}: "
                                 f"{one_line(exc)}") from exc
        try:
            self.loop = wire_loop.WireLoop(self._rctx)
            self.loop.start()
            self.deadlines.start(self)
        except BaseException:
            self.close()
            raise

    def reach(self) -> str:
        rmw = os.environ.get("RMW_IMPLEMENTATION", "").strip()
        if not rmw and self._rclpy is not None:
            try:
                from rclpy.utilities import get_rmw_implementation_identifier

                rmw = str(get_rmw_implementation_identifier())
            except Exception:  # noqa: BLE001 - a description only
                rmw = ""
        return f"ROS 2 middleware {rmw or 'of rclpy (its default)'} (RMW_IMPLEMENTATION)"

    def node_options(self) -> dict[str, Any]:
        """rclpy node options: nothing of rclpy's own that would need spinning (no parameter or
        type description services, no rosout); command-line arguments are never read."""
        from rclpy.parameter import Parameter

        return {"use_global_arguments": False, "start_parameter_services": False, "enable_rosout": False,
                "parameter_overrides": [Parameter("start_type_description_service", Parameter.Type.BOOL, False)]}

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            handles = list(self._handles)
            self._handles.clear()
        self.deadlines.stop()
        self.lanes.stop()
        for h in handles:
            try:
                h.close()
            except Exception:  # noqa: BLE001 - closing must finish
                _log.debug("closing %r failed", h, exc_info=True)
        if self.loop is not None:
            self.loop.stop()
        if self._rctx is not None:
            try:
                self._rclpy.try_shutdown(context=self._rctx)
            except Exception:  # noqa: BLE001
                pass

    def _track(self, handle: Any) -> Any:
        with self._lock:
            if self._closed:
                raise TransportError("the rclpy transport of this context is closed")
            self._handles.add(handle)
        return handle

    def _untrack(self, handle: Any) -> None:
        with self._lock:
            self._handles.discard(handle)

    def qos(self, profile: QoSProfile, *, keep_all: bool = False) -> Any:
        """rclpy's profile of ``profile``; ``keep_all``: history KEEP_ALL whatever it names (services)."""
        q = self._rclpy.qos
        history = HistoryPolicy.KEEP_ALL if keep_all else profile.history
        return q.QoSProfile(history=q.HistoryPolicy(int(history)), depth=int(profile.depth),
                            reliability=q.ReliabilityPolicy(int(profile.reliability)),
                            durability=q.DurabilityPolicy(int(profile.durability)))

    # -- graph -------------------------------------------------------------------------------
    def _graph(self) -> Any:
        """An rclpy node of this context to ask about the graph (every node of a context sees the
        same graph), or None while it has none: no hidden node of its own in everybody's graph."""
        with self._lock:
            for handle in self._handles:
                if isinstance(handle, _NodeHandle) and not handle._closed:
                    return handle.rnode
        return None

    def endpoints(self) -> list[Endpoint]:
        for _ in range(3):  # the node asked may be destroyed meanwhile: ask another
            g = self._graph()
            if g is None:
                return []
            try:
                return self._endpoints(g)
            except Exception:  # noqa: BLE001 - InvalidHandle of a node destroyed meanwhile
                continue
        return []

    def _endpoints(self, g: Any) -> list[Endpoint]:
        out: list[Endpoint] = []
        nodes = list(g.get_node_names_and_namespaces())
        out.extend(Endpoint(NODE, n, ns) for n, ns in nodes)
        for topic, _types in g.get_topic_names_and_types():
            for kind, infos in ((PUBLISHER, g.get_publishers_info_by_topic(topic)),
                                (SUBSCRIPTION, g.get_subscriptions_info_by_topic(topic))):
                out.extend(Endpoint(kind, i.node_name, i.node_namespace, topic, i.topic_type, origin="rclpy")
                           for i in infos)
        for n, ns in nodes:
            for kind, query in ((SERVICE, g.get_service_names_and_types_by_node),
                                (CLIENT, g.get_client_names_and_types_by_node)):
                try:
                    entries = query(n, ns)
                except Exception:  # noqa: BLE001 - the node left meanwhile
                    continue
                out.extend(Endpoint(kind, n, ns, name, t, origin="rclpy") for name, types in entries for t in types)
        return out

    def count(self, kind: str, name: str) -> int:
        for _ in range(3):
            g = self._graph()
            if g is None:
                return 0
            try:
                return self._count(g, kind, name)
            except Exception:  # noqa: BLE001 - InvalidHandle of a node destroyed meanwhile
                continue
        return 0

    def _count(self, g: Any, kind: str, name: str) -> int:
        if kind == PUBLISHER:
            return g.count_publishers(name)
        if kind == SUBSCRIPTION:
            return g.count_subscribers(name)
        if kind == SERVICE:
            return g.count_services(name)
        if kind == CLIENT:
            return g.count_clients(name)
        return super().count(kind, name)

    # -- entities ----------------------------------------------------------------------------
    def _rnode(self, node: Node) -> Any:
        rnode = getattr(node, "_rclpy_node", None)
        if rnode is None:
            raise TransportError(f"node '{node.get_fully_qualified_name()}' has no rclpy node (destroyed?)")
        return rnode

    def add_node(self, node: Node) -> _NodeHandle:
        return self._track(_NodeHandle(self, node))

    def _resolve(self, cls: Any, what: str, *, offer: bool) -> Any | None:
        if not isinstance(getattr(cls, "_type", None), str) or getattr(cls, "_registry", None) is None:
            raise TransportError(f"{what}: {cls!r} is not an interface type of multiros.ros.interfaces "
                                 "(get_message('pkg/msg/Name')); the rclpy transport needs one")
        try:
            return self.types.resolve(cls, what, offer=offer)
        except MissingInterfacePackageError as exc:
            if offer and exc.package in PRIVATE_PACKAGES:
                # A ROS install never has uniros' own interfaces: serve the standard ones, say once
                # which are left out and how to add them.
                if exc.package not in self._skipped_private:
                    self._skipped_private.add(exc.package)
                    _log.warning("%s; until then this process offers no %s interface over rclpy (%s is left out)",
                                 exc, exc.package, what)
                return None
            raise

    def add_publisher(self, pub: Publisher) -> _PublisherHandle | None:
        rcls = self._resolve(pub.msg_type, f"publisher on '{pub.topic_name}'", offer=True)
        return None if rcls is None else self._track(_PublisherHandle(self, pub, rcls))

    def add_subscription(self, sub: Subscription) -> _SubscriptionHandle:
        rcls = self._resolve(sub.msg_type, f"subscription on '{sub.topic_name}'", offer=False)
        return self._track(_SubscriptionHandle(self, sub, rcls))

    def add_service(self, srv: Service) -> _ServiceHandle | None:
        rcls = self._resolve(srv.srv_type, f"service '{srv.srv_name}'", offer=True)
        return None if rcls is None else self._track(_ServiceHandle(self, srv, rcls))

    def add_client(self, cli: Client) -> _ClientHandle:
        rcls = self._resolve(cli.srv_type, f"client of '{cli.srv_name}'", offer=False)
        return self._track(_ClientHandle(self, cli, rcls))

    # -- conversion (CDR both sides; see the module docstring) --------------------------------
    def to_rclpy(self, msg: Any, rcls: Any) -> Any:
        from multiros.ros.interfaces import serialize_message

        return self._ser.deserialize_message(serialize_message(msg), rcls)

    def from_rclpy(self, rmsg: Any, cls: Any) -> Any:
        from multiros.ros.interfaces import deserialize_message

        return deserialize_message(self._ser.serialize_message(rmsg), cls, trailing="ignore")


_RCL_ENVIRONMENT = ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "ROS_LOCALHOST_ONLY")
_environment_lock = threading.Lock()


def _with_environment(env: dict[str, str], fn: Any) -> Any:
    """``fn()`` with the discovery settings rcl reads at init taken from ``env`` (the context's, which
    may differ from this process's: a private graph's), this process's put back after."""
    with _environment_lock:
        saved = {k: os.environ.get(k) for k in _RCL_ENVIRONMENT}
        try:
            for key in _RCL_ENVIRONMENT:
                _set_env(key, env.get(key))
            return fn()
        finally:
            for key, value in saved.items():
                _set_env(key, value)


def _set_env(key: str, value: str | None) -> None:
    if value is None:
        os.environ.pop(key, None)
    else:
        os.environ[key] = value


def one_line(exc: BaseException) -> str:
    """rcl's message on one line: its first line (rcl appends ``, at <file>:<line>`` and the error
    stack on further lines), whitespace squeezed."""
    text = str(exc).strip() or type(exc).__name__
    first = text.splitlines()[0]
    return " ".join(first.split(", at ")[0].split())


class _NodeHandle:
    def __init__(self, transport: RclpyTransport, node: Node) -> None:
        self.transport = transport
        self._node = node
        rclpy = transport._rclpy
        try:
            self.rnode = rclpy.create_node(node.get_name(), namespace=node.get_namespace(), context=transport._rctx,
                                           **transport.node_options())
        except Exception as exc:  # noqa: BLE001 - rclpy's name checks and RCLError
            raise TransportError(f"rclpy could not create node '{node.get_fully_qualified_name()}': "
                                 f"{one_line(exc)}") from exc
        node._rclpy_node = self.rnode
        self._closed = False

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.transport._untrack(self)
        try:
            self.rnode.destroy_node()
        except Exception:  # noqa: BLE001
            pass
        self._node._rclpy_node = None


class _Entity:
    """Base of entity handles: ``close()`` destroys the rclpy entity once."""

    def __init__(self, transport: RclpyTransport, node: Node) -> None:
        self.transport = transport
        self.rnode = transport._rnode(node)
        self._closed = False

    def _destroy(self) -> None:
        pass

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.transport._untrack(self)
        try:
            self._destroy()
        except Exception:  # noqa: BLE001 - the node may be gone already
            pass


class _PublisherHandle(_Entity):
    def __init__(self, transport: RclpyTransport, pub: Publisher, rcls: Any) -> None:
        super().__init__(transport, pub.node)
        self._pub = self.rnode.create_publisher(rcls, pub.topic_name, transport.qos(pub.qos_profile))
        self._count = self._pub.get_subscription_count
        # A transient-local publisher keeps what it published for late joiners: always publish.
        self._always = pub.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
        from multiros.ros.interfaces import serialize_message

        self._serialize = serialize_message

    def publish(self, msg: Any) -> None:
        if self._closed or not (self._always or self._count()):
            return
        self._pub.publish(self._serialize(msg))  # bytes: rclpy's publish_raw

    def _destroy(self) -> None:
        self.rnode.destroy_publisher(self._pub)


class _SubscriptionHandle(_Entity):
    def __init__(self, transport: RclpyTransport, sub: Subscription, rcls: Any) -> None:
        super().__init__(transport, sub.node)
        from multiros.ros.interfaces import deserialize_message

        self._sub_entity = sub
        self._msg_type = sub.msg_type
        self._deserialize = deserialize_message
        self._rcls = rcls
        self._sub = self.rnode.create_subscription(rcls, sub.topic_name, _never_called,
                                                   transport.qos(sub.qos_profile), raw=True)
        transport.loop.add(wire_loop.SUBSCRIPTION, self._sub, self._on_ready)

    def _on_ready(self) -> None:
        take = self._sub.handle.take_message
        for _ in range(_TAKE_PER_WAKE):
            taken = take(self._rcls, True)
            if taken is None:
                return
            self._on_message(taken[0])

    def _on_message(self, data: bytes) -> None:
        try:
            msg = self._deserialize(data, self._msg_type, trailing="any_padding")
        except Exception as exc:  # noqa: BLE001 - anything from the wire may be garbage
            _log.warning("dropped a malformed message on '%s': %s: %s", self._sub_entity.topic_name,
                         type(exc).__name__, exc)
            return
        self._sub_entity._enqueue(msg)

    def _destroy(self) -> None:
        self.transport.loop.remove(wire_loop.SUBSCRIPTION, self._sub)
        self.rnode.destroy_subscription(self._sub)


class _ServiceHandle(_Entity):
    """A service: requests taken as CDR bytes (``raw_service.py``) where that can be set up, else as
    rclpy messages; either way queued in their client's lane and served on a worker."""

    def __init__(self, transport: RclpyTransport, srv: Service, rcls: Any) -> None:
        super().__init__(transport, srv.node)
        from multiros.ros.interfaces import deserialize_message, serialize_message

        self._srv_entity = srv
        self._rcls = rcls
        self._request_type = srv.srv_type.Request
        self._decode = deserialize_message
        self._encode = serialize_message
        self._srv = self.rnode.create_service(rcls, srv.srv_name, _never_called,
                                              qos_profile=transport.qos(srv.qos_profile, keep_all=True))
        self._raw = raw_service_io(self._srv, rcls)
        self._what = f"a request of service '{srv.srv_name}'"
        self._oversize = LogThrottle()
        on_ready = self._on_ready if self._raw is not None else self._on_ready_rclpy
        transport.loop.add(wire_loop.SERVICE, self._srv, on_ready)

    def _on_ready(self) -> None:
        """Take the waiting requests as bytes (the receive thread: the handle is entered); a request over
        the service's bound is queued as its refusal, never decoded."""
        assert self._raw is not None
        take, lanes, srv = self._raw.take, self.transport.lanes, self._srv_entity
        for _ in range(_TAKE_PER_WAKE):
            request = take()
            if request is None:
                return
            why = srv.over_bound(request.data)
            if why is not None:
                size, rid = len(request.data), request.request_id
                lanes.submit(request.client, lambda w=why, n=size, r=rid: self._refuse(w, n, r), self._what)
            else:
                lanes.submit(request.client, lambda r=request: self._take_raw(r.data, r.request_id), self._what)

    def _on_ready_rclpy(self) -> None:
        take = self._srv.handle.service_take_request
        request_type = self._rcls.Request
        for _ in range(_TAKE_PER_WAKE):
            request, header = take(request_type)
            if header is None:
                return
            # The lane: the client (its request writer's GUID), whose requests stay in order.
            lane = client_of(header.request_id)
            self.transport.lanes.submit(lane, lambda r=request, h=header, c=lane: self._take(r, h, c), self._what)

    def _refuse(self, why: str, size: int, request_id: Any) -> None:
        srv = self._srv_entity
        try:
            response = srv._refused(why)
        except Exception as exc:  # noqa: BLE001 - a refusal that failed: nothing to send
            _log.warning("%s (no reply sent)", exc)
            return
        finally:
            if size >= native_memory.LARGE_BYTES:  # its buffers are freed: given back once such requests stop
                native_memory.release_soon()
        if response is None:
            self._oversize.log(_log, logging.WARNING, "service '%s': dropped %s", srv.srv_name, why)
            return
        self._reply(response, request_id)

    def _take_raw(self, data: bytes, request_id: Any) -> None:
        try:
            try:
                req = self._decode(data, self._request_type, trailing="ignore")
            except Exception as exc:  # noqa: BLE001 - garbage from the wire must not kill the node
                _log.warning("service '%s': dropped a malformed request: %s: %s", self._srv_entity.srv_name,
                             type(exc).__name__, exc)
                return
            self._serve(req, request_id, bytes(bytearray(request_id.writer_guid)))
        finally:
            if len(data) >= native_memory.LARGE_BYTES:  # its buffers are freed: given back once such requests stop
                native_memory.release_soon()

    def _take(self, request: Any, header: Any, lane: Hashable = None) -> None:
        try:
            req = self.transport.from_rclpy(request, self._request_type)
        except Exception as exc:  # noqa: BLE001 - garbage from the wire must not kill the node
            _log.warning("service '%s': dropped a malformed request: %s: %s", self._srv_entity.srv_name,
                         type(exc).__name__, exc)
            return
        self._serve(req, header, lane)

    def _serve(self, req: Any, header: Any, lane: Hashable) -> None:
        try:
            # The writer GUID names the caller for accounting only (current_caller); unknown: None.
            caller = "dds:" + lane.hex() if isinstance(lane, bytes) else None
            response = self._srv_entity._call(req, caller)
        except Exception as exc:  # noqa: BLE001 - DDS services have no error reply: log, send nothing
            _log.warning("%s (no reply sent: a ROS 2 service over DDS cannot answer with an error)", exc)
            return
        if isinstance(response, Future):
            response.add_done_callback(lambda done: self._finish(done, header))
            return
        self._reply(response, header)

    def _finish(self, done: Future, header: Any) -> None:
        exc = done.exception()
        if done.cancelled() or exc is not None:
            _log.warning("service '%s': the deferred answer failed (%s); no reply sent", self._srv_entity.srv_name,
                         exc or "cancelled")
            return
        self._reply(done.result(), header)

    def _reply(self, response: Any, header: Any) -> None:
        """Send ``response`` to the request of ``header`` (rclpy's header, or the raw request id)."""
        if self._closed:
            return
        name = self._srv_entity.srv_name
        try:
            out = (self._encode(response) if self._raw is not None
                   else self.transport.to_rclpy(response, self._rcls.Response))
        except Exception as exc:  # noqa: BLE001
            _log.warning("service '%s': could not encode the response: %s: %s", name, type(exc).__name__, exc)
            return
        try:
            if self._raw is not None:
                self._raw.send(out, header)
            else:
                self._srv.send_response(out, header)
        except Exception as exc:  # noqa: BLE001 - the client went away, or the transport closed
            _log.debug("service '%s': could not send the reply: %s", name, exc)

    def _destroy(self) -> None:
        self.transport.loop.remove(wire_loop.SERVICE, self._srv)
        self.rnode.destroy_service(self._srv)


_WORD = ctypes.sizeof(ctypes.c_void_p)
_unknown_clients = itertools.count()
_guid_readable: list[bool] = []  # [] untried, [True]/[False] once the first request told


def client_of(request_id: Any) -> Hashable:
    """The GUID of the client that sent a request (16 bytes), else a key of its own per request.

    rclpy (Humble to Kilted) exposes only the ``sequence_number`` of ``rmw_request_id_t``, not its
    ``writer_guid``. The binding is a pybind11 object (checked) whose first slot after the Python header
    points at the C struct (``int8_t writer_guid[16]; int64_t sequence_number``); the GUID is read
    from there only once the struct's ``sequence_number`` was found equal to the binding's, which
    checks the layout. Where it does not hold, every request is a lane of its own: still served
    off the receive thread in turns, without the per-client order.
    """
    if _guid_readable == [False] or type(type(request_id)).__name__ != "pybind11_type":
        return ("request", next(_unknown_clients))  # not the binding described above: never read its memory
    try:
        address = ctypes.c_void_p.from_address(id(request_id) + 2 * _WORD).value
        raw = ctypes.string_at(address, 24) if address else b""
        ok = len(raw) == 24 and int.from_bytes(raw[16:], sys.byteorder, signed=True) == request_id.sequence_number
    except Exception:  # noqa: BLE001 - any surprise means: not readable
        ok = False
    if not _guid_readable:
        _guid_readable.append(ok)
        if not ok:
            _log.info("rclpy's request ids do not show their client here: requests are served in turns "
                      "without per-client order")
    return raw[:16] if ok and _guid_readable == [True] else ("request", next(_unknown_clients))


def _never_called(*_args: Any) -> Any:  # pragma: no cover - no rclpy executor spins our nodes
    raise RuntimeError("a uniros entity reached rclpy's own dispatch")


class _ClientHandle(_Entity):
    def __init__(self, transport: RclpyTransport, cli: Client, rcls: Any) -> None:
        super().__init__(transport, cli.node)
        self._cli_entity = cli
        self._rcls = rcls
        self._response_type = cli.srv_type.Response
        self._cli = self.rnode.create_client(rcls, cli.srv_name,
                                             qos_profile=transport.qos(cli.qos_profile, keep_all=True))
        self._pending: dict[int, Future] = {}
        self._pending_lock = threading.Lock()
        transport.loop.add(wire_loop.CLIENT, self._cli, self._on_ready)

    def _on_ready(self) -> None:
        take = self._cli.handle.take_response
        response_type = self._rcls.Response
        for _ in range(_TAKE_PER_WAKE):
            header, response = take(response_type)
            if header is None:
                return
            with self._pending_lock:
                future = self._pending.pop(header.request_id.sequence_number, None)
            if future is None or future.done():
                continue  # given up on (timed out) meanwhile
            try:
                future.set_result(self.transport.from_rclpy(response, self._response_type))
            except Exception as exc:  # noqa: BLE001 - a malformed reply
                future.set_exception(ServiceCallError(self._cli_entity.srv_name,
                                                      f"malformed reply: {type(exc).__name__}: {exc}"))

    def service_is_ready(self) -> bool:
        return not self._closed and self._cli.service_is_ready()

    def call_async(self, request: Any, future: Future, timeout_sec: float) -> None:
        name = self._cli_entity.srv_name
        if self._closed:
            future.set_exception(ServiceCallError(name, "the client's context was shut down"))
            return
        try:
            rreq = self.transport.to_rclpy(request, self._rcls.Request)
        except Exception as exc:  # noqa: BLE001 - a request our codec cannot encode
            future.set_exception(ServiceCallError(name, f"could not encode the request: {exc}"))
            return
        with self._pending_lock:  # before a response can be taken on the receive thread
            with self._cli.handle:
                seq = self._cli.handle.send_request(rreq)
            self._pending[seq] = future
        self.transport.deadlines.add(self, future, seq, timeout_sec)

    def forget(self, seq: Any) -> None:
        with self._pending_lock:
            self._pending.pop(seq, None)

    def call(self, request: Any, timeout_sec: float, total_timeout_sec: float) -> Any:
        future = Future()
        self.call_async(request, future, timeout_sec)
        future.wait(timeout_sec + 1.0)  # the deadline watcher completes it by then
        if not future.done():
            raise ServiceTimeoutError(self._cli_entity.srv_name, total_timeout_sec, "no reply")
        return future.result()

    def _destroy(self) -> None:
        self.transport.loop.remove(wire_loop.CLIENT, self._cli)
        self.rnode.destroy_client(self._cli)


class _Deadlines:
    """Fails pending calls whose time is up, or whose server left the graph (one thread per transport)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._heap: list[tuple[float, int, Any, Future, Any, float]] = []
        self._ids = itertools.count()
        self._stopped = False
        self._thread: threading.Thread | None = None

    def start(self, transport: RclpyTransport) -> None:
        self._thread = threading.Thread(target=self._run, name="uniros-rclpy-deadlines", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        with self._cond:
            self._stopped = True
            pending = list(self._heap)
            self._heap.clear()
            self._cond.notify_all()
        for _d, _i, handle, future, seq, _t in pending:
            handle.forget(seq)
            if not future.done():
                future.set_exception(ServiceCallError(handle._cli_entity.srv_name,
                                                      "the client's context was shut down"))

    def add(self, handle: Any, future: Future, seq: Any, timeout_sec: float) -> None:
        with self._cond:
            heapq.heappush(self._heap, (time.monotonic() + max(0.0, timeout_sec), next(self._ids), handle, future,
                                        seq, timeout_sec))
            self._cond.notify_all()

    def _run(self) -> None:
        next_server_check = time.monotonic() + _SERVER_CHECK_SEC
        while True:
            expired: list[tuple[Any, Future, Any, str]] = []
            with self._cond:
                if self._stopped:
                    return
                now = time.monotonic()
                while self._heap and (self._heap[0][3].done() or self._heap[0][0] <= now):
                    _d, _i, handle, future, seq, timeout = heapq.heappop(self._heap)
                    if not future.done():
                        expired.append((handle, future, seq, f"timeout:{timeout}"))
                if now >= next_server_check:
                    next_server_check = now + _SERVER_CHECK_SEC
                    keep = []
                    for entry in self._heap:
                        handle, future = entry[2], entry[3]
                        if future.done():
                            continue
                        if not handle.service_is_ready():
                            expired.append((handle, future, entry[4], "gone"))
                        else:
                            keep.append(entry)
                    if len(keep) != len(self._heap):
                        self._heap = keep
                        heapq.heapify(self._heap)
                wait = _SERVER_CHECK_SEC if not self._heap else min(_SERVER_CHECK_SEC, self._heap[0][0] - now)
            for handle, future, seq, why in expired:
                handle.forget(seq)
                name = handle._cli_entity.srv_name
                if why == "gone":
                    future.set_exception(ServiceCallError(
                        name, "no reply: the server left the ROS graph during the call"))
                else:
                    future.set_exception(ServiceTimeoutError(name, float(why.split(":", 1)[1]), "no reply"))
            with self._cond:
                if not self._stopped:
                    self._cond.wait(max(0.001, wait))
