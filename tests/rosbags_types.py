"""rosbags as an independent oracle: type stores built from definition text by rosbags' own parser.

Shared by the interface tests and the wire tests (importable from every test folder: ``tests/``
holds the root conftest, so it is on ``sys.path``). ``char`` is mapped to ``uint8`` as rosidl does
(rosbags keeps ``char``, which changes type hashes; see ros2_wire.md §1.7).
"""

from __future__ import annotations

import re
from typing import Any

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


def char_to_uint8(desc: Any) -> Any:
    """A rosbags field description with ``char`` replaced by ``uint8`` (recursively)."""
    if desc[0] == Nodetype.BASE and desc[1][0] == "char":
        return (Nodetype.BASE, ("uint8", desc[1][1]))
    if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return (desc[0], (char_to_uint8(desc[1][0]), desc[1][1]))
    return desc


def parts_types(full: str, text: str, suffixes: tuple[str, ...]) -> dict:
    """rosbags types of the ``---``-separated parts of a ``.srv``/``.action`` named ``pkg/kind/Name``."""
    pkg, _, base = full.split("/")
    types: dict = {}
    for part, suffix in zip(re.split(r"^---[ \t]*$", text, flags=re.M), suffixes):
        # rosbags resolves relative names only for pkg/msg/ names: parse as msg, then rename
        parsed = get_types_from_msg(part, f"{pkg}/msg/{base}{suffix}")
        types.update({k.replace(f"{pkg}/msg/{base}{suffix}", f"{full}{suffix}"): v for k, v in parsed.items()})
    return types


def service_types(srv: str, text: str) -> dict:
    """The rosbags types of service ``pkg/srv/Name``: request, response, the event and the service struct."""
    types = parts_types(srv, text, ("_Request", "_Response"))
    types[f"{srv}_Event"] = ([], [
        ("info", (Nodetype.NAME, "service_msgs/msg/ServiceEventInfo")),
        ("request", (Nodetype.SEQUENCE, ((Nodetype.NAME, f"{srv}_Request"), 1))),
        ("response", (Nodetype.SEQUENCE, ((Nodetype.NAME, f"{srv}_Response"), 1))),
    ])
    types[srv] = ([], [("request_message", (Nodetype.NAME, f"{srv}_Request")),
                       ("response_message", (Nodetype.NAME, f"{srv}_Response")),
                       ("event_message", (Nodetype.NAME, f"{srv}_Event"))])
    return types


def store_of(types: dict) -> Any:
    """A rosbags typestore holding exactly ``types`` (``char`` as ``uint8``)."""
    store = get_typestore(Stores.EMPTY)
    store.register({n: (c, [(f, char_to_uint8(d)) for f, d in fields]) for n, (c, fields) in types.items()})
    return store
