"""The ``ros2`` command lines of the docs are right for the distribution they are written for.

Every ``ros2 service call``, ``ros2 topic pub`` and ``ros2 action send_goal`` in a bash block is
parsed as the ROS 2 CLI would (name, type, YAML values); its type must be the one the simulation
node serves under that name (``multiros.sim.services``), and its values must be fields of that
distribution's request, message or goal (Jazzy unless the block says ``distro``). The service calls
of docs/ros2.md are then sent, in page order, to a simulation node started as the page starts it,
with the distribution's own request classes; each must succeed.
"""

from __future__ import annotations

from typing import Any

import pytest
import yaml
from docs_snippets import REPO, Block, all_blocks, parse, shell_lines

from multiros.ros.interfaces import registry_for
from multiros.sim.services import CONTROLLER_SERVICES, SIM_SERVICES

NODE = "/mujoco_sim"
RX200 = "package://rx200_description/urdf/rx200.urdf.xacro?robot_name=rx200"


def commands(block: Block) -> list[list[str]]:
    """The block's ``ros2`` command lines as argv lists (continuations and multi-line quotes joined)."""
    return [argv for argv in shell_lines(block) if argv[0] == "ros2"]


def positional(argv: list[str], start: int) -> list[str]:
    return [a for a in argv[start:] if not a.startswith("-")]


def fill(msg: Any, data: dict, registry: Any, where: str) -> Any:
    """Set ``data`` (parsed YAML) on a message as ``ros2`` does; unknown fields fail the test."""
    fields = msg.get_fields_and_field_types()
    for key, value in (data or {}).items():
        assert key in fields, f"{where}: {type(msg).__name__} has no field {key!r}; it has {sorted(fields)}"
        kind = fields[key]
        if isinstance(value, dict):
            fill(getattr(msg, key), value, registry, where)
        elif kind.startswith("sequence<") and "/" in kind:
            pkg, name = kind[len("sequence<"):].rstrip(">").split("<")[0].split("/")
            cls = registry.message_class(f"{pkg}/msg/{name}")
            setattr(msg, key, [fill(cls(), item, registry, where) for item in value])
        else:
            setattr(msg, key, value)
    return msg


def served_type(name: str) -> str | None:
    """The type the simulation node serves under a service name (``None``: not one of its services)."""
    if name.startswith(f"{NODE}/"):
        return SIM_SERVICES.get(name[len(NODE) + 1:])
    if "/controller_manager/" in name:
        return CONTROLLER_SERVICES.get(name.rsplit("/", 1)[1])
    return None


def service_calls() -> list[tuple[Block, list[str]]]:
    return [(b, argv) for b in all_blocks() if b.lang == "bash" for argv in commands(b)
            if argv[1:3] == ["service", "call"]]


def test_docs_have_ros2_commands():
    calls = service_calls()
    assert len(calls) >= 15, calls
    assert any(b.page == "docs/ros2.md" and b.distro == "rolling" for b, _ in calls)


@pytest.mark.parametrize("index", range(len(service_calls())))
def test_service_call_names_types_and_fields(index):
    block, argv = service_calls()[index]
    name, type_name, *values = positional(argv, 3)
    where = f"{block.where}: {name}"
    expected = served_type(name)
    assert expected is not None, f"{where}: the simulation node serves no such service"
    assert type_name == expected, f"{where}: served as {expected}, the page says {type_name}"
    registry = registry_for(block.distro)
    fill(registry.service_class(type_name).Request(), yaml.safe_load(values[0]) if values else {}, registry, where)


def test_topic_pub_and_action_goal_fields():
    checked = 0
    for block in all_blocks():
        if block.lang != "bash":
            continue
        registry = registry_for(block.distro)
        for argv in commands(block):
            if argv[1:3] == ["topic", "pub"]:
                topic, type_name, values = positional(argv, 3)[:3]
                fill(registry.message_class(type_name)(), yaml.safe_load(values), registry, f"{block.where}: {topic}")
                checked += 1
            elif argv[1:3] == ["action", "send_goal"]:
                name, type_name, values = positional(argv, 3)[:3]
                goal = registry.action_class(type_name).Goal()
                fill(goal, yaml.safe_load(values), registry, f"{block.where}: {name}")
                checked += 1
    assert checked >= 3


@pytest.mark.slow
def test_ros2_page_service_calls_succeed_on_a_node():
    """docs/ros2.md's calls, in order, against a node started as the page starts it (uniros-sim --robot)."""
    from multiros.ros import Context, Node
    from multiros.sim.launch import compose

    calls = [(b, argv) for b in parse(REPO / "docs" / "ros2.md") if b.lang == "bash" for argv in commands(b)
             if argv[1:3] == ["service", "call"]]
    assert len(calls) >= 15
    ctx = Context(transport="inproc").init()
    try:
        sim = compose("mujoco_sim", context=ctx)
        sim.spawn_from_cli("rx200", RX200)
        sim.mark_launched()
        node = Node("ros2_cli", context=ctx)
        for block, argv in calls:
            name, type_name, *values = positional(argv, 3)
            registry = registry_for(block.distro)
            cls = registry.service_class(type_name)
            request = fill(cls.Request(), yaml.safe_load(values[0]) if values else {}, registry, block.where)
            client = node.create_client(cls, name)
            assert client.wait_for_service(timeout_sec=5.0), f"{block.where}: {name} ({block.distro}) not served"
            response = client.call(request, timeout_sec=10.0)
            result = getattr(response, "result", None)
            if hasattr(result, "result"):
                assert result.result == result.RESULT_OK, f"{block.where}: {name}: {result.error_message}"
            if hasattr(response, "ok"):
                assert response.ok, f"{block.where}: {name}: {getattr(response, 'message', '')}"
            node.destroy_client(client)
    finally:
        ctx.try_shutdown()
