"""Types derived from an ``.action`` (test_msgs/action/Fibonacci): definitions peers decode."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap_ros2._vendor.rosidl_adapter.parser import InvalidResourceName
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from test_msgs.action import Fibonacci

from bagkit.bag import BagWriter, TopicInfo, message_definition
from bagkit.bag.action_definitions import split_action_part
from bagkit.bag.definitions import type_description_hash
from bagkit.bag.errors import UnknownMessageTypeError

ACTION = "test_msgs/action/Fibonacci"
UUID = list(range(16))


def _samples() -> dict[str, bytes]:
    feedback = Fibonacci.Impl.FeedbackMessage()
    feedback.goal_id.uuid = UUID
    feedback.feedback.sequence = [0, 1, 1, 2, 3]
    goal = Fibonacci.Impl.SendGoalService.Request()
    goal.goal_id.uuid = UUID
    goal.goal.order = 7
    result = Fibonacci.Impl.GetResultService.Response(status=4)
    result.result.sequence = [0, 1, 1]
    event = Fibonacci.Impl.SendGoalService.Event()
    event.info.sequence_number = 9
    event.request = [goal]
    return {
        f"{ACTION}_FeedbackMessage": serialize_message(feedback),
        f"{ACTION}_SendGoal_Request": serialize_message(goal),
        f"{ACTION}_GetResult_Response": serialize_message(result),
        f"{ACTION}_SendGoal_Event": serialize_message(event),
    }


def test_peers_decode_action_parts(tmp_path: Path) -> None:
    path = tmp_path / "action"
    samples = _samples()
    with BagWriter(path) as bag:
        for i, (type_name, data) in enumerate(samples.items()):
            bag.add_topic(TopicInfo(f"/t{i}", type_name))
            bag.write(f"/t{i}", data, log_time=i + 1)

    # mcap_ros2 (0.6.0) rejects any type name with '_' (as for service events): the records
    # read, the decoding fails on the name alone (docs/record.md, "Actions").
    with open(path / "action_0.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert {s.name for s in reader.get_summary().schemas.values()} == set(samples)
        assert sum(1 for _ in reader.iter_messages()) == len(samples)
        with pytest.raises(InvalidResourceName, match="Fibonacci_FeedbackMessage"):
            next(iter(reader.iter_decoded_messages()))

    # rosbags with an empty typestore: every type must come from the definitions in the bag.
    with AnyReader([path], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        by_type = {c.msgtype: reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()}
    assert set(by_type) == set(samples)
    assert list(by_type[f"{ACTION}_FeedbackMessage"].feedback.sequence) == [0, 1, 1, 2, 3]
    assert list(by_type[f"{ACTION}_FeedbackMessage"].goal_id.uuid) == UUID
    assert by_type[f"{ACTION}_SendGoal_Request"].goal.order == 7
    assert by_type[f"{ACTION}_GetResult_Response"].status == 4
    assert list(by_type[f"{ACTION}_GetResult_Response"].result.sequence) == [0, 1, 1]
    event = by_type[f"{ACTION}_SendGoal_Event"]
    assert event.info.sequence_number == 9
    assert event.request[0].goal.order == 7


def test_fields_follow_rclpy() -> None:
    """Each part's fields, in order, are those of the class rclpy generates for it."""
    classes = {
        "Goal": Fibonacci.Goal,
        "Result": Fibonacci.Result,
        "Feedback": Fibonacci.Feedback,
        "FeedbackMessage": Fibonacci.Impl.FeedbackMessage,
        "SendGoal_Request": Fibonacci.Impl.SendGoalService.Request,
        "SendGoal_Response": Fibonacci.Impl.SendGoalService.Response,
        "GetResult_Request": Fibonacci.Impl.GetResultService.Request,
        "GetResult_Response": Fibonacci.Impl.GetResultService.Response,
    }
    for part, cls in classes.items():
        root = message_definition(f"{ACTION}_{part}").split("=" * 80)[0]
        names = [
            line.split()[1]
            for line in root.splitlines()
            if line.strip() and not line.lstrip().startswith("#")
        ]
        assert names == list(cls.get_fields_and_field_types()), part
        assert type_description_hash(f"{ACTION}_{part}").startswith("RIHS01_")


def test_names_and_missing_actions() -> None:
    assert split_action_part("Fibonacci_SendGoal_Request") == ("Fibonacci", "SendGoal_Request")
    assert split_action_part("Fibonacci_FeedbackMessage") == ("Fibonacci", "FeedbackMessage")
    assert split_action_part("Fibonacci") is None
    with pytest.raises(UnknownMessageTypeError, match=r"Nope\.action"):
        message_definition("test_msgs/action/Nope_FeedbackMessage")
