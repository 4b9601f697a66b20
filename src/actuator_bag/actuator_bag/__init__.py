"""Recording, playback, repair and analysis of rosbag2 (MCAP) bags of the actuator node suite.

ROS-free modules: ``bag_format`` (BagWriter: rosbag2 v9 folder + MCAP file), ``msgdefs``
(full .msg definitions and RIHS01 hashes), ``reading`` (opening bags with rosbags),
``repair`` (``bag_repair``), ``analyze`` (``bag_analyze``), ``progress``, ``errors``.
Nodes (rclpy): ``recorder_node`` (``recorder``), ``player_node`` (``player``), with
``ros_common`` shared between them.
"""
