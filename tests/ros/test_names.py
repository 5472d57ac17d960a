"""ROS name validation, expansion and remapping."""

from __future__ import annotations

import pytest

from multiros import ros
from multiros.ros.names import expand_topic_name, normalize_namespace, parse_ros_arguments, resolve_name

EXPANSIONS = [
    # name, node, namespace, expected
    ("chatter", "talker", "/", "/chatter"),
    ("chatter", "talker", "/ns", "/ns/chatter"),
    ("/chatter", "talker", "/ns", "/chatter"),
    ("~", "talker", "/ns", "/ns/talker"),
    ("~/state", "talker", "/", "/talker/state"),
    ("~/state", "talker", "/a/b", "/a/b/talker/state"),
    ("sub/topic", "talker", "/a", "/a/sub/topic"),
    ("{node}/x", "talker", "/a", "/a/talker/x"),
    ("{ns}/x", "talker", "/a", "/a/x"),
]


@pytest.mark.parametrize(("name", "node", "ns", "expected"), EXPANSIONS)
def test_expand_topic_name(name: str, node: str, ns: str, expected: str) -> None:
    assert expand_topic_name(name, node, ns) == expected


@pytest.mark.parametrize("bad", ["", "a//b", "a/", "1abc", "/a/2b", "a b", "~x", "a/~", "{foo}"])
def test_invalid_topic_names_raise(bad: str) -> None:
    with pytest.raises(ros.InvalidTopicNameException):
        expand_topic_name(bad, "node", "/")


def test_invalid_name_message_points_at_character() -> None:
    with pytest.raises(ros.InvalidTopicNameException) as info:
        expand_topic_name("bad-name", "node", "/")
    assert "bad-name" in str(info.value) and "^" in str(info.value)


@pytest.mark.parametrize(("ns", "expected"), [(None, "/"), ("", "/"), ("robot", "/robot"), ("/a/b", "/a/b")])
def test_normalize_namespace(ns: str | None, expected: str) -> None:
    assert normalize_namespace(ns) == expected


@pytest.mark.parametrize("bad", ["/a/", "/a//b", "/1a", "/a-b"])
def test_invalid_namespace(bad: str) -> None:
    with pytest.raises(ros.InvalidNamespaceException):
        normalize_namespace(bad)


@pytest.mark.parametrize("bad", ["", "1node", "no-de", "a/b"])
def test_invalid_node_names(ctx: ros.Context, bad: str) -> None:
    with pytest.raises(ros.InvalidNodeNameException):
        ros.Node(bad, context=ctx)


def test_remap_rules_apply_first_match() -> None:
    args = parse_ros_arguments(["prog", "--ros-args", "-r", "chatter:=/talk", "-r", "/ns/x:=y", "--", "user"])
    assert resolve_name("chatter", "n", "/ns", args) == "/talk"
    assert resolve_name("x", "n", "/ns", args) == "/ns/y"
    assert resolve_name("other", "n", "/ns", args) == "/ns/other"


def test_node_name_namespace_and_topic_remap(ctx: ros.Context) -> None:
    node = ros.Node("orig", context=ctx, namespace="/a",
                    cli_args=["--ros-args", "-r", "__node:=renamed", "-r", "__ns:=/y", "-r", "cmd:=/robot/cmd"])
    assert node.get_name() == "renamed"
    assert node.get_namespace() == "/y"
    assert node.get_fully_qualified_name() == "/y/renamed"
    pub = node.create_publisher(object, "cmd", 10)
    assert pub.topic_name == "/robot/cmd"
    assert node.create_publisher(object, "~/state", 10).topic_name == "/y/renamed/state"


def test_node_specific_remap_only_affects_that_node(ctx: ros.Context) -> None:
    ros_args = ["--ros-args", "-r", "a:__node:=alpha"]
    ctx.arguments = parse_ros_arguments(ros_args)
    assert ros.Node("a", context=ctx).get_name() == "alpha"
    assert ros.Node("b", context=ctx).get_name() == "b"


def test_global_arguments_from_init() -> None:
    with ros.Context(env={}) as context:
        context.shutdown()
        context.init(["--ros-args", "-r", "__ns:=/global"])
        assert ros.Node("n", context=context).get_namespace() == "/global"
        node = ros.Node("m", context=context, use_global_arguments=False)
        assert node.get_namespace() == "/"
