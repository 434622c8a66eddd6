"""Pausing a recording: messages taken while paused are counted, not written, not lost.

The take thread goes on taking while paused (so the middleware never holds the messages back
and nothing is lost on resume); the writer thread asks the :class:`PauseGate` about each batch.
A paused batch is counted in ``TopicRecord.paused``; the last message of each latched topic
taken while paused is kept and written on resume, so that the state a latched publisher sent
meanwhile is not missing from the bag (rosbag2 loses it, #1302).
"""

from __future__ import annotations

import threading

from bagkit.bag import TopicInfo
from bagkit.bag.latched import is_transient_local
from bagkit.recording.handoff import BatchPart, TakenMessages


class PauseGate:
    """Whether the recording is paused, and the latched messages taken meanwhile.

    Args:
        paused: start paused (``--start-paused``).
    """

    def __init__(self, *, paused: bool = False) -> None:
        self._lock = threading.Lock()
        self._paused = paused
        self._latched: set[str] = set()
        self._held: dict[str, BatchPart] = {}

    @property
    def paused(self) -> bool:
        """Whether messages are being left out."""
        return self._paused

    def set_paused(self, paused: bool) -> bool:
        """Pause or resume; return whether this changed anything."""
        with self._lock:
            changed = self._paused != paused
            self._paused = paused
            return changed

    def add_topic(self, topic: TopicInfo) -> None:
        """If ``topic`` is latched, keep its last message taken while paused, for the resume."""
        if is_transient_local(topic.offered_qos_profiles):
            with self._lock:
                self._latched.add(topic.name)

    def hold(self, part: BatchPart, sim_time: int | None) -> bool:
        """Whether ``part`` is left out (paused): then counted as paused, a latched one kept.

        ``sim_time``: the batch's log time with ``--use-sim-time``.
        """
        topic, taken = part
        with self._lock:
            if not self._paused:
                return False
            name = topic.record.topic
            topic.record.paused += len(taken)
            if name in self._latched:
                last = len(taken) - 1
                log_time = taken.received[last] if sim_time is None else sim_time
                self._held[name] = (
                    topic,
                    TakenMessages(
                        [taken.payloads[last]],
                        [log_time],
                        [taken.sources[last]],
                        [taken.sequences[last]],
                        len(taken.payloads[last]),
                    ),
                )
            return True

    def release(self) -> list[BatchPart]:
        """After a resume: the latched messages to write (each one is counted ``paused``
        until the writer takes it out)."""
        with self._lock:
            if self._paused or not self._held:
                return []
            held = list(self._held.values())
            self._held.clear()
            return held
