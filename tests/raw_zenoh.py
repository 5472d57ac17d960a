"""A plain eclipse-zenoh peer session, with no uniros code: the foreign side of wire tests.

Importable from every test directory: ``tests/`` is on ``sys.path`` because it holds the root
``conftest.py`` (pytest's default import mode puts such folders first on the path).
"""

from __future__ import annotations

import json

import zenoh


def open_peer_session(endpoint: str) -> zenoh.Session:
    """A Zenoh session in peer mode, as rmw_zenoh opens one: connected to the router at ``endpoint``,
    listening on a free loopback port, multicast scouting off (so it meets nothing else)."""
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)
