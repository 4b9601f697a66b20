"""ROS-free helpers shared by the actuator packages: parameter specifications and checks."""
