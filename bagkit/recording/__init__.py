"""What a recording is, without rclpy: its options, its report, loss accounting.

The recorder itself (:mod:`bagkit.ros.record`) needs rclpy; these modules do not, so the CLI,
reports and tests use them without starting ROS.
"""
