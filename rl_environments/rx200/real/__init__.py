"""RX200 environments on a real robot (Interbotix ROS 2 driver, ros2_control)."""
