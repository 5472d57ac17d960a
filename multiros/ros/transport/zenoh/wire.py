"""rmw_zenoh_cpp wire conventions: data keys, liveliness tokens, the QoS string, attachments.

Formats (see ``docs``/``shared/reference/ros2_wire.md`` §2):

* data key: ``<domain>/<name without leading/trailing '/'>/<dds type>/<RIHS01 hash>``
* node token: ``@ros2_lv/<domain>/<zid>/<nid>/<nid>/NN/<enclave>/<namespace>/<node>``
* endpoint token: ``.../<nid>/<eid>/<MP|MS|SS|SC>/<enclave>/<namespace>/<node>/<name>/<dds type>/<hash>/<qos>``
  with every ``/`` inside a field replaced by ``%``.
* attachment (rmw_zenoh >= 0.2.4): ``int64 seq | int64 timestamp ns | 0x10 | 16-byte GID`` (33 bytes);
  the older (<= 0.2.3) format prefixes each value with its key string.

Hand-written because it is a few lines of ``struct``; ``zenoh.ext.z_serialize`` produces the
same bytes but costs more per message.
"""

from __future__ import annotations

import hashlib
import struct
from typing import NamedTuple

from multiros.ros.graph import NODE, Endpoint
from multiros.ros.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

__all__ = [
    "ADMIN_SPACE",
    "ATTACHMENT_V2",
    "ATTACHMENT_LEGACY",
    "Attachment",
    "AttachmentError",
    "topic_key",
    "mangle",
    "unmangle",
    "qos_to_str",
    "qos_from_str",
    "node_token",
    "endpoint_token",
    "parse_token",
    "gid_for",
    "encode_attachment",
    "decode_attachment",
    "ros_type_from_dds",
]

ADMIN_SPACE = "@ros2_lv"
ATTACHMENT_V2 = "v2"  # rmw_zenoh >= 0.2.4 (Jazzy), Kilted, Rolling
ATTACHMENT_LEGACY = "legacy"  # rmw_zenoh <= 0.2.3

# rmw_zenoh's reference profile: a component equal to it is left empty in the QoS string.
_ZENOH_DEFAULT_DEPTH = 42
_INFINITE_SEC, _INFINITE_NSEC = 9223372036, 854775807


def mangle(name: str) -> str:
    """Replace ``/`` with ``%`` (``/`` -> ``%``, ``/ns/a`` -> ``%ns%a``)."""
    return name.replace("/", "%")


def unmangle(name: str) -> str:
    return name.replace("%", "/")


def topic_key(domain_id: int, name: str, dds_type: str, type_hash: str) -> str:
    """The data key expression of a topic or service."""
    return f"{domain_id}/{name.strip('/')}/{dds_type}/{type_hash}"


def qos_to_str(qos: QoSProfile) -> str:
    """The QoS component of an endpoint token (``::,10:,:,:,,`` for the ROS default profile)."""
    rel = "" if qos.reliability == ReliabilityPolicy.RELIABLE else str(int(qos.reliability))
    dur = "" if qos.durability == DurabilityPolicy.VOLATILE else str(int(qos.durability))
    hist = "" if qos.history == HistoryPolicy.KEEP_LAST else str(int(qos.history))
    depth = "" if qos.depth == _ZENOH_DEFAULT_DEPTH else str(qos.depth)
    live = "" if qos.liveliness == LivelinessPolicy.AUTOMATIC else str(int(qos.liveliness))
    # deadline, lifespan and lease duration are infinite: rmw_zenoh's defaults, so empty.
    return f"{rel}:{dur}:{hist},{depth}:,:,:{live},,"


def qos_from_str(text: str) -> QoSProfile | None:
    """Parse a token's QoS string; ``None`` if malformed."""
    parts = text.split(":")
    if len(parts) < 6:
        return None
    try:
        hist, _, depth = parts[2].partition(",")
        return QoSProfile(
            history=HistoryPolicy(int(hist)) if hist else HistoryPolicy.KEEP_LAST,
            depth=int(depth) if depth else _ZENOH_DEFAULT_DEPTH,
            reliability=ReliabilityPolicy(int(parts[0])) if parts[0] else ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy(int(parts[1])) if parts[1] else DurabilityPolicy.VOLATILE,
        )
    except ValueError:
        return None


def node_token(domain_id: int, zid: str, nid: int, enclave: str, namespace: str, node: str) -> str:
    """The liveliness key of a node."""
    return f"{ADMIN_SPACE}/{domain_id}/{zid}/{nid}/{nid}/NN/{mangle(enclave)}/{mangle(namespace)}/{node}"


def endpoint_token(
    domain_id: int, zid: str, nid: int, eid: int, kind: str, enclave: str, namespace: str, node: str,
    name: str, dds_type: str, type_hash: str, qos: QoSProfile,
) -> str:
    """The liveliness key of a publisher (MP), subscription (MS), service (SS) or client (SC)."""
    return (
        f"{ADMIN_SPACE}/{domain_id}/{zid}/{nid}/{eid}/{kind}/{mangle(enclave)}/{mangle(namespace)}/{node}/"
        f"{mangle(name)}/{dds_type}/{type_hash}/{qos_to_str(qos)}"
    )


def ros_type_from_dds(dds_type: str) -> str:
    """``pkg::msg::dds_::Name_`` -> ``pkg/msg/Name`` (unchanged if not in that form)."""
    parts = dds_type.split("::")
    if len(parts) == 4 and parts[2] == "dds_" and parts[3].endswith("_"):
        return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"
    return dds_type


def parse_token(key: str) -> Endpoint | None:
    """A liveliness key as an ``Endpoint`` (``origin`` = the session id); ``None`` if not one of ours."""
    parts = key.split("/")
    if len(parts) < 9 or parts[0] != ADMIN_SPACE:
        return None
    kind = parts[5]
    namespace = unmangle(parts[7]) or "/"
    if kind == NODE:
        return Endpoint(NODE, parts[8], namespace, origin=parts[2])
    if kind not in ("MP", "MS", "SS", "SC") or len(parts) < 13:
        return None
    return Endpoint(
        kind, parts[8], namespace, unmangle(parts[9]), ros_type_from_dds(parts[10]),
        qos_from_str(parts[12]), parts[2], gid_for(key),
    )


def gid_for(token_key: str) -> bytes:
    """A stable 16-byte GID for an entity.

    rmw_zenoh uses XXH3-128 of the token key; peers only need GIDs unique and stable, so
    BLAKE2b-128 from the standard library serves.
    """
    return hashlib.blake2b(token_key.encode(), digest_size=16).digest()


class Attachment(NamedTuple):
    sequence_number: int
    source_timestamp: int
    source_gid: bytes


class AttachmentError(ValueError):
    """An attachment that is neither the 33-byte nor the legacy keyed format."""


_V2 = struct.Struct("<qqB16s")


def _zstr(text: str) -> bytes:
    raw = text.encode()
    return bytes([len(raw)]) + raw  # LEB128 of a length < 128 is one byte


_LEGACY_KEYS = (_zstr("sequence_number"), _zstr("source_timestamp"), _zstr("source_gid"))


def encode_attachment(seq: int, timestamp_ns: int, gid: bytes, fmt: str = ATTACHMENT_V2) -> bytes:
    """Serialize an attachment in the given rmw_zenoh format."""
    if fmt == ATTACHMENT_V2:
        return _V2.pack(seq, timestamp_ns, 16, gid)
    k_seq, k_ts, k_gid = _LEGACY_KEYS
    return k_seq + struct.pack("<q", seq) + k_ts + struct.pack("<q", timestamp_ns) + k_gid + b"\x10" + gid


def decode_attachment(data: bytes) -> Attachment:
    """Parse either attachment format.

    Raises:
        AttachmentError: the bytes are neither format.
    """
    if len(data) == _V2.size:
        seq, ts, n, gid = _V2.unpack(data)
        if n != 16:
            raise AttachmentError(f"attachment GID length byte is {n}, expected 16")
        return Attachment(seq, ts, gid)
    k_seq, k_ts, k_gid = _LEGACY_KEYS
    if data.startswith(k_seq):
        try:
            pos = len(k_seq)
            (seq,) = struct.unpack_from("<q", data, pos)
            pos += 8
            if data[pos:pos + len(k_ts)] != k_ts:
                raise AttachmentError("legacy attachment lacks 'source_timestamp'")
            pos += len(k_ts)
            (ts,) = struct.unpack_from("<q", data, pos)
            pos += 8
            if data[pos:pos + len(k_gid)] != k_gid or data[pos + len(k_gid)] != 16:
                raise AttachmentError("legacy attachment lacks 'source_gid'")
            pos += len(k_gid) + 1
            gid = data[pos:pos + 16]
            if len(gid) != 16 or pos + 16 != len(data):
                raise AttachmentError("legacy attachment has a truncated or oversized GID")
            return Attachment(seq, ts, bytes(gid))
        except (struct.error, IndexError) as exc:
            raise AttachmentError(f"truncated legacy attachment ({len(data)} bytes)") from exc
    raise AttachmentError(f"attachment of {len(data)} bytes is neither the 33-byte nor the legacy format")
