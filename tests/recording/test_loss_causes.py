"""The camera-loss line: middleware loss with messages larger than the publisher's segment."""

from __future__ import annotations

from pathlib import Path

from bagkit.bag import BagWriter, TopicInfo
from bagkit.recording.loss_causes import FASTDDS_DEFAULT_SEGMENT, large_message_cause
from bagkit.recording.report import LOSS_CUSTOM_DATA_KEY, TopicRecord, loss_summary
from bagkit.surgery.doctor import diagnose

FRAME = 640 * 480 * 3  # rgb8, 0.9 MB


def test_the_cause_is_named_only_for_middleware_loss_of_large_messages() -> None:
    line = large_message_cause("/camera", 205, 95, 95 * FRAME)
    assert line is not None
    assert line.startswith("/camera: 205 of 300 lost in the middleware with 0.9 MiB messages")
    assert "large_data profile in docs/record.md" in line
    assert large_message_cause("/camera", 0, 95, 95 * FRAME) is None  # nothing lost
    small = FASTDDS_DEFAULT_SEGMENT // 2
    assert large_message_cause("/imu", 205, 95, 95 * small) is None  # small messages


def test_doctor_names_the_cause_from_the_recorders_counts(tmp_path: Path) -> None:
    path = tmp_path / "camera"
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/camera", "std_msgs/msg/String"), definition="string data\n")
        for i in range(3):
            bag.write("/camera", bytes(FRAME), log_time=1_000 + i)
        record = TopicRecord("/camera", "std_msgs/msg/String", messages=3, bytes=3 * FRAME)
        record.gaps = 7
        bag.custom_data[LOSS_CUSTOM_DATA_KEY] = loss_summary([record])
    report = diagnose(path)
    notes = [f.line for f in report.findings if f.note]
    assert notes == ["note: bag: " + str(large_message_cause("/camera", 7, 3, 3 * FRAME))]
    assert report.healthy  # a note: the recording lost messages, the bag is sound
