"""Node loggers: standard ``logging`` loggers with rclpy's method names added."""

from __future__ import annotations

import logging as _logging

__all__ = ["RosLogger", "get_logger"]


class RosLogger(_logging.LoggerAdapter):
    """A ``logging.Logger`` adapter that also answers rclpy's ``warn`` and ``fatal``."""

    def warn(self, msg: object, *args: object, **kwargs: object) -> None:  # noqa: D102
        self.warning(msg, *args, **kwargs)

    def fatal(self, msg: object, *args: object, **kwargs: object) -> None:  # noqa: D102
        self.critical(msg, *args, **kwargs)

    def get_child(self, name: str) -> RosLogger:
        """A logger for a sub-component (``node.sub``)."""
        return RosLogger(self.logger.getChild(name), {})


def get_logger(name: str) -> RosLogger:
    """The logger for a ROS name (``/ns/node`` -> ``ros.ns.node``)."""
    dotted = ".".join(p for p in name.split("/") if p)
    return RosLogger(_logging.getLogger(f"ros.{dotted}" if dotted else "ros"), {})
