"""Moved to :mod:`multiros.ros.controller_manager` (the ros2_control client belongs to the ROS
layer: Real envs use it without the simulation); this name stays for code written against it."""

from multiros.ros.controller_manager import *  # noqa: F403
from multiros.ros.controller_manager import (  # noqa: F401
    BEST_EFFORT,
    STRICT,
    ControllerManagerClient,
    ControllerManagerError,
    destroy_clients,
)
