"""ROS-free core: limits and nominal constants, parameter specifications, elementwise math, sample timing, sample protocol, status codes and run metrics (no rclpy, no launch)."""
