"""``zenoh``: an rmw_zenoh_cpp-compatible transport on eclipse-zenoh.

One Zenoh session per context (as rmw_zenoh maps one context to one session), plus an
embedded router when none listens (see ``config.py``). Entities of the same context still
reach each other through the context's registry (intra-process); the session makes them
visible (liveliness tokens) and reachable (keys, queryables) on the wire.

Threads: incoming samples are decoded on Zenoh's receive thread and queued for the executor;
incoming service queries are answered on Zenoh's receive thread (no extra hop), under the
serving node's callback lock. Do not make blocking calls over this same transport from inside
a service callback that is served over the wire.
"""

from __future__ import annotations

import atexit
import itertools
import logging
import threading
import time
import weakref
from typing import TYPE_CHECKING, Any

import zenoh
import zenoh.ext as zext

from multiros.ros.exceptions import ServiceCallError, ServiceTimeoutError, TransportError
from multiros.ros.graph import CLIENT, PUBLISHER, SERVICE, SUBSCRIPTION, Endpoint
from multiros.ros.logging import LogThrottle
from multiros.ros.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from multiros.ros.task import Future
from multiros.ros.transport.base import Transport
from multiros.ros.transport.zenoh import wire
from multiros.ros.transport.zenoh.codec import Codec, InterfacesCodec
from multiros.ros.transport.zenoh.config import (
    ZenohSettings,
    router_config,
    router_listening,
    session_config,
)

if TYPE_CHECKING:
    from multiros.ros.client import Client
    from multiros.ros.context import Context
    from multiros.ros.node import Node
    from multiros.ros.publisher import Publisher
    from multiros.ros.service import Service
    from multiros.ros.subscription import Subscription

__all__ = ["ZenohTransport"]

_log = logging.getLogger(__name__)


class ZenohTransport(Transport):
    """The Zenoh transport of one context."""

    name = "zenoh"

    def __init__(self, context: Context) -> None:
        super().__init__(context)
        options = dict(context.transport_options)
        self._codec: Codec | None = options.get("codec")
        self.settings = ZenohSettings.from_options(options, context.env)
        self.domain_id = context.domain_id
        self.session: zenoh.Session | None = None
        self.router: zenoh.Session | None = None
        self.zid = ""
        self._ids = itertools.count()
        self._handles: set[Any] = set()
        self._lock = threading.Lock()
        self._graph: dict[str, Endpoint] = {}
        self._counts: dict[tuple[str, str], int] = {}  # (kind, name) -> entities in _graph
        self._graph_version = 0  # changes with _counts (graph_version)
        self._graph_lock = threading.Lock()
        self._servers: dict[str, int] = {}
        self._remote_subs: dict[str, int] = {}  # ROS subscriptions of other sessions, per topic
        self._lv_sub: Any = None
        self._closed = False

    # -- lifecycle ---------------------------------------------------------------------------
    @property
    def codec(self) -> Codec:
        if self._codec is None:
            self._codec = InterfacesCodec()
        return self._codec

    def reach(self) -> str:
        from multiros.ros.transport.zenoh.config import ROUTER_ENV

        return f"Zenoh router {self.settings.router_endpoint} ({ROUTER_ENV})"

    def open(self) -> None:
        _close_before_thread_join(self)
        s = self.settings
        try:
            if s.router == "embedded":
                self._start_router()
            elif (s.router == "auto" and s.router_check_attempts is not None
                  and not router_listening(s.router_endpoint, s.router_check_attempts)):
                try:
                    self._start_router()
                except TransportError:
                    # Another process may have started one meanwhile: use it if it is there.
                    if not router_listening(s.router_endpoint, 1):
                        raise
            try:
                self.session = zenoh.open(session_config(s))
            except Exception as exc:  # noqa: BLE001 - zenoh raises ZError
                raise TransportError(f"could not open the Zenoh session (router {s.router_endpoint}): {exc}") from exc
            self.zid = str(self.session.zid())
            if s.router != "none" and s.router_check_attempts is not None:
                self._wait_for_router()
            elif not router_listening(s.router_endpoint, 1):
                # As rmw_zenoh: go on, but peers only discover each other once a router runs.
                _log.warning("no Zenoh router at %s yet: this context will not see other processes until "
                             "one starts (rmw_zenohd, or a context with router='auto')", s.router_endpoint)
            self._lv_sub = self.session.liveliness().declare_subscriber(
                f"{wire.ADMIN_SPACE}/{self.domain_id}/**", self._on_token, history=True
            )
        except BaseException:
            self.close()
            raise

    def _start_router(self) -> None:
        try:
            self.router = zenoh.open(router_config(self.settings))
        except Exception as exc:  # noqa: BLE001
            raise TransportError(
                f"could not start an embedded Zenoh router at {self.settings.router_endpoint}: {exc} "
                "(is the port taken? pass router_endpoint=... or router='none')"
            ) from exc
        _log.info("started an embedded Zenoh router at %s", self.settings.router_endpoint)

    def _wait_for_router(self) -> None:
        deadline = time.monotonic() + self.settings.router_wait_sec
        while not self.session.info.routers_zid():
            if time.monotonic() > deadline:
                hint = ("; TLS or user/password authentication is configured: check the CA, certificates, "
                        "user and password (UNIROS_ZENOH_TLS_*, UNIROS_ZENOH_USER/PASSWORD)"
                        if self.settings.network.secured else "")
                raise TransportError(
                    f"no Zenoh router reachable at {self.settings.router_endpoint} after "
                    f"{self.settings.router_wait_sec:.1f} s: start one (rmw_zenohd) or use router='auto'{hint}"
                )
            time.sleep(0.005)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            handles = list(self._handles)
            self._handles.clear()
        for h in handles:
            try:
                h.close()
            except Exception:  # noqa: BLE001 - closing must finish
                _log.debug("closing %r failed", h, exc_info=True)
        for obj in (self._lv_sub,):
            if obj is not None:
                try:
                    obj.undeclare()
                except Exception:  # noqa: BLE001
                    pass
        for sess in (self.session, self.router):
            if sess is not None:
                try:
                    sess.close()
                except Exception:  # noqa: BLE001
                    _log.debug("closing a Zenoh session failed", exc_info=True)
        self.session = self.router = None

    def _track(self, handle: Any) -> Any:
        with self._lock:
            self._handles.add(handle)
        return handle

    def _untrack(self, handle: Any) -> None:
        with self._lock:
            self._handles.discard(handle)

    # -- graph -------------------------------------------------------------------------------
    def _on_token(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        ep = wire.parse_token(key)
        if ep is None:
            return
        with self._graph_lock:
            if sample.kind == zenoh.SampleKind.PUT:
                if key in self._graph:
                    return
                self._graph[key] = ep
                delta = 1
            else:
                if self._graph.pop(key, None) is None:
                    return
                delta = -1
            self._counts[(ep.kind, ep.name)] = self._counts.get((ep.kind, ep.name), 0) + delta
            self._graph_version += 1
            if ep.kind == SERVICE:
                self._servers[ep.name] = self._servers.get(ep.name, 0) + delta
            elif ep.kind == SUBSCRIPTION and ep.origin != self.zid:
                self._remote_subs[ep.name] = self._remote_subs.get(ep.name, 0) + delta
        self.context.notify()

    def endpoints(self) -> list[Endpoint]:
        with self._graph_lock:
            return list(self._graph.values())

    def count(self, kind: str, name: str) -> int:
        with self._graph_lock:
            return self._counts.get((kind, name), 0)

    def graph_version(self) -> int | None:
        return self._graph_version

    def has_remote_subscriber(self, topic: str) -> bool:
        """Whether a ROS subscription of another session is known on ``topic`` (from its token)."""
        return self._remote_subs.get(topic, 0) > 0

    def has_server(self, name: str) -> bool:
        return self._servers.get(name, 0) > 0

    # -- entities ----------------------------------------------------------------------------
    def _names(self, type_name: str, what: str, ros_type: Any = None) -> tuple[str, str]:
        if "/" not in type_name or type_name.count("/") != 2:
            raise TransportError(
                f"{what}: type {type_name!r} has no ROS type name; the zenoh transport needs interface "
                "types from multiros.ros.interfaces (classes with _type = 'pkg/msg/Name')"
            )
        # A codec that can hash a class hashes it with its own distribution's definitions.
        hash_of = getattr(self.codec, "type_hash_of", None)
        if hash_of is not None and ros_type is not None:
            return self.codec.dds_type_name(type_name), hash_of(ros_type)
        return self.codec.dds_type_name(type_name), self.codec.type_hash(type_name)

    def _enclave(self) -> str:
        return self.context.arguments.enclave or "/"

    def add_node(self, node: Node) -> _Token:
        nid = next(self._ids)
        node._zenoh_nid = nid
        key = wire.node_token(self.domain_id, self.zid, nid, self._enclave(), node.get_namespace(), node.get_name())
        return self._track(_Token(self, key))

    def _endpoint_key(self, node: Node, kind: str, name: str, dds: str, hsh: str, qos: QoSProfile) -> str:
        return wire.endpoint_token(
            self.domain_id, self.zid, node._zenoh_nid, next(self._ids), kind, self._enclave(),
            node.get_namespace(), node.get_name(), name, dds, hsh, qos,
        )

    def add_publisher(self, pub: Publisher) -> _PublisherHandle:
        dds, hsh = self._names(pub.type_name, f"publisher on '{pub.topic_name}'", pub.msg_type)
        token = self._endpoint_key(pub.node, PUBLISHER, pub.topic_name, dds, hsh, pub.qos_profile)
        return self._track(_PublisherHandle(self, pub, wire.topic_key(self.domain_id, pub.topic_name, dds, hsh), token))

    def add_subscription(self, sub: Subscription) -> _SubscriptionHandle:
        dds, hsh = self._names(sub.type_name, f"subscription on '{sub.topic_name}'", sub.msg_type)
        token = self._endpoint_key(sub.node, SUBSCRIPTION, sub.topic_name, dds, hsh, sub.qos_profile)
        key = wire.topic_key(self.domain_id, sub.topic_name, dds, hsh)
        return self._track(_SubscriptionHandle(self, sub, key, token))

    def add_service(self, srv: Service) -> _ServiceHandle:
        dds, hsh = self._names(srv.type_name, f"service '{srv.srv_name}'", srv.srv_type)
        token = self._endpoint_key(srv.node, SERVICE, srv.srv_name, dds, hsh, srv.qos_profile)
        return self._track(_ServiceHandle(self, srv, wire.topic_key(self.domain_id, srv.srv_name, dds, hsh), token))

    def add_client(self, cli: Client) -> _ClientHandle:
        dds, hsh = self._names(cli.type_name, f"client of '{cli.srv_name}'", cli.srv_type)
        token = self._endpoint_key(cli.node, CLIENT, cli.srv_name, dds, hsh, cli.qos_profile)
        return self._track(_ClientHandle(self, cli, wire.topic_key(self.domain_id, cli.srv_name, dds, hsh), token))


def _close_before_thread_join(transport: ZenohTransport) -> None:
    """Close ``transport`` at interpreter exit, before Python joins non-daemon threads.

    zenoh-python runs callback handlers on non-daemon Python threads that end only when the
    subscriber/queryable is undeclared, so an ``atexit`` hook would come too late (the
    interpreter would wait forever). ``threading._register_atexit`` (private but stable since
    Python 3.9; ``concurrent.futures`` relies on it) runs before that join.
    """
    ref = weakref.ref(transport)

    def close() -> None:
        t = ref()
        if t is not None:
            t.close()

    register = getattr(threading, "_register_atexit", None)
    try:
        if register is not None:
            register(close)
        else:  # pragma: no cover - future Pythons
            atexit.register(close)
    except RuntimeError:
        pass  # interpreter already shutting down


class _Token:
    """A liveliness token; base of every entity handle."""

    def __init__(self, transport: ZenohTransport, token_key: str) -> None:
        self.transport = transport
        self.token_key = token_key
        self.gid = wire.gid_for(token_key)
        self._token: Any = transport.session.liveliness().declare_token(token_key)
        self._closed = False

    def _undeclare(self) -> None:
        pass

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.transport._untrack(self)
        for obj in (self._token,):
            try:
                obj.undeclare()
            except Exception:  # noqa: BLE001 - session may already be closed
                pass
        try:
            self._undeclare()
        except Exception:  # noqa: BLE001
            pass


class _PublisherHandle(_Token):
    def __init__(self, transport: ZenohTransport, pub: Publisher, key: str, token_key: str) -> None:
        qos = pub.qos_profile
        session = transport.session
        reliable = qos.reliability == ReliabilityPolicy.RELIABLE
        congestion = (
            zenoh.CongestionControl.BLOCK
            if reliable and qos.history == HistoryPolicy.KEEP_ALL else zenoh.CongestionControl.DROP
        )
        reliability = zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT
        self._transient = qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
        if self._transient:
            # As rmw_zenoh: an advanced publisher with a cache of `depth` samples, detectable by
            # late-joining advanced subscribers, with sample-miss heartbeats when reliable.
            self._pub = zext.declare_advanced_publisher(
                session, key, congestion_control=congestion, reliability=reliability,
                cache=zext.CacheConfig(max_samples=qos.depth if qos.history == HistoryPolicy.KEEP_LAST else 1000),
                publisher_detection=True,
                sample_miss_detection=zext.MissDetectionConfig(sporadic_heartbeat=0.5) if reliable else None,
            )
        else:
            # Only other sessions: this context's own subscriptions get messages from the registry.
            self._pub = session.declare_publisher(key, congestion_control=congestion, reliability=reliability,
                                                  allowed_destination=zenoh.Locality.REMOTE)
        self._lazy = transport.settings.lazy_publish and not self._transient
        self._matching = True
        self._listener: Any = None
        if self._lazy:
            # Zenoh tells the publisher whether any subscriber matches its key (a ROS node or a
            # plain Zenoh tool alike); serialize and put only then, or while a remote ROS
            # subscription's token is known: matching news can trail the graph, and a node that
            # saw get_subscription_count() == 1 must not lose the next message. Listener first,
            # then the current status, so no change is missed in between.
            self._listener = self._pub.declare_matching_listener(_direct_callback(self._on_matching))
            self._matching = bool(self._pub.matching_status.matching)
        super().__init__(transport, token_key)
        self.key = key
        self.topic = pub.topic_name
        self._seq = itertools.count(1)
        self._fmt = transport.settings.attachment_format
        self._codec = transport.codec

    def _on_matching(self, status: Any) -> None:
        self._matching = bool(status.matching)

    def publish(self, msg: Any) -> None:
        if self._closed or not (self._matching or self.transport.has_remote_subscriber(self.topic)):
            return
        payload = self._codec.serialize(msg)
        att = wire.encode_attachment(next(self._seq), time.time_ns(), self.gid, self._fmt)
        self._pub.put(payload, attachment=att)

    def _undeclare(self) -> None:
        if self._listener is not None:
            self._listener.undeclare()
        self._pub.undeclare()


def _direct_callback(fn: Any) -> Any:
    """Run ``fn`` on Zenoh's own thread (no extra Python thread per listener) where supported."""
    try:
        return zenoh.handlers.Callback(fn, indirect=False)
    except TypeError:  # pragma: no cover - zenoh-python without the (unstable) indirect flag
        return fn


class _SubscriptionHandle(_Token):
    def __init__(self, transport: ZenohTransport, sub: Subscription, key: str, token_key: str) -> None:
        self._sub_entity = sub
        self._msg_type = sub.msg_type
        self._codec = transport.codec
        self.key = key
        self._session = transport.session
        self._inline = False
        self._drops = LogThrottle()  # a flood of bad samples logs a few lines, then one per interval
        self._sub = self._declare(self._on_sample)
        super().__init__(transport, token_key)

    def _declare(self, handler: Any) -> Any:
        # Samples from this session are delivered in-process by the registry already.
        qos = self._sub_entity.qos_profile
        if qos.durability == DurabilityPolicy.TRANSIENT_LOCAL:
            reliable = qos.reliability == ReliabilityPolicy.RELIABLE
            return zext.declare_advanced_subscriber(
                self._session, self.key, handler, allowed_origin=zenoh.Locality.REMOTE,
                history=zext.HistoryConfig(detect_late_publishers=True, max_samples=qos.depth),
                recovery=zext.RecoveryConfig(heartbeat=True) if reliable else None,
                subscriber_detection=True,
            )
        return self._session.declare_subscriber(self.key, handler, allowed_origin=zenoh.Locality.REMOTE)

    def deliver_inline(self) -> None:
        """Decode and hand over samples on Zenoh's receive thread instead of a Python thread of
        this subscriber's own: a sample is then delivered before any query that follows it on the
        same link reaches its queryable (whose thread could otherwise answer first)."""
        if self._inline:
            return
        old, self._sub = self._sub, self._declare(_direct_callback(self._on_sample))
        self._inline = True
        old.undeclare()

    def _on_sample(self, sample: zenoh.Sample) -> None:
        att = sample.attachment
        if att is None:
            self._drops.log(_log, logging.WARNING, "dropped a sample on '%s': no attachment (rmw_zenoh requires one)",
                            self.key)
            return
        try:
            source = wire.decode_attachment(att.to_bytes()).source_gid
            msg = self._codec.deserialize(sample.payload.to_bytes(), self._msg_type)
        except Exception as exc:  # noqa: BLE001 - anything from the wire may be garbage
            self._drops.log(_log, logging.WARNING, "dropped a malformed sample on '%s': %s: %s", self.key,
                            type(exc).__name__, str(exc))
            return
        self._sub_entity._enqueue(msg, source)

    def _undeclare(self) -> None:
        self._sub.undeclare()


class _ServiceHandle(_Token):
    def __init__(self, transport: ZenohTransport, srv: Service, key: str, token_key: str) -> None:
        self._srv = srv
        self._codec = transport.codec
        self._request_type = srv.srv_type.Request
        self._fmt = transport.settings.attachment_format
        self.key = key
        self._drops = LogThrottle()
        # complete=True: rmw_zenoh clients query with target ALL_COMPLETE.
        self._queryable = transport.session.declare_queryable(key, self._on_query, complete=True)
        super().__init__(transport, token_key)

    def _on_query(self, query: zenoh.Query) -> None:
        # Dropping the query sends Zenoh's final reply; do it explicitly, because a traceback
        # kept alive elsewhere (a log handler holding the exception) would otherwise keep the
        # query, and the caller, waiting until its timeout. A deferred answer drops it later.
        deferred = False
        try:
            deferred = self._answer(query)
        finally:
            if not deferred:
                _drop(query)

    def _answer(self, query: zenoh.Query) -> bool:
        """Answer ``query``; ``True`` when the answer was deferred (the query stays open)."""
        name = self._srv.srv_name
        try:
            att_bytes = query.attachment
            if att_bytes is None:
                raise wire.AttachmentError("request has no attachment")
            att = wire.decode_attachment(att_bytes.to_bytes())
            payload = query.payload
            if payload is None:
                raise ValueError("request has no payload")
            request = self._codec.deserialize(payload.to_bytes(), self._request_type)
        except Exception as exc:  # noqa: BLE001 - garbage from the wire must not kill the node
            self._drops.log(_log, logging.WARNING, "service '%s': dropped a malformed request: %s: %s", name,
                            type(exc).__name__, str(exc))
            _reply_err(query, f"service '{name}': malformed request: {exc}")
            return False
        try:
            # The GID names the caller for accounting only: any peer can put any GID there.
            response = self._srv._call(request, "zenoh:" + att.source_gid.hex())
        except Exception as exc:  # noqa: BLE001
            _log.warning("%s", str(exc))
            _reply_err(query, getattr(exc, "detail", f"{type(exc).__name__}: {exc}"))
            return False
        if isinstance(response, Future):
            def finish(done: Future) -> None:
                try:
                    exc = done.exception()
                    if done.cancelled():
                        _reply_err(query, f"service '{name}': the server gave up on the request")
                    elif exc is not None:
                        _reply_err(query, getattr(exc, "detail", f"{type(exc).__name__}: {exc}"))
                    else:
                        self._reply(query, done.result(), att)
                finally:
                    _drop(query)

            response.add_done_callback(finish)
            return True
        self._reply(query, response, att)
        return False

    def _reply(self, query: zenoh.Query, response: Any, att: wire.Attachment) -> None:
        name = self._srv.srv_name
        try:
            data = self._codec.serialize(response)
        except Exception as exc:  # noqa: BLE001
            _log.warning("service '%s': could not serialize the response: %s", name, exc)
            _reply_err(query, f"service '{name}': bad response: {type(exc).__name__}: {exc}")
            return
        reply_att = wire.encode_attachment(att.sequence_number, time.time_ns(), att.source_gid, self._fmt)
        try:
            query.reply(self.key, data, attachment=reply_att)
        except Exception as exc:  # noqa: BLE001 - e.g. the client went away
            _log.warning("service '%s': could not send the reply: %s", name, str(exc))

    def _undeclare(self) -> None:
        self._queryable.undeclare()


def _drop(query: zenoh.Query) -> None:
    try:
        query.drop()
    except Exception:  # noqa: BLE001
        pass


def _reply_err(query: zenoh.Query, text: str) -> None:
    try:
        query.reply_err(text.encode())
    except Exception:  # noqa: BLE001
        pass


class _ClientHandle(_Token):
    def __init__(self, transport: ZenohTransport, cli: Client, key: str, token_key: str) -> None:
        super().__init__(transport, token_key)
        self._cli = cli
        self._codec = transport.codec
        self._response_type = cli.srv_type.Response
        self._fmt = transport.settings.attachment_format
        self._seq = itertools.count(1)
        self.key = key

    def service_is_ready(self) -> bool:
        return self.transport.has_server(self._cli.srv_name)

    def _get(self, request: Any, timeout_sec: float, seq: int, handler: Any = None) -> Any:
        session = self.transport.session
        if session is None or self._closed:
            raise ServiceCallError(self._cli.srv_name, "the client's context was shut down")
        att = wire.encode_attachment(seq, time.time_ns(), self.gid, self._fmt)
        replies = session.get(
            self.key, handler, payload=self._codec.serialize(request), attachment=att,
            target=zenoh.QueryTarget.ALL_COMPLETE, consolidation=zenoh.ConsolidationMode.NONE,
            timeout=max(timeout_sec, 0.001),
        )
        return replies

    def _decode(self, reply: zenoh.Reply, seq: int, timeout_sec: float | None = None) -> Any:
        name = self._cli.srv_name
        if reply.ok is None:
            err = reply.err
            text = err.payload.to_bytes().decode(errors="replace") if err is not None else "unknown error"
            if text == "Timeout":
                # Zenoh's own query timeout, not an answer from the server.
                raise ServiceTimeoutError(name, timeout_sec or 0.0, "no reply")
            raise ServiceCallError(name, f"the server replied with an error ({text})")
        sample = reply.ok
        if sample.attachment is not None:
            att = wire.decode_attachment(sample.attachment.to_bytes())
            if att.sequence_number != seq:
                raise ServiceCallError(name, f"reply for request {att.sequence_number}, expected {seq}")
        return self._codec.deserialize(sample.payload.to_bytes(), self._response_type)

    def call(self, request: Any, timeout_sec: float, total_timeout_sec: float) -> Any:
        start = time.monotonic()
        seq = next(self._seq)
        replies = self._get(request, timeout_sec, seq)
        for reply in replies:
            try:
                return self._decode(reply, seq, total_timeout_sec)
            except (ServiceCallError, ServiceTimeoutError):
                raise
            except Exception as exc:  # noqa: BLE001 - a malformed reply
                raise ServiceCallError(self._cli.srv_name, f"malformed reply: {type(exc).__name__}: {exc}") from exc
        if time.monotonic() - start >= timeout_sec * 0.95:
            raise ServiceTimeoutError(self._cli.srv_name, total_timeout_sec, "no reply")
        raise ServiceCallError(self._cli.srv_name, "no reply: the server went away or dropped the request")

    def call_async(self, request: Any, future: Future, timeout_sec: float) -> None:
        name = self._cli.srv_name
        seq = next(self._seq)

        def on_reply(reply: zenoh.Reply) -> None:
            if future.done():
                return
            try:
                future.set_result(self._decode(reply, seq, timeout_sec))
            except (ServiceCallError, ServiceTimeoutError) as exc:
                future.set_exception(exc)
            except Exception as exc:  # noqa: BLE001
                future.set_exception(ServiceCallError(name, f"malformed reply: {exc}"))

        start = time.monotonic()

        def on_done() -> None:
            if future.done():
                return
            if time.monotonic() - start < timeout_sec * 0.95:  # the query ended early: nobody answered
                future.set_exception(ServiceCallError(name, "no reply: the server went away or dropped the request"))
            else:
                future.set_exception(ServiceTimeoutError(name, timeout_sec, "no reply"))

        try:
            self._get(request, timeout_sec, seq, zenoh.handlers.Callback(on_reply, on_done))
        except ServiceCallError as exc:
            future.set_exception(exc)
