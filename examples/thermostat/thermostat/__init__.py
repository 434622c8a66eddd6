"""A room thermostat: a PI controller (``core``), its ROS 2 node, and a simulated sensor."""
