"""Extended state observer of the joint actuator: the ROS-free observer and its node."""
