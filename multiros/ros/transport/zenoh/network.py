"""Multi-host Zenoh settings: extra endpoints, TLS, user/password authentication, access control.

Loopback stays the default: with none of these set, sessions and the embedded router listen on
127.0.0.1 only. Each setting is a ``Context`` option or an environment variable (the option wins):

=========================  ====================================  =====================================
option                     environment variable                  meaning
=========================  ====================================  =====================================
``connect``                ``UNIROS_ZENOH_CONNECT``              more endpoints the session connects to
``listen``                 ``UNIROS_ZENOH_LISTEN``               the session's listen endpoints
                                                                 (default ``tcp/127.0.0.1:0``)
``router_listen``          ``UNIROS_ZENOH_ROUTER_LISTEN``        more endpoints the embedded router
                                                                 listens on (reachable from other hosts)
``router_connect``         ``UNIROS_ZENOH_ROUTER_CONNECT``       routers (other hosts) the embedded
                                                                 router connects to
``tls_root_ca``            ``UNIROS_ZENOH_TLS_ROOT_CA``          CA certificate (PEM) to verify peers
``tls_cert``, ``tls_key``  ``UNIROS_ZENOH_TLS_CERT``, ``_KEY``   this side's certificate and key (PEM)
``tls_mtls``               ``UNIROS_ZENOH_TLS_MTLS`` (``1``)     require client certificates (mutual TLS)
``user``, ``password``     ``UNIROS_ZENOH_USER``, ``_PASSWORD``  credentials presented when connecting
``auth_dictionary``        ``UNIROS_ZENOH_AUTH_DICTIONARY``      file of ``user:password`` lines that
                                                                 incoming connections must match
``access_control``         ``UNIROS_ZENOH_ACCESS_CONTROL``       JSON5 file with Zenoh's
                                                                 ``access_control`` object (router
                                                                 and session)
=========================  ====================================  =====================================

Lists are comma-separated in variables. Endpoints are Zenoh locators: ``tcp/10.0.0.5:7447``,
``tls/robot.local:7447``, ``udp/...``, ``quic/...``, ``ws/...``, ``unixsock-stream/<path>``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

from multiros.ros.exceptions import TransportError

__all__ = ["NetworkSettings", "NETWORK_OPTIONS", "NETWORK_ENV_VARS", "validate_endpoint"]

_HOST_PORT_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")
_PATH_PROTOCOLS = ("unixsock-stream", "unixpipe", "serial", "vsock")
_TLS_PROTOCOLS = ("tls", "quic")

# option name -> environment variable
NETWORK_OPTIONS = {
    "connect": "UNIROS_ZENOH_CONNECT",
    "listen": "UNIROS_ZENOH_LISTEN",
    "router_listen": "UNIROS_ZENOH_ROUTER_LISTEN",
    "router_connect": "UNIROS_ZENOH_ROUTER_CONNECT",
    "tls_root_ca": "UNIROS_ZENOH_TLS_ROOT_CA",
    "tls_cert": "UNIROS_ZENOH_TLS_CERT",
    "tls_key": "UNIROS_ZENOH_TLS_KEY",
    "tls_mtls": "UNIROS_ZENOH_TLS_MTLS",
    "user": "UNIROS_ZENOH_USER",
    "password": "UNIROS_ZENOH_PASSWORD",
    "auth_dictionary": "UNIROS_ZENOH_AUTH_DICTIONARY",
    "access_control": "UNIROS_ZENOH_ACCESS_CONTROL",
}
NETWORK_ENV_VARS = tuple(NETWORK_OPTIONS.values())
DEFAULT_LISTEN = ("tcp/127.0.0.1:0",)


def validate_endpoint(endpoint: str, what: str) -> str:
    """Check that ``endpoint`` looks like a Zenoh locator; return it stripped.

    Raises:
        TransportError: it does not, naming ``what`` (the option or variable) and the fix.
    """
    text = str(endpoint).strip()
    proto, sep, address = text.partition("/")
    address = address.split("#", 1)[0].split("?", 1)[0]
    fix = (f"{what}: {text!r} is not a Zenoh endpoint; write <protocol>/<host>:<port> "
           f"(protocols {', '.join(_HOST_PORT_PROTOCOLS)}), e.g. tcp/192.168.1.10:7447, "
           "or unixsock-stream/<path>")
    if not sep or not address:
        raise TransportError(fix)
    if proto in _PATH_PROTOCOLS:
        return text
    if proto not in _HOST_PORT_PROTOCOLS:
        raise TransportError(fix)
    host, colon, port = address.rpartition(":")
    if not colon or not host.strip("[]") or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise TransportError(fix)
    return text


def _endpoints(value: Any, what: str) -> tuple[str, ...]:
    if value is None or value == "":
        return ()
    items = value.split(",") if isinstance(value, str) else list(value)
    return tuple(validate_endpoint(e, what) for e in items if str(e).strip())


def _file(value: Any, what: str) -> str | None:
    if value is None or str(value).strip() == "":
        return None
    path = Path(str(value).strip()).expanduser()
    if not path.is_file():
        raise TransportError(f"{what}: file {str(path)!r} does not exist or is not a file")
    return str(path.resolve())


def _flag(value: Any, what: str) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value or "").strip().lower()
    if text in ("", "0", "false", "no", "off"):
        return False
    if text in ("1", "true", "yes", "on"):
        return True
    raise TransportError(f"{what}={value!r}: use 1 or 0")


@dataclass(frozen=True)
class NetworkSettings:
    """Validated multi-host settings (see the module docstring)."""

    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = DEFAULT_LISTEN
    router_listen: tuple[str, ...] = ()
    router_connect: tuple[str, ...] = ()
    tls_root_ca: str | None = None
    tls_cert: str | None = None
    tls_key: str | None = None
    tls_mtls: bool = False
    user: str | None = None
    password: str | None = None
    auth_dictionary: str | None = None
    access_control: str | None = None

    @classmethod
    def from_options(cls, options: Mapping[str, Any], env: Mapping[str, str]) -> NetworkSettings:
        """Read options (which win) and environment variables, and validate them.

        Raises:
            TransportError: a malformed endpoint, a missing file, or an incomplete pair
                (certificate without key, user without password, ...), naming the setting.
        """
        def get(name: str) -> tuple[Any, str]:
            if options.get(name) is not None:
                return options[name], f"option {name}"
            return env.get(NETWORK_OPTIONS[name]), NETWORK_OPTIONS[name]

        value, what = get("listen")
        listen = _endpoints(value, what) or DEFAULT_LISTEN
        s = cls(
            connect=_endpoints(*get("connect")),
            listen=listen,
            router_listen=_endpoints(*get("router_listen")),
            router_connect=_endpoints(*get("router_connect")),
            tls_root_ca=_file(*get("tls_root_ca")),
            tls_cert=_file(*get("tls_cert")),
            tls_key=_file(*get("tls_key")),
            tls_mtls=_flag(*get("tls_mtls")),
            user=(str(get("user")[0]) if get("user")[0] else None),
            password=(str(get("password")[0]) if get("password")[0] else None),
            auth_dictionary=_file(*get("auth_dictionary")),
            access_control=_file(*get("access_control")),
        )
        s._check()
        return s

    def _check(self) -> None:
        if (self.tls_cert is None) != (self.tls_key is None):
            raise TransportError("TLS needs both a certificate and its private key: set UNIROS_ZENOH_TLS_CERT and "
                                 "UNIROS_ZENOH_TLS_KEY (options tls_cert, tls_key), or neither")
        if (self.user is None) != (self.password is None):
            raise TransportError("authentication needs both UNIROS_ZENOH_USER and UNIROS_ZENOH_PASSWORD "
                                 "(options user, password), or neither")
        if self.tls_mtls and self.tls_cert is None:
            raise TransportError("mutual TLS (UNIROS_ZENOH_TLS_MTLS=1) needs this side's certificate and key "
                                 "(UNIROS_ZENOH_TLS_CERT, UNIROS_ZENOH_TLS_KEY)")
        endpoints = self.connect + self.listen + self.router_listen + self.router_connect
        if any(e.split("/", 1)[0] in _TLS_PROTOCOLS for e in endpoints) and self.tls_root_ca is None:
            raise TransportError("a tls/ or quic/ endpoint needs the CA certificate that signed the peers' "
                                 "certificates: set UNIROS_ZENOH_TLS_ROOT_CA (option tls_root_ca)")

    def _apply_common(self, config: zenoh.Config) -> None:
        if self.tls_root_ca:
            config.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(self.tls_root_ca))
        if self.tls_cert and self.tls_key:
            for side in ("listen", "connect"):
                config.insert_json5(f"transport/link/tls/{side}_certificate", json.dumps(self.tls_cert))
                config.insert_json5(f"transport/link/tls/{side}_private_key", json.dumps(self.tls_key))
        if self.tls_mtls:
            config.insert_json5("transport/link/tls/enable_mtls", "true")
        if self.user is not None:
            config.insert_json5("transport/auth/usrpwd/user", json.dumps(self.user))
            config.insert_json5("transport/auth/usrpwd/password", json.dumps(self.password))
        if self.auth_dictionary:
            config.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(self.auth_dictionary))

    def apply_to_session(self, config: zenoh.Config, router_endpoint: str, *, defaults: bool) -> None:
        """Set endpoints (only when ``defaults``: no user config file), TLS, authentication and access control."""
        if defaults:
            config.insert_json5("connect/endpoints", json.dumps(_unique((router_endpoint, *self.connect))))
            config.insert_json5("listen/endpoints", json.dumps(list(self.listen)))
        elif self.connect:
            config.insert_json5("connect/endpoints", json.dumps(list(self.connect)))
        self._apply_common(config)
        self._apply_access_control(config)

    def apply_to_router(self, config: zenoh.Config, router_endpoint: str, *, defaults: bool) -> None:
        """Set the router's endpoints, TLS, authentication and access control."""
        if defaults:
            config.insert_json5("listen/endpoints", json.dumps(_unique((router_endpoint, *self.router_listen))))
            config.insert_json5("connect/endpoints", json.dumps(list(self.router_connect)))
        else:
            if self.router_listen:
                config.insert_json5("listen/endpoints", json.dumps(list(self.router_listen)))
            if self.router_connect:
                config.insert_json5("connect/endpoints", json.dumps(list(self.router_connect)))
        self._apply_common(config)
        self._apply_access_control(config)

    def _apply_access_control(self, config: zenoh.Config) -> None:
        # Peers exchange data directly (the router relays nothing between them), so the rules
        # must hold in every session that serves something, not only in the router.
        if self.access_control:
            text = Path(self.access_control).read_text(encoding="utf-8")
            try:
                config.insert_json5("access_control", text)
            except Exception as exc:  # noqa: BLE001 - zenoh raises ZError
                raise TransportError(
                    f"UNIROS_ZENOH_ACCESS_CONTROL: {self.access_control!r} is not a valid Zenoh access_control "
                    f"object (JSON5 with enabled, default_permission, rules, subjects, policies): {exc}"
                ) from exc

    @property
    def secured(self) -> bool:
        """Whether TLS or authentication is configured (for clearer connection errors)."""
        return bool(self.tls_root_ca or self.user or self.auth_dictionary)


def _unique(items: Sequence[str]) -> list[str]:
    return list(dict.fromkeys(items))
