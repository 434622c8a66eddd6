"""What a replay is, without rclpy: its options and window, timing, lateness, controls, report.

The player itself (:mod:`bagkit.ros.replay`) needs rclpy; these modules do not.
"""
