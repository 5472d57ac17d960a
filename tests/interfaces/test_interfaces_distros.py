"""Per-distribution definitions: type hashes and CDR against rosbags for every shipped distribution,
the release differences that matter on the wire, and the ``ROS_DISTRO`` choice."""

from __future__ import annotations

import os
import random
import subprocess
import sys

import pytest
from interfaces_factory import to_rosbags
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags_types import parts_types, service_types, store_of

from multiros.ros.interfaces import (
    DEFAULT_DISTRO,
    SHIPPED_DISTROS,
    SUPPORTED_DISTROS,
    UnsupportedDistroError,
    default_distro,
    deserialize_message,
    registry_for,
    serialize_message,
    type_hash,
)
from multiros.ros.interfaces._classgen import NP_DTYPES, value_kind
from multiros.ros.interfaces.registry import DISTROS_ROOT

DISTRO_PACKAGES = ("simulation_interfaces", "controller_manager_msgs", "control_msgs")
# rosbags' typestore of each distribution (Lyrical branched from Rolling after Kilted).
STORES = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY, "kilted": Stores.ROS2_KILTED,
          "rolling": Stores.ROS2_LYRICAL}
VERSIONS = {  # package.xml versions of the releases (reference/interfaces_by_distro/README.md)
    "humble": {"simulation_interfaces": "1.4.0", "controller_manager_msgs": "2.54.0", "control_msgs": "4.8.0"},
    "jazzy": {"simulation_interfaces": "1.5.1", "controller_manager_msgs": "4.46.0", "control_msgs": "5.8.0"},
    "kilted": {"simulation_interfaces": "1.6.1", "controller_manager_msgs": "5.16.0", "control_msgs": "6.8.0"},
    "rolling": {"simulation_interfaces": "2.1.0", "controller_manager_msgs": "6.8.0", "control_msgs": "6.8.0"},
}


def _oracle(distro: str):
    """rosbags store of one distribution's registry: every definition file parsed by rosbags itself,
    ``char`` mapped to uint8 as rosidl does, plus the service, event and action structs."""
    reg = registry_for(distro)
    types: dict = {}
    for full in reg.list_types():
        text = reg.definition_file(full).read_text()
        kind = full.split("/")[1]
        if kind == "msg":
            types.update(get_types_from_msg(text, full))
        elif kind == "srv":
            types.update(service_types(full, text))
        else:
            types.update(parts_types(full, text, ("_Goal", "_Result", "_Feedback")))
    return store_of(types)


ORACLES = {d: _oracle(d) for d in SHIPPED_DISTROS}


def _distro_types(distro: str, kind: str) -> list[str]:
    return [n for n in registry_for(distro).list_types(kind) if n.split("/")[0] in DISTRO_PACKAGES]


def _cases(kind: str) -> list[tuple[str, str]]:
    return [(d, n) for d in SHIPPED_DISTROS for n in _distro_types(d, kind)]


# -- what ships ----------------------------------------------------------------------------------
@pytest.mark.parametrize("distro", SHIPPED_DISTROS)
def test_each_distribution_ships_its_release(distro: str) -> None:
    for pkg, version in VERSIONS[distro].items():
        xml = (DISTROS_ROOT / distro / pkg / "package.xml").read_text()
        assert f"<version>{version}</version>" in xml and "<license>" in xml
    assert (DISTROS_ROOT / distro / "simulation_interfaces" / "LICENSE").is_file()
    reg = registry_for(distro)
    assert reg.distro == distro and reg.roots[0] == DISTROS_ROOT / distro
    assert registry_for(distro) is reg


def test_common_definitions_are_those_of_jazzy_kilted_and_rolling() -> None:
    """The distribution-independent packages hash as in rosbags' store of each supported distribution."""
    for distro in SUPPORTED_DISTROS:
        store, reg = get_typestore(STORES[distro]), registry_for(distro)
        common = [n for n in reg.list_types("msg") if n in store.fielddefs]
        assert len(common) > 100
        char_types = {"std_msgs/msg/Char", "service_msgs/msg/ServiceEventInfo"}  # rosbags' char pitfall
        wrong = [n for n in common if n not in char_types and type_hash(n, reg) != store.hash_rihs01(n)]
        assert wrong == [], distro


# -- hashes against rosbags ----------------------------------------------------------------------
@pytest.mark.parametrize(("distro", "type_name"), _cases("msg") + _cases("srv"))
def test_hash_matches_rosbags(distro: str, type_name: str) -> None:
    assert type_hash(type_name, registry_for(distro)) == ORACLES[distro].hash_rihs01(type_name)


def test_wire_differences_between_releases() -> None:
    """What the issue measured: Jazzy's SpawnEntity/SetEntityState/LoadWorld/GetSpawnables differ from
    Rolling's; ListControllers/SwitchController agree from Jazzy on, and differ from Humble's."""
    def h(distro: str, name: str) -> str:
        return type_hash(name, registry_for(distro))

    for name in ("srv/SpawnEntity", "srv/SetEntityState", "srv/LoadWorld", "srv/GetSpawnables", "msg/Spawnable"):
        full = f"simulation_interfaces/{name}"
        assert h("jazzy", full) == h("kilted", full) != h("rolling", full)
    for name in ("srv/DeleteEntity", "srv/StepSimulation", "srv/ResetSimulation", "msg/Result", "msg/EntityState"):
        full = f"simulation_interfaces/{name}"
        assert h("jazzy", full) == h("kilted", full) == h("rolling", full)
    for name in ("ListControllers", "SwitchController"):
        full = f"controller_manager_msgs/srv/{name}"
        assert h("humble", full) != h("jazzy", full) == h("kilted", full) == h("rolling", full)
    fjt = "control_msgs/action/FollowJointTrajectory"
    assert h("humble", fjt) == h("jazzy", fjt) != h("kilted", fjt) == h("rolling", fjt)


def test_uniros_interfaces_hash_alike_in_every_distribution() -> None:
    """uniros_interfaces embed simulation_interfaces/Result, which no release changed."""
    reg = registry_for(DEFAULT_DISTRO)
    for name in reg.list_types():
        if name.startswith("uniros_interfaces/"):
            assert len({type_hash(name, registry_for(d)) for d in SHIPPED_DISTROS}) == 1, name


# -- CDR against rosbags -------------------------------------------------------------------------
def _random(reg, type_name: str, rng: random.Random, depth: int = 0):
    from interfaces_factory import _length, _scalar

    spec, cls = reg.message_spec(type_name), reg.message_class(type_name)
    values = {}
    for f in spec.fields:
        t, kind = f.type, value_kind(f.type)
        if kind == "nested":
            values[f.name] = _random(reg, t.base, rng, depth + 1)
        elif not t.array:
            values[f.name] = _scalar(rng, t)
        else:
            n = _length(rng, t, t.is_nested or depth > 2)
            if kind == "list_nested":
                values[f.name] = [_random(reg, t.base, rng, depth + 1) for _ in range(n)]
            elif kind == "bytes":
                values[f.name] = bytes(rng.randrange(256) for _ in range(n))
            elif kind == "ndarray":
                import numpy as np

                values[f.name] = np.array([_scalar(rng, t.element()) for _ in range(n)], dtype=NP_DTYPES[t.base])
            else:
                values[f.name] = [_scalar(rng, t.element()) for _ in range(n)]
    return cls(**values)


def _message_cases() -> list[tuple[str, str]]:
    out = []
    for distro in SHIPPED_DISTROS:
        reg = registry_for(distro)
        for name in _distro_types(distro, "msg"):
            out.append((distro, name))
        for name in _distro_types(distro, "srv"):
            spec = reg.service_spec(name)
            out += [(distro, spec.request.name), (distro, spec.response.name)]
        for name in _distro_types(distro, "action"):
            a = reg.action_spec(name)
            out += [(distro, a.goal.name), (distro, a.result.name), (distro, a.feedback.name)]
    return out


@pytest.mark.parametrize(("distro", "type_name"), _message_cases())
def test_cdr_identical_to_rosbags(distro: str, type_name: str) -> None:
    reg, oracle = registry_for(distro), ORACLES[distro]
    for seed in range(3):
        msg = _random(reg, type_name, random.Random(seed))
        ours = serialize_message(msg)
        assert bytes(oracle.serialize_cdr(to_rosbags(msg, oracle), type_name)) == ours, seed
        assert deserialize_message(ours, type(msg)) == msg


# -- classes shared between distributions --------------------------------------------------------
def test_identical_definitions_share_one_class() -> None:
    jazzy, rolling = registry_for("jazzy"), registry_for("rolling")
    for name in ("std_msgs/msg/Header", "simulation_interfaces/msg/EntityState", "simulation_interfaces/msg/Result"):
        assert jazzy.message_class(name) is rolling.message_class(name)
    step = "uniros_interfaces/srv/StepRobot"
    assert jazzy.service_class(step) is rolling.service_class(step)
    spawn_j = jazzy.service_class("simulation_interfaces/srv/SpawnEntity")
    spawn_r = rolling.service_class("simulation_interfaces/srv/SpawnEntity")
    assert spawn_j is not spawn_r and type_hash(spawn_j) != type_hash(spawn_r)
    assert spawn_j.Response is spawn_r.Response  # same response definition
    assert "uri" in spawn_j.Request._fields and "entity_resource" in spawn_r.Request._fields
    # a message of one distribution nests inside the other's where the definition is the same
    req = spawn_r.Request()
    req.initial_pose = jazzy.message_class("geometry_msgs/msg/PoseStamped")()
    assert serialize_message(req)


def test_action_types_per_distribution() -> None:
    jazzy = registry_for("jazzy").action_class("control_msgs/action/FollowJointTrajectory")
    rolling = registry_for("rolling").action_class("control_msgs/action/FollowJointTrajectory")
    assert jazzy.Goal is rolling.Goal  # Kilted/Rolling added index fields to the feedback only
    assert jazzy.Feedback is not rolling.Feedback and "index" in rolling.Feedback._fields
    assert "action_msgs/srv/CancelGoal" in registry_for("jazzy").list_types("srv")


# -- choosing the distribution -------------------------------------------------------------------
def test_default_distro_follows_ros_distro(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ROS_DISTRO", raising=False)
    assert default_distro() == DEFAULT_DISTRO == "jazzy"
    for value in ("kilted", "Rolling", " jazzy "):
        monkeypatch.setenv("ROS_DISTRO", value)
        assert default_distro() == value.strip().lower()
    monkeypatch.setenv("ROS_DISTRO", "")
    assert default_distro() == "jazzy"
    monkeypatch.setenv("ROS_DISTRO", "galactic")
    with pytest.raises(UnsupportedDistroError, match="'galactic'.*jazzy, kilted, rolling"):
        default_distro()
    monkeypatch.setenv("ROS_DISTRO", "humble")
    with pytest.raises(UnsupportedDistroError, match="no type hashes"):
        default_distro()
    with pytest.raises(UnsupportedDistroError, match="humble, jazzy, kilted, rolling"):
        registry_for("iron")


def test_humble_is_refused_only_by_the_transports_that_reach_peers(monkeypatch: pytest.MonkeyPatch) -> None:
    from multiros.ros.interfaces.registry import _in_process_distro
    from multiros.ros.transport import make_transport

    monkeypatch.setenv("ROS_DISTRO", "humble")
    assert _in_process_distro() == DEFAULT_DISTRO  # in-process messages: Jazzy's definitions
    for name in ("zenoh", "rclpy"):
        with pytest.raises(UnsupportedDistroError, match=f"^the {name} transport reaches other ROS 2 programs .*"
                                                         "no type hashes.*inproc transport need no ROS"):
            make_transport(name, None)  # type: ignore[arg-type]
    assert make_transport("inproc", object()).name == "inproc"  # type: ignore[arg-type]


_PROBE = """
from multiros.ros.interfaces import default_registry, get_service, type_hash
cls = get_service("simulation_interfaces/srv/SpawnEntity")
print(default_registry().distro, type_hash(cls), "entity_resource" in cls.Request._fields)
"""


@pytest.mark.parametrize("distro", [None, "kilted", "rolling"])
def test_ros_distro_picks_the_default_registry_in_a_process(distro: str | None) -> None:
    env = {k: v for k, v in os.environ.items() if k != "ROS_DISTRO"}
    if distro:
        env["ROS_DISTRO"] = distro
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    name, digest, has_resource = out.stdout.split()
    expected = distro or "jazzy"
    assert name == expected
    assert digest == type_hash("simulation_interfaces/srv/SpawnEntity", registry_for(expected))
    assert has_resource == str(expected == "rolling")


def test_unknown_ros_distro_is_a_clear_error_only_where_peers_are_reached() -> None:
    """A ROS_DISTRO uniros has no definitions of (a sourced ROS 1, say) leaves in-process messages on
    Jazzy's (simulated use needs no ROS) and makes opening a wire transport a clear one-line error."""
    env = {**os.environ, "ROS_DISTRO": "noetic"}
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[0] == "jazzy"
    probe = "from multiros.ros.transport import make_transport\nmake_transport('zenoh', None)\n"
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode != 0
    assert "'noetic' is not supported" in out.stderr and "jazzy, kilted, rolling" in out.stderr
