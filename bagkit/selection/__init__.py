"""One vocabulary for every command: which topics, which times, which fields, which messages.

- :mod:`bagkit.selection.topics`: topic rules (absolute names, hidden topics, regex,
  exclusions, types), as ``ros2 bag`` selects them.
- :mod:`bagkit.selection.fields`: field paths and the globs that select them.
- :mod:`bagkit.selection.times` and :mod:`bagkit.selection.windows`: one grammar for times
  and durations, and ``--start``/``--end`` resolved against each bag.
- :mod:`bagkit.selection.condition_syntax` and :mod:`bagkit.selection.conditions`: the
  ``--where`` language, parsed (never eval'd) and evaluated on messages or numpy columns.
- :mod:`bagkit.selection.services` and :mod:`bagkit.selection.actions`: the hidden topics
  that services and actions are recorded on.

Nothing here reads a bag or imports rclpy; every command's options pass through these.
"""
