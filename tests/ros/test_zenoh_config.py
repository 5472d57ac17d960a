"""Zenoh transport settings: rmw_zenoh environment variables and router selection."""

from __future__ import annotations

import pytest

from multiros import ros
from multiros.ros.transport.zenoh.config import ZenohSettings, router_listening, session_config


def test_settings_from_env_and_options() -> None:
    s = ZenohSettings.from_options({}, {"UNIROS_ZENOH_ROUTER": "tcp/127.0.0.1:1234",
                                        "ZENOH_ROUTER_CHECK_ATTEMPTS": "-1"})
    assert (s.router, s.router_endpoint, s.router_check_attempts) == ("auto", "tcp/127.0.0.1:1234", None)
    s = ZenohSettings.from_options({"router": "tcp/127.0.0.1:99"}, {"ZENOH_ROUTER_CHECK_ATTEMPTS": "0"})
    assert (s.router, s.router_endpoint, s.router_check_attempts) == ("auto", "tcp/127.0.0.1:99", 60)
    with pytest.raises(ros.TransportError, match="attachment_format"):
        ZenohSettings.from_options({"attachment_format": "v9"}, {})
    with pytest.raises(ros.TransportError, match="unknown zenoh transport option"):
        ZenohSettings.from_options({"routr": "none"}, {})


def test_session_config_is_loopback_without_multicast_and_honours_override() -> None:
    s = ZenohSettings.from_options({"router_endpoint": "tcp/127.0.0.1:7"},
                                   {"ZENOH_CONFIG_OVERRIDE": 'scouting/gossip/enabled=false;bad'})
    cfg = session_config(s)
    assert '"tcp/127.0.0.1:0"' in cfg.get_json("listen/endpoints")
    assert cfg.get_json("scouting/multicast/enabled") == "false"
    assert cfg.get_json("scouting/gossip/enabled") == "false"


def test_router_none_without_router_warns_and_opens(router_endpoint: str, caplog: pytest.LogCaptureFixture) -> None:
    assert not router_listening(router_endpoint, 1)
    with ros.Context(transport="zenoh", env={}, router="none", router_endpoint=router_endpoint) as ctx:
        assert ctx.ok()
        assert "no Zenoh router" in caplog.text
        assert not router_listening(router_endpoint, 1)  # "none" never starts one


def test_embedded_router_is_stopped_on_shutdown(router_endpoint: str) -> None:
    with ros.Context(transport="zenoh", env={}, router="embedded", router_endpoint=router_endpoint):
        assert router_listening(router_endpoint, 1)
    assert not router_listening(router_endpoint, 1)


@pytest.mark.slow
@pytest.mark.multiprocess
def test_interpreter_exits_without_explicit_shutdown(router_endpoint: str) -> None:
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    code = (
        "from multiros import ros\n"
        "from multiros.ros.interfaces import get_message, get_service\n"
        f"ctx = ros.Context(transport='zenoh', env={{}}, router_endpoint='{router_endpoint}').init()\n"
        "n = ros.Node('x', context=ctx)\n"
        "n.create_subscription(get_message('std_msgs/msg/String'), 't', print, 10)\n"
        "n.create_service(get_service('std_srvs/srv/Trigger'), 's', lambda q, r: r)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=root, env={"PYTHONPATH": str(root)})
    try:
        assert proc.wait(timeout=20) == 0
    finally:
        proc.kill()
        proc.wait(10)


# -- multi-host settings -------------------------------------------------------------------------
def test_multi_host_settings_from_env_and_options(tmp_path) -> None:
    from multiros.ros.transport.zenoh.config import router_config

    ca, cert, key, acl = (tmp_path / n for n in ("ca.pem", "cert.pem", "key.pem", "acl.json5"))
    for f in (ca, cert, key):
        f.write_text("-----BEGIN CERTIFICATE-----\n")
    acl.write_text('{enabled: true, default_permission: "deny", rules: [], subjects: [], policies: []}')
    env = {"UNIROS_ZENOH_CONNECT": "tcp/10.231.0.1:7447, tls/robot.local:7448",
           "UNIROS_ZENOH_ROUTER_LISTEN": "tcp/0.0.0.0:7447", "UNIROS_ZENOH_ROUTER_CONNECT": "tcp/10.0.0.9:7447",
           "UNIROS_ZENOH_TLS_ROOT_CA": str(ca), "UNIROS_ZENOH_TLS_CERT": str(cert),
           "UNIROS_ZENOH_TLS_KEY": str(key), "UNIROS_ZENOH_USER": "ros", "UNIROS_ZENOH_PASSWORD": "secret",
           "UNIROS_ZENOH_ACCESS_CONTROL": str(acl)}
    s = ZenohSettings.from_options({"router_endpoint": "tcp/127.0.0.1:7"}, env)
    cfg = session_config(s)
    assert cfg.get_json("connect/endpoints") == (
        '["tcp/127.0.0.1:7","tcp/10.231.0.1:7447","tls/robot.local:7448"]')
    assert cfg.get_json("listen/endpoints") == '["tcp/127.0.0.1:0"]'  # loopback unless asked
    assert cfg.get_json("transport/auth/usrpwd/user") == '"ros"'
    assert str(ca) in cfg.get_json("transport/link/tls/root_ca_certificate")
    rcfg = router_config(s)
    assert rcfg.get_json("listen/endpoints") == '["tcp/127.0.0.1:7","tcp/0.0.0.0:7447"]'
    assert rcfg.get_json("connect/endpoints") == '["tcp/10.0.0.9:7447"]'
    assert "deny" in rcfg.get_json("access_control")
    # Options win over variables; a single listen endpoint may be a string.
    s = ZenohSettings.from_options({"listen": "tcp/10.1.2.3:0", "connect": []}, {"UNIROS_ZENOH_LISTEN": "x"})
    assert s.listen == ("tcp/10.1.2.3:0",) and s.network.connect == ()


@pytest.mark.parametrize(("env", "message"), [
    ({"UNIROS_ZENOH_CONNECT": "10.0.0.1:7447"}, "UNIROS_ZENOH_CONNECT: '10.0.0.1:7447' is not a Zenoh endpoint"),
    ({"UNIROS_ZENOH_ROUTER_LISTEN": "tcp/0.0.0.0"}, "<protocol>/<host>:<port>"),
    ({"UNIROS_ZENOH_LISTEN": "http/a:1"}, "UNIROS_ZENOH_LISTEN"),
    ({"UNIROS_ZENOH_TLS_ROOT_CA": "/nonexistent/ca.pem"}, "does not exist"),
    ({"UNIROS_ZENOH_USER": "ros"}, "both UNIROS_ZENOH_USER and UNIROS_ZENOH_PASSWORD"),
    ({"UNIROS_ZENOH_CONNECT": "tls/a:1"}, "UNIROS_ZENOH_TLS_ROOT_CA"),
    ({"UNIROS_ZENOH_TLS_MTLS": "maybe"}, "use 1 or 0"),
])
def test_multi_host_settings_are_validated(env, message) -> None:
    with pytest.raises(ros.TransportError, match=message):
        ZenohSettings.from_options({}, env)


def test_wrong_password_cannot_reach_a_router(tmp_path, router_endpoint: str) -> None:
    users = tmp_path / "users.txt"
    users.write_text("robot:right-password\n")
    server_env = {"UNIROS_ZENOH_USER": "robot", "UNIROS_ZENOH_PASSWORD": "right-password",
                  "UNIROS_ZENOH_AUTH_DICTIONARY": str(users)}
    with ros.Context(transport="zenoh", env=server_env, router="embedded", router_endpoint=router_endpoint):
        # router="auto": a router listens there, so the session must connect to it (and cannot).
        bad = ros.Context(transport="zenoh", router_endpoint=router_endpoint, router_wait_sec=1.0,
                          env={"UNIROS_ZENOH_USER": "robot", "UNIROS_ZENOH_PASSWORD": "wrong",
                               "ZENOH_ROUTER_CHECK_ATTEMPTS": "1"})
        with pytest.raises(ros.TransportError, match="no Zenoh router reachable.*user and password"):
            bad.init()
        nobody = ros.Context(transport="zenoh", router_endpoint=router_endpoint,
                             router_wait_sec=1.0, env={"ZENOH_ROUTER_CHECK_ATTEMPTS": "1"})
        with pytest.raises(ros.TransportError, match="no Zenoh router reachable"):
            nobody.init()
        good = ros.Context(transport="zenoh", router_endpoint=router_endpoint, env=server_env)
        with good:
            assert good.transport.session.info.routers_zid()


def _make_ca_and_cert(folder, name: str) -> tuple[str, str, str]:
    """A throw-away CA and a certificate for localhost/127.0.0.1 signed by it (needs openssl)."""
    import shutil
    import subprocess

    if shutil.which("openssl") is None:
        pytest.skip("openssl is not installed: cannot make test certificates")
    run = lambda *a: subprocess.run(["openssl", *a], check=True, capture_output=True, timeout=60)  # noqa: E731
    ca, ca_key, key, csr, cert = (str(folder / f"{name}-{n}")
                                  for n in ("ca.pem", "ca.key", "key.pem", "csr", "cert.pem"))
    run("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", ca_key, "-out", ca, "-days", "2",
        "-subj", f"/CN={name}-ca")
    run("req", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", csr, "-subj", "/CN=localhost")
    ext = folder / f"{name}-ext.cnf"
    ext.write_text("subjectAltName=DNS:localhost,IP:127.0.0.1\n")
    run("x509", "-req", "-in", csr, "-CA", ca, "-CAkey", ca_key, "-CAcreateserial", "-out", cert, "-days", "2",
        "-extfile", str(ext))
    return ca, cert, key


def test_tls_router_accepts_only_peers_trusting_its_ca(tmp_path, router_endpoint: str) -> None:
    ca, cert, key = _make_ca_and_cert(tmp_path, "good")
    other_ca, _, _ = _make_ca_and_cert(tmp_path, "other")
    endpoint = router_endpoint.replace("tcp/127.0.0.1", "tls/localhost")
    tls = {"UNIROS_ZENOH_TLS_ROOT_CA": ca, "UNIROS_ZENOH_TLS_CERT": cert, "UNIROS_ZENOH_TLS_KEY": key}
    with ros.Context(transport="zenoh", env=tls, router="embedded", router_endpoint=endpoint):
        with ros.Context(transport="zenoh", env={"UNIROS_ZENOH_TLS_ROOT_CA": ca}, router_endpoint=endpoint) as ok:
            assert ok.transport.session.info.routers_zid()
        wrong = ros.Context(transport="zenoh", env={"UNIROS_ZENOH_TLS_ROOT_CA": other_ca}, router_endpoint=endpoint,
                            router_wait_sec=1.0)
        with pytest.raises(ros.TransportError, match="check the CA"):
            wrong.init()
