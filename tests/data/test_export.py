"""``bagkit export``: Parquet and CSV read back by pandas equal read_dataframe; streaming row
groups; undecodable topics and damaged bags. A real ``bagkit`` process for one export and for
the error exit; the other runs in the test's process (``_run_here``)."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from bagkit_runs import bagkit_in_process
from samples import JAZZY, SAMPLE_TYPES, random_message

import bagkit
from bagkit.bag import BagWriter, TopicInfo
from bagkit.data import export as export_module
from bagkit.data.export import export, topic_path
from bagkit.selection.query import Query

RNG = np.random.default_rng(3)
BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, "export", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def _run_here(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return bagkit_in_process(["export", *args], Path.cwd())


def _frame(bag: Path, topic: str) -> pd.DataFrame:
    return bagkit.read_dataframe(bag, topic).reset_index(drop=True)


def _same_cell(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        left, right = np.asarray(a).tolist(), np.asarray(b).tolist()
        return len(left) == len(right) and all(
            _same_cell(x, y) for x, y in zip(left, right, strict=True)
        )
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def _assert_equal(read: pd.DataFrame, expected: pd.DataFrame) -> None:
    assert list(read.columns) == list(expected.columns)
    assert len(read) == len(expected)
    for column in expected.columns:
        if expected[column].dtype == object:
            pairs = zip(read[column], expected[column], strict=True)
            assert all(_same_cell(a, b) for a, b in pairs), column
        else:
            assert read[column].dtype == expected[column].dtype, column
            assert read[column].equals(expected[column]), column


def test_parquet_per_topic_reads_back_equal(sample_bag: Path, tmp_path: Path) -> None:
    result = _run(sample_bag, "-o", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    for topic in SAMPLE_TYPES:
        path = topic_path(tmp_path / "out", topic, ".parquet")
        assert f"{topic}: 300 rows -> {path}" in result.stdout
        assert pq.ParquetFile(path).metadata.row_group(0).column(0).compression == "ZSTD"
        _assert_equal(pd.read_parquet(path), _frame(sample_bag, topic))


# pandas 2's default CSV float parser can be an ulp off; pandas 3's is exact (and deprecates this).
ROUND_TRIP = {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}


def test_csv_reads_back_equal_with_sequences_as_json(sample_bag: Path, tmp_path: Path) -> None:
    result = _run_here(sample_bag, "-o", tmp_path / "csv", "--format", "csv")
    assert result.returncode == 0, result.stderr
    for topic in SAMPLE_TYPES:
        expected = _frame(sample_bag, topic)
        dtypes = {c: t for c, t in expected.dtypes.items() if t.kind not in "OT"}
        texts = [c for c in expected.columns if c not in dtypes]
        read = pd.read_csv(
            topic_path(tmp_path / "csv", topic, ".csv"),
            dtype={**dtypes, **dict.fromkeys(texts, str)},
            keep_default_na=False,  # an empty string stays one
            **ROUND_TRIP,
            na_values={c: ["nan"] for c, t in dtypes.items() if t.kind == "f"},
        )
        for column in texts:
            if any(isinstance(v, np.ndarray) for v in expected[column]):  # a list: JSON text
                read[column] = [np.array(json.loads(v)) for v in read[column]]
        read = read.astype({c: expected[c].dtype for c in texts if str(expected[c].dtype) == "str"})
        _assert_equal(read, expected)


def test_one_topic_to_one_file_and_datasets_in_parts(
    sample_bag: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    result = _run_here(sample_bag, "-t", "/odom", "-o", tmp_path / "odom.parquet")
    assert result.returncode == 0, result.stderr
    _assert_equal(pd.read_parquet(tmp_path / "odom.parquet"), _frame(sample_bag, "/odom"))
    # In process, with small row groups and parts: streaming writes many of each.
    monkeypatch.setattr(export_module, "ROW_GROUP_ROWS", 64)
    monkeypatch.setattr(export_module, "ROWS_PER_PART", 100)
    report = export(
        sample_bag, tmp_path / "ds", query=Query.create(["/imu", "/scan"]), dataset=True
    )
    assert len(report.files["/imu"]) == 3
    for topic in ("/imu", "/scan"):
        folder = tmp_path / "ds" / topic.strip("/")
        assert pq.ParquetFile(report.files[topic][0]).num_row_groups > 1
        _assert_equal(pd.read_parquet(folder), _frame(sample_bag, topic))


def test_window_fields_and_unknown_names(sample_bag: Path, tmp_path: Path) -> None:
    result = _run_here(
        sample_bag,
        "-o",
        tmp_path / "w",
        "-t",
        "/imu",
        "-t",
        "/fix",
        "-f",
        "header.stamp.*",
        "--start",
        "0.1",
        "--end",
        "0.2",
    )
    assert result.returncode == 0, result.stderr
    imu = pd.read_parquet(tmp_path / "w" / "imu.parquet")
    expected = bagkit.read_dataframe(sample_bag, "/imu", ["header.stamp.*"], start=0.1, end=0.2)
    _assert_equal(imu, expected.reset_index(drop=True))
    assert list(imu.columns) == [
        "log_time",
        "publish_time",
        "header.stamp.sec",
        "header.stamp.nanosec",
    ]
    result = _run_here(sample_bag, "-o", tmp_path / "x", "-t", "/nope")
    assert result.returncode == 2 and result.stderr.startswith(
        "error: topic /nope not in the bag (it has /diagnostics"
    )
    result = _run_here(sample_bag, "-o", tmp_path / "x.csv")
    assert result.returncode == 2 and "give a directory" in result.stderr


def test_undecodable_topic_is_skipped_with_one_warning(tmp_path: Path) -> None:
    bag = tmp_path / "mixed"
    typename = "sensor_msgs/msg/Temperature"
    temperature = bytes(JAZZY.serialize_cdr(random_message(JAZZY, typename, RNG), typename))
    with BagWriter(bag) as writer:
        writer.add_topic(
            TopicInfo("/blob", "acme_msgs/msg/Blob"), definition="int32 x\nbogus_t y\n"
        )
        writer.add_topic(TopicInfo("/temperature", "sensor_msgs/msg/Temperature"))
        for i in range(5):
            writer.write("/blob", b"\x00\x01\x00\x00" + bytes(8), log_time=i)
            writer.write("/temperature", temperature, log_time=i)
    result = _run_here(bag, "-o", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and warnings[0].startswith("warning: topic /blob skipped: ")
    assert "acme_msgs/msg/Blob" in warnings[0]
    assert len(pd.read_parquet(tmp_path / "out" / "temperature.parquet")) == 5
    assert not (tmp_path / "out" / "blob.parquet").exists()


def test_topic_of_which_no_message_decodes_is_an_error_and_an_empty_file(
    tmp_path: Path,
) -> None:
    bag = tmp_path / "garbage"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/t", "sensor_msgs/msg/Temperature"))
        for i in range(5):
            writer.write("/t", b"\x00\x01\x00\x00" + bytes([i]) * 3, log_time=i)
    for suffix in (".parquet", ".csv"):
        out = tmp_path / f"t{suffix}"
        result = _run(bag, "-o", out)
        assert result.returncode == 2, result.stderr
        assert "internal error" not in result.stderr and "Traceback" not in result.stderr
        warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
        assert len(warnings) == 1, result.stderr
        assert "/t: 5 messages could not be decoded" in warnings[0]
        assert result.stderr.splitlines()[-1] == "error: none of the 5 messages of /t decode"
        read = pd.read_parquet(out) if suffix == ".parquet" else pd.read_csv(out)
        assert len(read) == 0 and "temperature" in read.columns


def test_damaged_bag_exports_what_is_intact_and_says_what_was_lost(
    sample_bag: Path, tmp_path: Path
) -> None:
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    [file] = sample_bag.glob("*.mcap")
    data = file.read_bytes()
    (damaged / file.name).write_bytes(data[: len(data) * 2 // 3])
    result = _run_here(damaged, "-o", tmp_path / "out", "-t", "/imu")
    assert result.returncode == 0, result.stderr
    assert "warning: lost: " in result.stderr and "truncated" in result.stderr
    read = pd.read_parquet(tmp_path / "out" / "imu.parquet")
    full = _frame(sample_bag, "/imu")
    assert 0 < len(read) < len(full)
    _assert_equal(read, full.iloc[: len(read)].reset_index(drop=True))
    shutil.rmtree(damaged)
