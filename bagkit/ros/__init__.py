"""Everything in bagkit that needs a ROS 2 runtime (rclpy): recorder, player, QoS and types."""
