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
