"""Everything in bagkit that needs a ROS 2 runtime (rclpy).

``record/`` holds the recorder, ``replay/`` the player; this package holds what both use: the
clock, QoS, the graph, serialization, message classes, errors and the process tuning.
"""
