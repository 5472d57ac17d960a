"""Robot description packages shipped with the library.

Each subpackage is both a Python package and a ROS description package (``package.xml``,
``urdf/*.urdf.xacro``, ``config/*_controllers.yaml``), found without ROS through the
``uniros.description_packages`` entry points:

* :mod:`rl_environments.robots.rx200_description`: Interbotix ReactorX 200 (5-DOF arm + gripper).
* :mod:`rl_environments.robots.abb_irb120_description`: ABB IRB 120 (6-DOF).
* :mod:`rl_environments.robots.vx300s_description`: Interbotix ViperX 300 6DOF (6-DOF arm + gripper).
* :mod:`rl_environments.robots.ur5e_description`: Universal Robots UR5e (6-DOF) with a 2F-85-like gripper.
* :mod:`rl_environments.robots.ned2_description`: Niryo Ned2 (6-DOF) with its standard gripper.
"""
