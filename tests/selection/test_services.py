"""Which event topics the service options select, as rosbag2 Jazzy selects them."""

from __future__ import annotations

from bagkit.recording.options import RecordOptions
from bagkit.selection.services import event_topic, is_service_event_topic, service_name

EVENT = ["std_srvs/srv/Trigger_Event"]


def test_topic_options_never_select_event_topics() -> None:
    selection = RecordOptions(all_topics=True, include_hidden=True, regex="reset").selection
    assert not selection.matches("/reset/_service_event", EVENT)
    assert selection.matches("/_hidden", ["std_msgs/msg/String"])


def test_service_options() -> None:
    selection = RecordOptions(services=("reset",)).selection
    assert selection.matches("/reset/_service_event", EVENT)
    assert not selection.matches("/other/_service_event", EVENT)
    everything = RecordOptions(all_services=True, exclude_services=("/other",)).selection
    assert everything.matches("/reset/_service_event", EVENT)
    assert not everything.matches("/other/_service_event", EVENT)
    assert not everything.matches("/imu", ["sensor_msgs/msg/Imu"])
    excluded = RecordOptions(all_services=True, exclude_regex="res").selection
    assert not excluded.matches("/reset/_service_event", EVENT)


def test_names() -> None:
    assert event_topic("ns/reset") == "/ns/reset/_service_event"
    assert service_name("/ns/reset/_service_event") == "/ns/reset"
    assert not is_service_event_topic("/x/_service_event", ["std_msgs/msg/String"])
