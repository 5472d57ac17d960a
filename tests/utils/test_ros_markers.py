from __future__ import annotations

import time

import numpy as np
import pytest

from multiros.ros import Context, Node, SingleThreadedExecutor
from multiros.utils.ros_markers import Marker, MarkerArray, RosMarker, RosMarkerArray, goal_marker


@pytest.fixture
def graph():
    ctx = Context(transport="inproc").init()
    pub_node, sub_node = Node("markers", context=ctx), Node("viewer", context=ctx)
    got: list = []
    got_arrays: list = []
    sub_node.create_subscription(Marker, "/visualization_marker", got.append, 10)
    sub_node.create_subscription(MarkerArray, "/visualization_marker_array", got_arrays.append, 10)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sub_node)

    def drain():
        for _ in range(20):
            executor.spin_once(timeout_sec=0.05)

    yield pub_node, got, got_arrays, drain
    ctx.try_shutdown()


def test_goal_marker_is_a_world_sphere(graph):
    node, got, _, drain = graph
    goal_marker(node, (0.1, 0.2, 0.3), diameter=0.04)
    drain()
    (msg,) = got
    assert msg.header.frame_id == "world"
    assert msg.type == Marker.SPHERE and msg.action == Marker.ADD
    assert (msg.pose.position.x, msg.pose.position.y, msg.pose.position.z) == (0.1, 0.2, 0.3)
    assert msg.pose.orientation.w == 1.0  # identity, never the zero quaternion
    assert (msg.scale.x, msg.scale.y, msg.scale.z) == (0.04, 0.04, 0.04)
    assert msg.color.g == 1.0 and msg.color.a == pytest.approx(0.8)


def test_multiros_setters_update_and_delete(graph):
    node, got, _, drain = graph
    m = RosMarker(node, "world", "targets", Marker.CUBE, marker_id=7, lifetime=1.5)
    m.set_color(r=0.0, g=0.0, b=1.0)
    m.update(position=(1.0, 2.0, 3.0), orientation=(0.0, 1.0, 0.0, 0.0), a=0.5)
    m.delete()
    drain()
    shown, deleted = got
    assert shown.ns == "targets" and shown.id == 7 and shown.type == Marker.CUBE
    assert (shown.lifetime.sec, shown.lifetime.nanosec) == (1, 500_000_000)
    assert (shown.color.r, shown.color.b, shown.color.a) == (0.0, 1.0, 0.5)
    assert (shown.pose.orientation.w, shown.pose.orientation.x) == (0.0, 1.0)
    assert deleted.action == Marker.DELETE and deleted.id == 7
    m.destroy()


def test_bad_values_refused(graph):
    node = graph[0]
    with pytest.raises(ValueError, match="not a rotation"):
        RosMarker(node, orientation=(0, 0, 0, 0))
    with pytest.raises(ValueError, match="lifetime must be >= 0"):
        RosMarker(node, lifetime=-1)


def test_marker_array(graph):
    node, _, arrays, drain = graph
    arr = RosMarkerArray(node)
    for i in range(3):
        arr.add_marker(RosMarker(node, marker_id=i, position=(i, 0, 0)))
    arr.publish()
    arr.remove_marker(1)
    arr.remove_all_markers()
    drain()
    assert [m.id for m in arrays[0].markers] == [0, 1, 2]
    assert [(m.id, m.action) for m in arrays[1].markers] == [(1, Marker.DELETE)]
    assert arrays[2].markers[0].action == Marker.DELETEALL
    assert arr.markers == [] and arr.get_marker_by_id(0) is None


def _node_renders() -> bool:
    try:
        from multiros.sim.launch import connect

        conn = connect("composed")
        try:
            conn.client.render("", 32, 32)
        finally:
            conn.close()
    except Exception:
        return False
    return True


@pytest.mark.skipif(not _node_renders(), reason="simulation node cannot render here (no GL backend?)")
def test_marker_appears_in_rendered_image():
    from multiros.sim.launch import connect

    conn = connect("composed")
    try:
        before = conn.client.render("", 96, 96).astype(int)
        marker = goal_marker(conn.node, (0.0, 0.0, 0.2), diameter=0.3, color=(1.0, 0.0, 0.0, 1.0))
        deadline = time.monotonic() + 10.0
        changed = 0
        while time.monotonic() < deadline and changed == 0:
            changed = int(np.count_nonzero(np.abs(conn.client.render("", 96, 96).astype(int) - before).sum(-1)))
        assert changed > 0, "the goal marker never showed up in the rendered image"
        marker.delete()
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            if np.array_equal(conn.client.render("", 96, 96).astype(int), before):
                break
        else:
            pytest.fail("the deleted marker stayed in the image")
    finally:
        conn.close()
