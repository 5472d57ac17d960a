"""IRB120 environments on a real robot (ros2_control with a joint trajectory controller)."""
