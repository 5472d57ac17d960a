"""The rclpy transport (see ``transport.py``): uniros nodes in the user's own ROS 2 graph.

Importing this package does not import rclpy; ``RclpyTransport.open`` does (after checking
``RMW_IMPLEMENTATION``, see ``loader.py``).
"""

from multiros.ros.transport.rclpy.loader import rclpy_available
from multiros.ros.transport.rclpy.transport import RclpyTransport
from multiros.ros.transport.rclpy.types import InterfaceMismatchError, MissingInterfacePackageError

__all__ = ["RclpyTransport", "rclpy_available", "MissingInterfacePackageError", "InterfaceMismatchError"]
