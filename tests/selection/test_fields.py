"""The one field-path glob language, and both of its users (stats and compare) held to it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bagkit.compare.options import CompareOptions, Tolerance, ToleranceRule
from bagkit.selection.fields import FieldSelection, name_matches, path_matches, split_pattern
from bagkit.selection.query import Query
from bagkit.stats import summarize
from tests.stats.rosbags_oracle import imu_data, scan_data, write_bag

# (glob, path, selected)
RULES = [
    ("linear_acceleration.x", "linear_acceleration.x", True),
    ("linear_acceleration.?", "linear_acceleration.z", True),
    ("linear_acceleration.?", "linear_acceleration_covariance[0]", False),
    ("*.x", "angular_velocity.x", True),
    ("*", "header.stamp.sec", True),  # * crosses dots and brackets
    ("*_covariance[4]", "orientation_covariance[4]", True),
    ("orientation_covariance[4]", "orientation_covariance[40]", False),
    ("orientation_covariance[1]", "orientation_covariance[1]", True),
    ("orientation_covariance[?]", "orientation_covariance[8]", True),
    ("covariance[0]", "orientation_covariance[0]", False),  # the whole path, not a suffix
    ("ranges[]", "ranges[]", True),  # brackets are literal, not a character set
    ("ranges[]", "ranges", False),
    ("[ab]", "a", False),
    ("[ab]", "[ab]", True),
    # A message, an array or a sequence selects every leaf below it.
    ("header", "header.stamp.sec", True),
    ("header", "header_extra", False),
    ("header.stamp", "header.stamp.nanosec", True),
    ("orientation_covariance", "orientation_covariance[8]", True),
    ("status", "status[].level", True),
    ("status[]", "status[].values[].key", True),
    ("status[].values", "status[].values[].key", True),
    ("stat", "status[].level", False),
    ("*_covariance", "linear_acceleration_covariance[2]", True),
]


@pytest.mark.parametrize(("glob", "path", "selected"), RULES)
def test_field_globs(glob: str, path: str, selected: bool) -> None:
    assert path_matches(path, glob) is selected
    assert FieldSelection([glob]).for_topic("/t")(path) is selected
    assert FieldSelection([f"/t:{glob}"]).selects("/t", path) is selected


def test_topic_globs_match_whole_names() -> None:
    assert name_matches("/imu/data", "/imu/*")
    assert name_matches("/imu/data", "*")
    assert not name_matches("/imu/data", "/imu")  # topics have no subtrees
    assert not name_matches("/imu/data_raw", "/imu/dat?")
    assert split_pattern("/imu/*:linear_acceleration") == ("/imu/*", "linear_acceleration")
    assert split_pattern("header") == ("*", "header")
    assert split_pattern(":x") == ("*", "x") and split_pattern("/t:") == ("/t", "*")


def test_a_selection_restricted_to_topics() -> None:
    selection = FieldSelection(["/imu/*:header", "ranges[]"])
    on_imu, on_scan = selection.for_topic("/imu/data"), selection.for_topic("/scan")
    assert on_imu("header.frame_id") and on_imu("ranges[]")
    assert not on_scan("header.frame_id") and on_scan("ranges[]")
    assert FieldSelection([]).for_topic("/x")("anything")
    assert not FieldSelection([]).selects("/x", "anything")
    assert not FieldSelection(["/other:*"]).for_topic("/x")("anything")


@pytest.mark.parametrize(("glob", "path", "selected"), RULES)
def test_compare_uses_the_same_rules(glob: str, path: str, selected: bool) -> None:
    options = CompareOptions(
        ignore_fields=(f"/t:{glob}",),
        rules=(ToleranceRule("/t", glob, Tolerance(atol=1.0)),),
    )
    assert options.is_ignored("/t", path) is selected
    assert options.is_ignored("/other", path) is False
    assert (options.tolerance_for("/t", path).atol == 1.0) is selected


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rng = np.random.default_rng(4)
    topics = {"/imu": imu_data(rng, 20), "/scan": scan_data(rng, 5)}
    return write_bag(tmp_path_factory.mktemp("paths") / "bag", topics)


def test_stats_uses_the_same_rules(bag: Path) -> None:
    """Every leaf stats reports is one the selection selects, and every selected one is there."""
    everything = {t.topic: [f.field for f in t.fields] for t in summarize([bag]).topics}
    patterns = ["/imu:*_covariance", "header.stamp", "ranges[]", "/scan:angle_?i?"]
    result = summarize([bag], Query.create(fields=patterns))
    selection = FieldSelection(patterns)
    reported = {t.topic: [f.field for f in t.fields] for t in result.topics}
    assert reported == {
        topic: [p for p in paths if selection.selects(topic, p)]
        for topic, paths in everything.items()
    }
    assert len(reported["/imu"]) == 2 + 27 and reported["/scan"] == [
        "header.stamp.sec",
        "header.stamp.nanosec",
        "angle_min",
        "ranges[]",
    ]
