"""Stand-ins for robot hardware: a fake ros2_control robot (``uniros-fake-robot``).

Layer: above :mod:`multiros.sim` (it reuses its numpy controllers, URDF reader and trajectory
action servers, never MuJoCo), below :mod:`multiros.envs`.
"""

from multiros.hardware.fake_hardware import DEFAULT_TIME_CONSTANT, FakeHardware
from multiros.hardware.robot_spec import PRESETS, JointSpec, MimicSpec, RobotSpec, load_robot_spec

__all__ = [
    "DEFAULT_TIME_CONSTANT",
    "FakeHardware",
    "FakeRobot",
    "JointSpec",
    "MimicSpec",
    "PRESETS",
    "RobotSpec",
    "load_robot_spec",
]


def __getattr__(name: str):
    # FakeRobot imports the ROS layer; keep `import multiros.hardware` light.
    if name == "FakeRobot":
        from multiros.hardware.fake_robot import FakeRobot

        return FakeRobot
    raise AttributeError(f"module 'multiros.hardware' has no attribute {name!r}")
