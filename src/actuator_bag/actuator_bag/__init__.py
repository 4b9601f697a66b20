"""Recording, playback, repair and analysis of rosbag2 (MCAP) bags of the actuator node suite."""
