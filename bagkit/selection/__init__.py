"""One vocabulary for every command: which topics, which times, which fields, which messages.

- :mod:`bagkit.selection.topics`: topic rules (absolute names, hidden topics, regex,
  exclusions, types), as ``ros2 bag`` selects them.
- :mod:`bagkit.selection.fields`: field paths and the globs that select them.

Nothing here reads a bag or imports rclpy; every command's options pass through these.
"""
