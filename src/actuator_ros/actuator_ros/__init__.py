"""rclpy helpers shared by the nodes (the only package of helpers that imports rclpy)."""
