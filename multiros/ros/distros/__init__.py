"""ROS 2 interface definitions that differ between distributions, one folder per distribution
(upstream release files; licences in each package.xml/LICENSE)."""
