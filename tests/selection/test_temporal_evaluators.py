"""One table of temporal cases run against both evaluators: the numpy one over columns
(bags) and the streaming one fed message by message (the live recorder). The expected
intervals come from how the stream is built; random streams check that both agree."""

from __future__ import annotations

import heapq
from collections.abc import Iterator

import numpy as np
import pytest

from bagkit.selection.condition_syntax import parse_expression
from bagkit.selection.condition_terms import Expression, Path
from bagkit.selection.conditions import Condition, subtree_leaves
from bagkit.selection.streaming import StreamingCondition
from bagkit.selection.temporal import Scope, evaluate, stamps

MS = 1_000_000
PERIOD = 10 * MS
N = 1000
SILENT = range(300, 400)
FROZEN = range(600, 851)
NAN_AT = 900
JUMP_AT = 950
LATE = range(700, 720)  # stamps 300 ms (and 5 us, to be no other message's) behind
SLOW = range(500, 511)  # the source message 80 ms before (30 ms otherwise)
Z = "linear_acceleration.z"


class ArrayData:
    """A topic as columns (what the bag reader gives the numpy evaluator)."""

    def __init__(
        self,
        times: np.ndarray,
        columns: dict[str, np.ndarray],
        sources: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    ) -> None:
        self.log_times = self.arrival_times = times
        self.columns = columns
        self.sources = sources or {}
        self._masks: dict[int, np.ndarray] = {}

    def mask(self, node: Expression) -> np.ndarray:
        if id(node) not in self._masks:
            condition = Condition("", node)
            reads = condition.bulk_columns(list(self.columns))
            assert reads is not None
            with np.errstate(invalid="ignore"):
                self._masks[id(node)] = condition.mask(self.columns, reads)
        return self._masks[id(node)]

    def values(self, path: Path | None) -> np.ndarray:
        names = subtree_leaves(path, list(self.columns))
        return np.stack([self.columns[n].astype(np.float64) for n in names], axis=1)

    def source(self, topic: str, path: Path) -> tuple[np.ndarray, np.ndarray]:
        return self.sources[topic]


class Row:
    """One message of an ArrayData (what the recorder gives the streaming evaluator)."""

    def __init__(self, data: ArrayData, index: int) -> None:
        self.data, self.index = data, index

    def holds(self, node: Expression) -> bool:
        return bool(self.data.mask(node)[self.index])

    def values(self, path: Path | None) -> np.ndarray:
        return self.data.values(path)[self.index]


def built() -> ArrayData:
    kept = np.array([i for i in range(N) if i not in SILENT])
    times = kept * PERIOD
    z = (kept % 7).astype(np.float64) + np.where(kept >= JUMP_AT, 1000.0, 0.0)
    z[np.isin(kept, list(FROZEN))] = 5.0
    z[kept == NAN_AT] = np.nan
    stamp = times - np.where(np.isin(kept, list(LATE)), 300 * MS + 5000, 0)
    columns = {
        Z: z,
        "header.stamp.sec": stamp // 10**9,
        "header.stamp.nanosec": stamp % 10**9,
    }
    delay = np.where(np.isin(kept, list(SLOW)), 80 * MS, 30 * MS)
    source = (times - delay, stamp)
    return ArrayData(times, columns, {"/src": source})


def t(i: int) -> int:
    return i * PERIOD


END = t(N - 1)
CASES = [
    ("gap > 500ms", [(t(299), t(400))]),
    ("gap > 5ms", [(t(0), END)]),
    ("gap < 5ms", []),
    ("rate < 50 Hz over 1s", [(t(250), t(449) - 1)]),
    # 100 messages in (t - 1 s, t] from t = 1 s (the first whole window) until message 200
    # leaves at 3.00 s; again from t = 4.99 s (messages 400..499), whose window starts at 3.99 s.
    ("rate > 99 Hz over 1s", [(t(0), t(300) - 1), (t(399), END)]),
    (f"unchanged({Z}) for 2s", [(t(600), t(850))]),
    (f"unchanged({Z})", [(t(600), t(850))]),
    ("isnan(*)", [(t(NAN_AT), t(NAN_AT))]),
    (f"delta({Z}) > 100", [(t(JUMP_AT), t(JUMP_AT))]),
    ("age(header.stamp) > 200ms", [(t(LATE[0]), t(LATE[-1]))]),
    ("latency(/src -> /imu, header.stamp) > 50ms", [(t(SLOW[0]), t(SLOW[-1]))]),
    (f"{Z} >= 1000 for 300ms", [(t(JUMP_AT), END)]),
    ("gap > 500ms or isnan(*)", [(t(299), t(400)), (t(NAN_AT), t(NAN_AT))]),
    ("not gap > 500ms", [(t(0), t(299) - 1), (t(400) + 1, END)]),
    (
        f"not unchanged({Z}) for 2s and gap < 20ms",
        [(t(0), t(299)), (t(400), t(600) - 1), (t(850) + 1, END)],
    ),
    (f"(unchanged({Z}) or isnan(*)) for 1s", [(t(600), t(850))]),
    ("(gap > 500ms or rate < 50 Hz over 1s) for 1500ms", [(t(250), t(449) - 1)]),
    ("age(header.stamp) > 200ms and rate > 50 Hz over 1s", [(t(LATE[0]), t(LATE[-1]))]),
]


def numpy_intervals(data: ArrayData, text: str, state: bool = False) -> list[tuple[int, int]]:
    scope = Scope("/imu", 0, int(data.log_times[-1]), state)
    found = evaluate(parse_expression(text), data, scope)
    return [(a, b) for a, b in found.tolist()]


def events(data: ArrayData, tick: int | None) -> Iterator[tuple[int, int, str, int]]:
    """(time, order, kind, index): source messages, ticks, then the topic's, in time order."""
    src_times = data.sources.get("/src", (np.zeros(0, np.int64), None))[0]
    streams = [
        ((int(s), 0, "source", i) for i, s in enumerate(src_times)),
        ((int(s), 2, "message", i) for i, s in enumerate(data.log_times)),
    ]
    if tick is not None:
        streams.append((s, 1, "tick", 0) for s in range(0, int(data.log_times[-1]), tick))
    return heapq.merge(*streams)


def streaming_intervals(
    data: ArrayData, text: str, tick: int | None = None, state: bool = False
) -> list[tuple[int, int]]:
    stream = StreamingCondition(parse_expression(text), 0, state=state)
    src_stamps = data.sources.get("/src", (None, np.zeros(0, np.int64)))[1]
    for time, _, kind, index in events(data, tick):
        if kind == "source":
            stream.source("/src", time, int(src_stamps[index]))
        elif kind == "tick":
            stream.advance(time)
        else:
            stream.push(time, Row(data, index))
    return stream.finish(int(data.log_times[-1]))


@pytest.fixture(scope="module")
def data() -> ArrayData:
    return built()


@pytest.mark.parametrize("evaluator", ["numpy", "streaming", "streaming with ticks"])
@pytest.mark.parametrize(("text", "expected"), CASES, ids=[c[0] for c in CASES])
def test_cases(data: ArrayData, evaluator: str, text: str, expected: list[tuple[int, int]]) -> None:
    if evaluator == "numpy":
        found = numpy_intervals(data, text)
    else:
        found = streaming_intervals(data, text, 7 * MS if "ticks" in evaluator else None)
    assert found == expected


def test_state_topic_both_evaluators() -> None:
    times = np.array([0, 2, 4, 7, 8], dtype=np.int64) * 10**9
    level = np.array([0, 2, 0, 2, 0])
    data = ArrayData(times, {"level": level})
    expected = [(2 * 10**9, 4 * 10**9), (7 * 10**9, 8 * 10**9)]
    assert numpy_intervals(data, "level >= 2", state=True) == expected
    assert streaming_intervals(data, "level >= 2", state=True) == expected
    assert streaming_intervals(data, "level >= 2 for 1500ms", state=True) == expected[:1]
    assert numpy_intervals(data, "level >= 2 for 1500ms", state=True) == expected[:1]


RANDOM = [
    "gap > 30ms",
    "gap >= 25ms",
    "gap < 3ms",
    "rate < 80 Hz over 200ms",
    "rate >= 120 Hz over 100ms",
    "unchanged(x) for 30ms",
    "delta(x) > 1",
    "x > 1 for 20ms",
    "not (x > 1) and gap > 15ms",
    "(x > 0 or unchanged(x)) and not rate < 50 Hz over 100ms",
    "(gap > 20ms or delta(x) >= 2) for 10ms",
    "not (unchanged(x) or gap > 30ms)",
]


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("text", RANDOM)
def test_both_evaluators_agree_on_random_streams(seed: int, text: str) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 400))
    steps = rng.choice([1, 5, 10, 10, 10, 12, 40], n) * MS
    times = np.cumsum(steps).astype(np.int64)
    x = rng.choice([0.0, 0.0, 1.0, 2.0, 4.0], n)
    data = ArrayData(times, {"x": x})
    expected = numpy_intervals(data, text)
    assert streaming_intervals(data, text) == expected
    assert streaming_intervals(data, text, tick=int(rng.integers(1, 30)) * MS) == expected


def test_stamps_read_sec_and_nanosec() -> None:
    assert stamps(np.array([[1.0, 5.0]])).tolist() == [1_000_000_005]


@pytest.mark.parametrize(
    ("first", "text"),
    [
        # A bag's log times are untrusted: the last windows end past int64.
        (2**63 - 36 * 10**8, "rate < 80 Hz over 2s"),
        (2**63 - 36 * 10**8, "rate < 70 Hz over 500ms"),
        # A window longer than the bag: none fits.
        (10**18, "rate < 1000 Hz over 2000000h"),
    ],
)
def test_rate_windows_near_the_end_of_int64(first: int, text: str) -> None:
    """The same stream 10^18 ns earlier gives the same windows, shifted; so does streaming."""
    steps = np.where(np.arange(250) % 50 < 40, 10, 30) * MS
    found = []
    for offset in (0, 10**18):
        times = (first - offset + np.cumsum(steps)).astype(np.int64)
        data = ArrayData(times, {"x": np.zeros(len(times))})
        scope = Scope("/imu", int(times[0]), int(times[-1]), False)
        shifted = evaluate(parse_expression(text), data, scope) + offset
        found.append([(a, b) for a, b in shifted.tolist()])
        stream = StreamingCondition(parse_expression(text), int(times[0]))
        for index, time in enumerate(times.tolist()):
            stream.push(time, Row(data, index))
        streamed = [(a + offset, b + offset) for a, b in stream.finish(int(times[-1]))]
        assert found[-1] == streamed
    assert found[0] == found[1]
    assert (found[0] == []) == ("2000000h" in text)
