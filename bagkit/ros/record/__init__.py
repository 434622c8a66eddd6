"""The recorder (:class:`~bagkit.ros.record.recorder.Recorder`): take thread, writer thread and
the queue between them."""
