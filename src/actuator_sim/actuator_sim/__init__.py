"""ROS-free closed loop, scenarios, offline simulation, stability analysis and the late-command study."""
