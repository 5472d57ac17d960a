"""Service calls as a foreign rmw_zenoh client sends them: a plain Zenoh query with the key,
CDR payload and attachment rmw_zenoh uses (importable by the tests of this folder)."""

from __future__ import annotations

import struct
import time

import zenoh
from raw_zenoh import query_until_answered

from multiros.ros.interfaces import dds_type_name, deserialize_message, serialize_message, type_hash
from multiros.sim.distro_adapters import get_service


def raw_get_entities(session: zenoh.Session, domain: int, timeout: float = 10.0) -> list[str]:
    """``GetEntities`` as an rmw_zenoh client sends it (key, CDR payload, attachment), until answered."""
    type_name = "simulation_interfaces/srv/GetEntities"
    srv = get_service(type_name)
    key = f"{domain}/mujoco_sim/get_entities/{dds_type_name(type_name)}/{type_hash(srv)}"
    replies = query_until_answered(
        session, key, payload=serialize_message(srv.Request()), timeout=timeout, reply_timeout=1.0,
        attachment=lambda: struct.pack("<qqB", 1, time.time_ns(), 16) + bytes(range(16)))
    if not replies or replies[0].ok is None:
        raise AssertionError(f"no answer to GetEntities within {timeout} s")
    return list(deserialize_message(replies[0].ok.payload.to_bytes(), srv.Response).entities)
