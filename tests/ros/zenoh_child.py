"""Child process for cross-process tests and benchmarks: a node serving /add and /hang and
echoing /ping to /pong. Run: python tests/ros/zenoh_child.py <router endpoint>. Stopped by PID."""

from __future__ import annotations

import sys
import time

from multiros import ros
from multiros.ros.interfaces import get_message, get_service


def main(argv: list[str]) -> int:
    endpoint = argv[1]
    AddTwoInts = get_service("example_interfaces/srv/AddTwoInts")
    Int64 = get_message("std_msgs/msg/Int64")
    with ros.Context(transport="zenoh", env={}, router="none", router_endpoint=endpoint) as ctx:
        node = ros.Node("child", context=ctx)

        def add(req, res):
            res.sum = req.a + req.b
            return res

        def hang(req, res):
            time.sleep(3600)  # a server that never answers; the parent kills us
            return res

        node.create_service(AddTwoInts, "/add", add)
        node.create_service(AddTwoInts, "/hang", hang)
        pong = node.create_publisher(Int64, "/pong", 1000)
        node.create_subscription(Int64, "/ping", pong.publish, 1000)
        ros.spin(node)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
