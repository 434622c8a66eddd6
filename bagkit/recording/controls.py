"""Pause, resume, split and snapshot of a recording in progress: what the recorder's
``~/`` services (:mod:`~bagkit.ros.record.control_services`) and the space key call."""

from __future__ import annotations

from pathlib import Path

from bagkit.bag import BagWriter
from bagkit.recording.errors import RecorderOptionsError
from bagkit.recording.handoff import HandoffQueue
from bagkit.recording.pause import PauseGate
from bagkit.recording.report import SnapshotRecord
from bagkit.recording.snapshot import SnapshotSink
from bagkit.recording.write_loop import WriteLoop


class RecordingControls:
    """The controls of :class:`~bagkit.ros.record.recorder.Recorder`, over the state it sets
    up: the pause gate, the queue to the writer, the writer and its bag."""

    path: Path
    _gate: PauseGate
    _queue: HandoffQueue
    _writer: WriteLoop | None

    @property
    def is_paused(self) -> bool:
        """Whether the recording is paused (messages are taken, counted, not written)."""
        return self._gate.paused

    def pause(self) -> bool:
        """Pause (``~/pause``, the space key); return whether it was recording."""
        return self._gate.set_paused(True)

    def resume(self) -> bool:
        """Resume (``~/resume``); the last latched messages taken meanwhile are written.

        Returns whether it was paused.
        """
        changed = self._gate.set_paused(False)
        self._queue.put_control("wake")  # the writer writes the held latched messages now
        return changed

    def toggle_paused(self) -> None:
        """Pause if recording, resume if paused (the space key)."""
        if not self.pause():
            self.resume()

    def split(self) -> str:
        """Start a new file before the next message (``~/split_bagfile``); return a description.

        Raises:
            RecorderOptionsError: in snapshot mode (each snapshot is a bag of its own).
        """
        bag = self._writer.bag if self._writer is not None else None
        if not isinstance(bag, BagWriter):
            raise RecorderOptionsError("split: no bag file to split (snapshot mode or not started)")
        bag.request_split()
        return f"{self.path}: a new file starts with the next message"

    def snapshot(self, reason: str = "request") -> SnapshotRecord:
        """Trigger a snapshot now, as the ``~/snapshot`` service does (snapshot mode only).

        Returns:
            The snapshot this opened, or the open one it extended (its window grows).

        Raises:
            RecorderOptionsError: not in snapshot mode, or not started.
        """
        sink = self._writer.bag if self._writer is not None else None
        if not isinstance(sink, SnapshotSink):
            raise RecorderOptionsError("snapshots need snapshot mode (options.snapshot), started")
        return sink.request(reason)
