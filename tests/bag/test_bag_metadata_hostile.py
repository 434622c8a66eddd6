"""metadata.yaml as untrusted input: limits, types, paths; one clean error each, real bags kept."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from bagkit.bag import BagReader, NotABagError, safe_yaml
from bagkit.bag.metadata import MAX_METADATA_BYTES, parse_metadata, read_metadata

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
ROOT = "rosbag2_bagfile_information"
Change = Callable[[dict[str, object]], None]


def _edit(bag: Path, change: Callable[[dict[str, object]], None]) -> None:
    """Load the bag's metadata.yaml (written by BagWriter), change its root mapping, write it."""
    path = bag / "metadata.yaml"
    document = yaml.safe_load(path.read_text())
    change(document[ROOT])
    path.write_text(yaml.safe_dump(document, sort_keys=False))


def _set(key: str, value: object) -> Callable[[dict[str, object]], None]:
    return lambda root: root.__setitem__(key, value)


def _set_topic(key: str, value: object) -> Callable[[dict[str, object]], None]:
    def change(root: dict[str, object]) -> None:
        topics = root["topics_with_message_count"]
        assert isinstance(topics, list)
        topics[0]["topic_metadata"][key] = value

    return change


# (mutation, what the error must name): every field read, each with a wrong type or value.
WRONG_FIELDS = [
    (_set("message_count", float("inf")), "message_count: expected an integer"),
    (_set("message_count", float("nan")), "message_count: expected an integer"),
    (_set("message_count", "many"), "message_count: expected an integer"),
    (_set("message_count", -1), "message_count: -1 out of range"),
    (_set("message_count", 1 << 64), "out of range"),
    (_set("message_count", True), "message_count: expected an integer"),
    (_set("duration", {"nanoseconds": "abc"}), "duration.nanoseconds: expected an integer"),
    (_set("duration", [1, 2]), "duration: expected an integer"),
    (_set("starting_time", {"nanoseconds_since_epoch": 1.5}), "starting_time.nanoseconds"),
    (_set("version", "nine"), "version: expected an integer"),
    (_set("storage_identifier", ["mcap"]), "storage_identifier: expected a string"),
    (_set("relative_file_paths", {"a": 1}), "relative_file_paths: expected a list"),
    (_set("relative_file_paths", [["x"]]), "relative_file_paths[0]: expected a string"),
    (_set("topics_with_message_count", "all"), "topics_with_message_count: expected a list"),
    (_set("topics_with_message_count", [[]]), "topics_with_message_count[0]: expected a mapping"),
    (_set("topics_with_message_count", [{"topic_metadata": {}}]), "name or type missing"),
    (_set_topic("name", {"a": 1}), "topic_metadata.name: expected a string"),
    (_set_topic("type", [1]), "topic_metadata.type: expected a string"),
    (_set_topic("offered_qos_profiles", b"\x00"), "offered_qos_profiles: expected a string"),
    (_set("files", [{"path": "x.mcap", "message_count": "1e3"}]), "files[0].message_count"),
    (_set("files", [{"path": {"x": 1}}]), "files[0].path: expected a string"),
    (_set("custom_data", ["a"]), "custom_data: expected a mapping"),
    (_set("custom_data", {"k": {"nested": 1}}), "custom_data['k']: expected a string"),
    (_set("compression_format", {"zstd": 1}), "compression_format: expected a string"),
]


@pytest.mark.parametrize(("change", "expected"), WRONG_FIELDS)
def test_wrong_types_and_values_are_one_clean_error(
    write_sample_bag: Callable[..., Path],
    change: Callable[[dict[str, object]], None],
    expected: str,
) -> None:
    bag = write_sample_bag(n_imu=5)
    _edit(bag, change)
    with pytest.raises(NotABagError, match="malformed rosbag2 metadata") as info:
        BagReader(bag).open()
    assert expected in str(info.value)
    assert str(bag / "metadata.yaml") in str(info.value)


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        ("/etc/passwd", "not a path inside the bag directory"),
        ("../other/other_0.mcap", "not a path inside the bag directory"),
        ("sub/../../x.mcap", "not a path inside the bag directory"),
        ("", "not a path inside the bag directory"),
        ("a\x00.mcap", "not a path inside the bag directory"),
    ],
)
def test_listed_paths_leaving_the_bag_are_refused(
    write_sample_bag: Callable[..., Path], path: str, expected: str
) -> None:
    bag = write_sample_bag(n_imu=5)
    _edit(bag, _set("relative_file_paths", [path]))
    with pytest.raises(NotABagError, match=expected):
        BagReader(bag).open()


def test_a_file_listed_twice_is_read_once(write_sample_bag: Callable[..., Path]) -> None:
    bag = write_sample_bag(n_imu=5)
    _edit(bag, _set("relative_file_paths", ["sample_0.mcap", "./sample_0.mcap"]))
    with BagReader(bag) as reader:
        assert reader.topic_counts == {"/imu/data": 5, "/text": 1}
        assert len(list(reader.messages())) == 6
    doctor = subprocess.run(
        [BAGKIT, "doctor", str(bag)], capture_output=True, text=True, timeout=60, check=False
    )
    assert doctor.returncode == 1, doctor.stdout
    assert "lists sample_0.mcap 2 times" in doctor.stdout


def test_a_listed_symlink_to_outside_is_refused(
    write_sample_bag: Callable[..., Path], tmp_path: Path
) -> None:
    bag = write_sample_bag(n_imu=5)
    outside = tmp_path / "outside.mcap"
    (bag / "sample_0.mcap").rename(outside)
    (bag / "sample_0.mcap").symlink_to(outside)
    with pytest.raises(NotABagError, match=r"'sample_0\.mcap' resolves outside"):
        BagReader(bag).open()


def test_a_symlink_inside_the_bag_and_a_linked_bag_directory_are_read(
    write_sample_bag: Callable[..., Path], tmp_path: Path
) -> None:
    bag = write_sample_bag(n_imu=5)
    (bag / "data").mkdir()
    (bag / "sample_0.mcap").rename(bag / "data" / "real.mcap")
    (bag / "sample_0.mcap").symlink_to(Path("data") / "real.mcap")
    linked = tmp_path / "linked"
    linked.symlink_to(bag)
    with BagReader(linked) as reader:
        assert reader.message_count == 5 + 1


def test_a_symlink_loop_is_one_clean_error(write_sample_bag: Callable[..., Path]) -> None:
    bag = write_sample_bag(n_imu=5)
    (bag / "sample_0.mcap").unlink()
    (bag / "sample_0.mcap").symlink_to("loop.mcap")
    (bag / "loop.mcap").symlink_to("sample_0.mcap")
    with pytest.raises(NotABagError, match="cannot resolve the listed files"):
        BagReader(bag).open()


def test_quoted_integers_and_plain_scalars_are_accepted() -> None:
    text = f"""{ROOT}:
  version: "5"
  storage_identifier: mcap
  relative_file_paths: [sub/a_0.mcap]
  message_count: "12"
  duration: {{nanoseconds: 7}}
  starting_time: {{nanoseconds_since_epoch: 9223372036854775807}}
  topics_with_message_count:
    - topic_metadata: {{name: 123, type: pkg/msg/T, offered_qos_profiles: [{{depth: 1}}]}}
      message_count: 3
  custom_data: {{lost: 0, when: 2024-01-02}}
"""
    metadata = parse_metadata(text)
    assert (metadata.version, metadata.message_count, metadata.duration) == (5, 12, 7)
    assert metadata.starting_time == (1 << 63) - 1
    topic, count = metadata.topics[0]
    assert (topic.name, count) == ("123", 3)
    assert yaml.safe_load(topic.offered_qos_profiles) == [{"depth": 1}]
    assert metadata.custom_data == {"lost": "0", "when": "2024-01-02"}


def _nested(depth: int) -> str:
    return f"{ROOT}: " + "[" * depth


def _alias_bomb() -> str:
    """Nine levels of nine references: 1.9 KB that describe 9**9 strings once expanded."""
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 10)]
    lines.append(f"{ROOT}: {{storage_identifier: mcap, custom_data: {{bomb: *a9}}}}")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (_nested(30_000), "YAML refused: nested deeper than 64 levels"),
        (_alias_bomb(), "YAML refused: alias \\*a0"),
        ("[" + "a," * (safe_yaml.MAX_YAML_NODES + 1) + "]", "YAML refused: more than"),
        (f"{ROOT}: {{storage_identifier: mcap, starting_time: 2024-99-99}}", "not valid YAML"),
        (f"{ROOT}: {{storage_identifier: mcap, version: {'9' * 5000}}}", "not valid YAML"),
        (f"{ROOT}: {{storage_identifier: !!python/name:os.system x}}", "not valid YAML"),
        (f"{ROOT}: {{storage_identifier: [unclosed}}", "not valid YAML"),
        ("just a string", "not rosbag2 metadata"),
    ],
    ids=["nested", "alias-bomb", "nodes", "bad-date", "huge-int", "unsafe-tag", "syntax", "scalar"],
)
def test_yaml_beyond_limits_is_one_clean_error(text: str, expected: str) -> None:
    with pytest.raises(NotABagError, match=expected) as info:
        parse_metadata(text)
    assert "\n" not in str(info.value)


def test_non_utf8_and_oversized_files_are_refused_before_parsing(
    write_sample_bag: Callable[..., Path],
) -> None:
    bag = write_sample_bag(n_imu=5)
    path = bag / "metadata.yaml"
    path.write_bytes(path.read_bytes() + b"# \xff\n")
    with pytest.raises(NotABagError, match=r"not UTF-8 \(byte \d+\)"):
        read_metadata(bag)
    path.write_bytes(b"#" * (MAX_METADATA_BYTES + 1))
    with pytest.raises(NotABagError, match=f"larger than {MAX_METADATA_BYTES} bytes"):
        read_metadata(bag)


@pytest.mark.parametrize("case", ["nested", "alias-bomb"])
def test_every_reading_command_ends_with_one_error_line(
    write_sample_bag: Callable[..., Path], case: str
) -> None:
    """The two inputs that crashed (SIGSEGV) or hung the process, through the real CLI."""
    bag = write_sample_bag(n_imu=5)
    good = write_sample_bag("good", n_imu=5)
    (bag / "metadata.yaml").write_text(_nested(30_000) if case == "nested" else _alias_bomb())
    env = {**os.environ, "COLUMNS": "200"}
    commands = (
        ["info", str(bag)],
        ["stats", "summary", str(bag)],
        ["compare", str(good), str(bag)],
    )
    for args in commands:
        run = subprocess.run(
            [BAGKIT, *map(str, args)],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
            env=env,
        )
        assert run.returncode == 2, (args, run.stderr)
        assert run.stderr.count("error:") == 1 and "Traceback" not in run.stderr, run.stderr
        assert "YAML refused" in run.stderr
