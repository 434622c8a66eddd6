"""fusion: the live ROS 2 system bagkit is exercised with.

A simulated flight measured by IMU, GPS, thermometer and barometer (``sensor_publisher``), and the
pipeline that logs (``data_logger``), checks (``alert_system``) and fuses (``sensor_fusion``) it.
Pure cores (``sim``, ``sensors``, ``estimation``, ``faults``, ``alerts``, ``stats``), processors
without rclpy (``processors``), thin rclpy nodes (``nodes``) and the ``fusion`` command (``cli``).
"""
