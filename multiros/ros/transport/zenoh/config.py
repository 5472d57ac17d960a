"""Zenoh settings, session and router configuration, and the router check.

Environment variables honoured as rmw_zenoh documents them (read once, by the ``Context``):

* ``ZENOH_SESSION_CONFIG_URI`` - a JSON5 session config file replacing our defaults;
* ``ZENOH_ROUTER_CONFIG_URI`` - a JSON5 config file for the embedded router;
* ``ZENOH_CONFIG_OVERRIDE`` - ``key=value;key=value`` JSON5 overrides applied to both;
* ``ZENOH_ROUTER_CHECK_ATTEMPTS`` - router probes, one second apart (default 1; ``< 0`` skips
  the check; ``0`` means "forever" in rmw_zenoh and is capped here at ``MAX_CHECK_ATTEMPTS``
  because every wait has a bound).

Ours: ``UNIROS_ZENOH_ROUTER`` (router endpoint, default ``tcp/127.0.0.1:7447``), and the
multi-host settings of ``network.py`` (``UNIROS_ZENOH_CONNECT``, ``UNIROS_ZENOH_ROUTER_LISTEN``,
TLS, user/password, access control). Our settings apply on top of a config file too.
"""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import zenoh

from multiros.ros.exceptions import TransportError
from multiros.ros.transport.zenoh.network import NETWORK_ENV_VARS, NETWORK_OPTIONS, NetworkSettings
from multiros.ros.transport.zenoh.wire import ATTACHMENT_LEGACY, ATTACHMENT_V2

__all__ = ["ZenohSettings", "session_config", "router_config", "router_listening", "DEFAULT_ROUTER_ENDPOINT",
           "ENV_VARS"]

_log = logging.getLogger(__name__)

DEFAULT_ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"
ROUTER_ENV = "UNIROS_ZENOH_ROUTER"
MAX_CHECK_ATTEMPTS = 60
_ROUTER_MODES = ("auto", "embedded", "none")
#: Every environment variable the Zenoh transport reads (a private context must ignore them all).
ENV_VARS = (ROUTER_ENV, "ZENOH_SESSION_CONFIG_URI", "ZENOH_ROUTER_CONFIG_URI", "ZENOH_CONFIG_OVERRIDE",
            "ZENOH_ROUTER_CHECK_ATTEMPTS", *NETWORK_ENV_VARS)


@dataclass(frozen=True)
class ZenohSettings:
    """Options of the Zenoh transport.

    Attributes:
        router: ``"auto"`` (use a router at ``router_endpoint``, start one embedded if none
            listens), ``"embedded"`` (always start one), ``"none"`` (never start one), or an
            endpoint (``"tcp/127.0.0.1:7448"``, meaning ``"auto"`` at that endpoint).
        router_endpoint: where the router listens.
        attachment_format: ``"v2"`` (33 bytes, rmw_zenoh >= 0.2.4) or ``"legacy"``.
        lazy_publish: serialize and put volatile messages only while Zenoh reports a matching
            subscriber in another session (a ROS node or any Zenoh tool; transient-local ones are
            always put, for the cache).
        router_wait_sec: how long to wait for the session to connect to the router.
        network: multi-host settings (extra endpoints, TLS, authentication, access control).
    """

    router: str = "auto"
    router_endpoint: str = DEFAULT_ROUTER_ENDPOINT
    attachment_format: str = ATTACHMENT_V2
    lazy_publish: bool = True
    router_wait_sec: float = 5.0
    router_check_attempts: int | None = 1
    session_config_uri: str | None = None
    router_config_uri: str | None = None
    config_override: str | None = None
    network: NetworkSettings = NetworkSettings()

    @property
    def listen(self) -> tuple[str, ...]:
        """The session's listen endpoints."""
        return self.network.listen

    @classmethod
    def from_options(cls, options: Mapping[str, Any], env: Mapping[str, str]) -> ZenohSettings:
        """Build from ``Context`` keyword options and the environment snapshot.

        Raises:
            TransportError: an option or variable has an invalid value.
        """
        known = {"router", "router_endpoint", "attachment_format", "lazy_publish", "router_wait_sec",
                 "codec", *NETWORK_OPTIONS}
        unknown = set(options) - known
        if unknown:
            raise TransportError(f"unknown zenoh transport option(s) {sorted(unknown)}; known: {sorted(known)}")
        router = str(options.get("router") or "auto")
        endpoint = options.get("router_endpoint") or env.get(ROUTER_ENV) or DEFAULT_ROUTER_ENDPOINT
        if router not in _ROUTER_MODES:
            endpoint, router = router, "auto"
        fmt = options.get("attachment_format", ATTACHMENT_V2)
        if fmt not in (ATTACHMENT_V2, ATTACHMENT_LEGACY):
            raise TransportError(f"attachment_format {fmt!r}: use 'v2' (rmw_zenoh >= 0.2.4) or 'legacy'")
        raw_attempts = env.get("ZENOH_ROUTER_CHECK_ATTEMPTS", "").strip()
        attempts: int | None = 1
        if raw_attempts:
            try:
                value = int(raw_attempts)
            except ValueError:
                raise TransportError(f"ZENOH_ROUTER_CHECK_ATTEMPTS={raw_attempts!r} is not an integer") from None
            attempts = None if value < 0 else (MAX_CHECK_ATTEMPTS if value == 0 else value)
        return cls(
            router=router,
            router_endpoint=str(endpoint),
            attachment_format=fmt,
            lazy_publish=bool(options.get("lazy_publish", True)),
            router_wait_sec=float(options.get("router_wait_sec", 5.0)),
            router_check_attempts=attempts,
            session_config_uri=env.get("ZENOH_SESSION_CONFIG_URI") or None,
            router_config_uri=env.get("ZENOH_ROUTER_CONFIG_URI") or None,
            config_override=env.get("ZENOH_CONFIG_OVERRIDE") or None,
            network=NetworkSettings.from_options(options, env),
        )


def _apply_override(config: zenoh.Config, override: str | None) -> None:
    if not override:
        return
    for pair in override.split(";"):
        key, sep, value = pair.partition("=")
        if not sep or not key.strip():
            continue
        try:
            config.insert_json5(key.strip(), value.strip())
        except Exception as exc:  # noqa: BLE001 - zenoh raises ZError
            _log.warning("ZENOH_CONFIG_OVERRIDE: ignoring invalid pair %r: %s", pair, exc)


def _from_file(path: str, what: str) -> zenoh.Config:
    try:
        return zenoh.Config.from_file(path)
    except Exception as exc:  # noqa: BLE001
        raise TransportError(f"{what} config file {path!r} could not be loaded: {exc}") from exc


def session_config(settings: ZenohSettings) -> zenoh.Config:
    """The session config: rmw_zenoh's defaults (peer mode, connect to the router, no multicast
    scouting) but listening on loopback only, unless ``ZENOH_SESSION_CONFIG_URI`` gives a file;
    then the multi-host settings, then ``ZENOH_CONFIG_OVERRIDE``."""
    defaults = not settings.session_config_uri
    if not defaults:
        config = _from_file(settings.session_config_uri, "ZENOH_SESSION_CONFIG_URI")
    else:
        config = zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("scouting/multicast/enabled", "false")
        config.insert_json5("scouting/gossip/enabled", "true")
    settings.network.apply_to_session(config, settings.router_endpoint, defaults=defaults)
    _apply_override(config, settings.config_override)
    return config


def router_config(settings: ZenohSettings) -> zenoh.Config:
    """The embedded router's config: router mode listening on ``router_endpoint`` (plus
    ``router_listen``), connecting to ``router_connect``; a ``ZENOH_ROUTER_CONFIG_URI`` file
    replaces these defaults."""
    defaults = not settings.router_config_uri
    if not defaults:
        config = _from_file(settings.router_config_uri, "ZENOH_ROUTER_CONFIG_URI")
    else:
        config = zenoh.Config()
        config.insert_json5("mode", '"router"')
        config.insert_json5("scouting/multicast/enabled", "false")
    settings.network.apply_to_router(config, settings.router_endpoint, defaults=defaults)
    _apply_override(config, settings.config_override)
    return config


def _host_port(endpoint: str) -> tuple[str, int] | None:
    proto, _, address = endpoint.partition("/")
    if proto not in ("tcp", "tls", "quic", "udp") or ":" not in address:
        return None
    host, _, port = address.rpartition(":")
    host = host.strip("[]")
    try:
        return host, int(port.split("#")[0])
    except ValueError:
        return None


def router_listening(endpoint: str, attempts: int, interval_sec: float = 1.0) -> bool:
    """Whether something accepts TCP connections at ``endpoint`` (probed ``attempts`` times)."""
    hp = _host_port(endpoint)
    if hp is None:
        return True  # cannot probe (unix socket, ...): assume the user runs a router there
    for i in range(max(1, attempts)):
        try:
            with socket.create_connection(hp, timeout=0.5):
                return True
        except OSError:
            if i + 1 < attempts:
                time.sleep(interval_sec)  # rmw_zenoh's spacing between router checks
    return False
