"""A plain eclipse-zenoh peer session, with no uniros code: the foreign side of wire tests.

Importable from every test directory: ``tests/`` is on ``sys.path`` because it holds the root
``conftest.py`` (pytest's default import mode puts such folders first on the path).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Mapping

import zenoh


def open_peer_session(endpoint: str, *, credentials: Mapping[str, str] | None = None,
                      connect_timeout_ms: int | None = None, mode: str = "peer") -> zenoh.Session:
    """A Zenoh session in peer mode, as rmw_zenoh opens one: connected to the router at ``endpoint``,
    listening on a free loopback port, multicast scouting off (so it meets nothing else).

    Args:
        credentials: ``user``, ``password`` and optionally ``auth_dictionary`` (Zenoh's
            ``transport/auth/usrpwd``), to join a graph that requires them.
        connect_timeout_ms: fail to open (``zenoh.ZError``) unless connected within this time,
            instead of retrying in the background.
        mode: ``"client"`` routes everything through the router (no direct link to other peers,
            whose set-up a loaded machine can delay).
    """
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    config.insert_json5("scouting/multicast/enabled", "false")
    if connect_timeout_ms is not None:
        config.insert_json5("connect/timeout_ms", str(int(connect_timeout_ms)))
        config.insert_json5("connect/exit_on_failure", "true")
    if credentials:
        config.insert_json5("transport/auth/usrpwd/user", json.dumps(credentials["user"]))
        config.insert_json5("transport/auth/usrpwd/password", json.dumps(credentials["password"]))
        if credentials.get("auth_dictionary"):
            config.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(credentials["auth_dictionary"]))
    return zenoh.open(config)


def query_until_answered(session: zenoh.Session, key: str, *, payload: bytes, attachment: Callable[[], bytes],
                         timeout: float, reply_timeout: float = 2.0, poll: float = 0.05) -> list[zenoh.Reply]:
    """Query ``key`` (all complete queryables, no consolidation: as an rmw_zenoh client calls a service)
    until a reply comes back or ``timeout`` passes; returns the replies of the answered query, or ``[]``.

    A fresh session learns the node's queryables a moment after it opens (longer on a loaded machine),
    and a query sent before then is answered at once with nothing. So between tries this waits for
    Zenoh's matching status to say a queryable exists, instead of sending queries nothing can answer
    (a loop of those runs at tens of thousands a second and starves the processes it waits for); a
    query that matched but got no reply is tried again no sooner than ``poll`` seconds later.
    ``attachment`` is called for each try (a fresh sequence number and timestamp).
    """
    querier = session.declare_querier(key, target=zenoh.QueryTarget.ALL_COMPLETE,
                                      consolidation=zenoh.ConsolidationMode.NONE, timeout=reply_timeout)
    matched = threading.Event()
    listener = querier.declare_matching_listener(lambda status: matched.set() if status.matching else matched.clear())
    try:
        if querier.matching_status.matching:
            matched.set()
        deadline = time.monotonic() + timeout
        while (remaining := deadline - time.monotonic()) > 0:
            if not matched.wait(remaining):
                break
            started = time.monotonic()
            replies = list(querier.get(payload=payload, attachment=attachment()))
            if replies:
                return replies
            time.sleep(max(0.0, min(poll - (time.monotonic() - started), deadline - time.monotonic())))  # poll interval
        return []
    finally:
        listener.undeclare()
        querier.undeclare()
