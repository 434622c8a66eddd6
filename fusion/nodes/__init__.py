"""rclpy nodes: one module per node, each a thin shell over its processor."""
