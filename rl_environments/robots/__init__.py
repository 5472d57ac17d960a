"""Robot description packages shipped with the library.

Each subpackage is both a Python package and a ROS description package (``package.xml``,
``urdf/*.urdf.xacro``, ``config/*_controllers.yaml``), found without ROS through the
``uniros.description_packages`` entry points:

* :mod:`rl_environments.robots.rx200_description`: Interbotix ReactorX 200 (5-DOF arm + gripper).
* :mod:`rl_environments.robots.abb_irb120_description`: ABB IRB 120 (6-DOF).
"""
