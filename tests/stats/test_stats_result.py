"""Summary's JSON document and DataFrame."""

from __future__ import annotations

from pathlib import Path

from bagkit.selection.query import Query
from bagkit.stats import Summary, summarize


def test_dataframe_has_a_row_per_field(bag: Path) -> None:
    result = summarize([bag], Query.create("/imu/data"))
    frame = result.to_dataframe()
    assert len(frame) == len(result.topics[0].fields)
    row = frame.set_index("field").loc["linear_acceleration.z"]
    field = next(f for f in result.topics[0].fields if f.field == "linear_acceleration.z")
    assert (row["count"], row["mean"], row["std"]) == (field.count, field.mean, field.std)


def test_json_document_has_the_documented_keys(bag: Path) -> None:
    document = summarize([bag]).to_dict()
    assert list(document) == ["bags", "unread", "start_ns", "end_ns", "duration_s", "topics"]
    assert document["unread"] == []
    topic = document["topics"][0]
    assert list(topic) == ["topic", "type", "count", "rate_hz", "undecodable", "fields"]
    assert list(topic["fields"][0]) == ["field", "count", "nan_count", "min", "max", "mean", "std"]


def test_result_is_a_summary(bag: Path) -> None:
    assert isinstance(summarize([bag]), Summary)
