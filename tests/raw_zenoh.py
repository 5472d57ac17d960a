"""A plain eclipse-zenoh peer session, with no uniros code: the foreign side of wire tests.

Importable from every test directory: ``tests/`` is on ``sys.path`` because it holds the root
``conftest.py`` (pytest's default import mode puts such folders first on the path).
"""

from __future__ import annotations

import json
from collections.abc import Mapping

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
