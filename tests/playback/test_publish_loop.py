"""The publishing loop's count of what went out, when Ctrl-C interrupts a pass."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from bagkit.bag import BagMessage
from bagkit.playback.controls import PlayControls
from bagkit.playback.lateness import LatenessSamples
from bagkit.playback.publish_loop import PassPublisher

START_NS = 1_700_000_000_000_000_000


class InterruptedOutput:
    """An output whose ``interrupt_at``-th publish sends its message and then raises
    KeyboardInterrupt, as Python raises a Ctrl-C that came during a call into C."""

    def __init__(self, interrupt_at: int) -> None:
        self.count = 0
        self.sent: list[bytes] = []
        self._interrupt_at = interrupt_at

    @property
    def publish(self) -> Callable[[bytes], None]:
        return self._publish

    def _publish(self, data: bytes) -> None:
        self.sent.append(data)
        if len(self.sent) == self._interrupt_at:
            raise KeyboardInterrupt


class Latched:
    """The pass reader's part the pass uses: latched state before a time, and the end."""

    def __init__(self, latched: list[BagMessage]) -> None:
        self._latched = latched
        self.end_ns = START_NS + 10**9

    def latched_before(self, bag_ns: int) -> Iterator[BagMessage]:
        return iter(self._latched)


def _message(i: int) -> BagMessage:
    return BagMessage("/a", bytes([i]), START_NS + i * 1_000, START_NS + i * 1_000, i)


@pytest.mark.parametrize(("latched", "interrupt_at"), [(0, 3), (2, 1), (2, 4)])
def test_a_message_out_as_ctrl_c_is_raised_is_counted(latched: int, interrupt_at: int) -> None:
    output = InterruptedOutput(interrupt_at)
    publisher = PassPublisher(
        {"/a": output},
        None,
        controls=PlayControls(rate=1e6),
        clock_hz=None,
        lateness=LatenessSamples(),
        on_progress=None,
        progress_period_ns=10**9,
        loop=0,
        reader=Latched([_message(100 + i) for i in range(latched)]),  # type: ignore[arg-type]
    )
    with pytest.raises(KeyboardInterrupt):
        publisher.run(iter([_message(i) for i in range(10)]), START_NS)
    assert len(output.sent) == interrupt_at
    assert output.count == interrupt_at
    assert publisher.latched == min(latched, interrupt_at)
