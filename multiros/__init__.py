"""MultiROS-style ROS 2 environments on a MuJoCo simulation node.

Layers (each imports only the ones before it): ``multiros.ros`` (ROS 2 client layer),
``multiros.sim`` (the MuJoCo simulation node), ``multiros.envs`` (gymnasium base envs),
``multiros.utils`` and ``multiros.wrappers``.
"""

__version__ = "0.1.0"
