"""Simulated deep-sea oil-filled joint actuator: the ROS-free joint model and its plant node."""
