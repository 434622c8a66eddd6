"""Loss inside the middleware: holes in publication sequence numbers (pure, no rclpy)."""

from __future__ import annotations

from collections.abc import Callable


class SequenceTracker:
    """Count holes in publication sequence numbers of one topic's publishers.

    rclpy does not give the publisher of a message (rmw's ``publisher_gid`` is not in the
    message info), so the messages are attributed to *streams*: a number that continues a
    stream extends it; otherwise, while there are fewer streams than matched publishers, it
    starts a new one (a publisher's first message after matching is not a loss); otherwise the
    stream it skipped ahead from (the highest number below it) counts the hole. A number below
    every stream is a publisher that restarted. Exact with one publisher; with several whose
    numbers run close to each other, a lossy stretch can be attributed to the wrong stream and
    the count be off by a few (an estimate, never a silent zero).
    """

    __slots__ = ("_hot", "_last", "publishers")

    def __init__(self) -> None:
        self._last: list[int] = []
        self._hot = 0  # the stream that advanced last: where the next number most likely goes
        self.publishers = 0

    def observe(self, sequence: int, matched_publishers: Callable[[], int]) -> int:
        """Account for one received ``sequence`` number; return how many messages were skipped.

        ``matched_publishers`` is asked only when the number does not continue a stream.
        """
        last = self._last
        hot = self._hot
        if last and last[hot] + 1 == sequence:
            last[hot] = sequence
            return 0
        for i, previous in enumerate(last):
            if sequence == previous + 1:
                last[i] = sequence
                self._hot = i
                return 0
        if len(last) < max(1, matched_publishers()):
            last.append(sequence)
            self._hot = len(last) - 1
            self.publishers = max(self.publishers, len(last))
            return 0
        below = [(previous, i) for i, previous in enumerate(last) if previous < sequence]
        if not below:
            # Restarted publisher (numbers start again), or a duplicate: nothing lost.
            self._hot = last.index(max(last))
            last[self._hot] = sequence
            return 0
        previous, self._hot = max(below)
        last[self._hot] = sequence
        return sequence - previous - 1

    def observe_many(self, sequences: list[int], matched_publishers: Callable[[], int]) -> int:
        """Account for received ``sequences`` in order (0: unknown, skipped); return the skipped.

        The common case, a run that continues the last stream without a hole, costs one list
        comparison instead of a call per number.
        """
        last = self._last
        if sequences and last:
            expected = last[self._hot] + 1
            if sequences == list(range(expected, expected + len(sequences))):
                last[self._hot] = sequences[-1]
                return 0
        observe = self.observe
        return sum(observe(sequence, matched_publishers) for sequence in sequences if sequence)
