"""RecordOptions and PlayOptions: the library's defaults are the command line's, and out-of-range
values are refused before anything starts (no rclpy)."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path

import pytest

from bagkit.bag.file_rotation import FreeSpace
from bagkit.bag.latched import LatchedOptions
from bagkit.cli.record import record
from bagkit.cli.replay import replay
from bagkit.playback.errors import PlayerError
from bagkit.playback.options import (
    PlayOptions,
    PlayWindow,
    ServiceRequestReplay,
    SubscriberWaits,
)
from bagkit.recording.errors import RecorderOptionsError
from bagkit.recording.options import (
    DEFAULT_QUEUE_BYTES,
    FileOptions,
    RecordOptions,
    SnapshotOptions,
    SnapshotTrigger,
)
from bagkit.selection.times import NS_PER_S


def cli_defaults(command: object) -> dict[str, object]:
    return {
        name: parameter.default
        for name, parameter in inspect.signature(command).parameters.items()  # type: ignore[arg-type]
    }


def test_record_options_default_to_the_cli() -> None:
    cli = cli_defaults(record)
    options = RecordOptions(all_topics=True)
    assert options.output is cli["output"] is None
    assert options.node_name == cli["node_name"]
    assert options.discovery_period_ns == cli["polling_interval"] * 1_000_000  # type: ignore[operator]
    assert options.files.max_bag_size == cli["max_bag_size"]
    assert options.files.max_bag_duration_ns == cli["max_bag_duration"]
    assert options.files.max_bag_files == cli["max_bag_files"]
    assert options.files.min_free_space is cli["min_free_space"] is None
    assert options.duration_ns is cli["duration"] is None
    assert options.snapshot is None and cli["snapshot_mode"] is False
    assert options.use_sim_time is cli["use_sim_time"] is False
    assert options.include_hidden is cli["include_hidden"] is False
    assert options.include_unpublished is cli["include_unpublished"] is False
    assert options.qos_overrides is cli["qos_overrides"] is None
    assert cli["max_cache_size"] is None and options.queue_bytes == DEFAULT_QUEUE_BYTES
    assert options.files.compression == "zstd"  # no --compression-* option: bagkit's zstd chunks
    assert options.tune_process


def test_play_options_default_to_the_cli() -> None:
    cli = cli_defaults(replay)
    options = PlayOptions(Path("bag"))
    assert options.rate == cli["rate"]
    assert options.window.bounds(10**18, 10**18 + 5, Path("bag")) == (10**18, None)
    assert options.window.start == PlayWindow.create(cli["start_offset"]).start
    assert options.duration_ns is cli["duration"] is None
    assert options.delay_ns == cli["delay"] * NS_PER_S
    assert options.clock_hz is cli["clock"] is None
    assert options.loops == 1 and cli["loop"] is False
    assert options.start_paused is cli["start_paused"] is False
    assert options.waits.before_start is cli["wait_for_subscribers"] is True
    assert options.waits.timeout_ns == cli["wait_timeout"] * NS_PER_S
    assert options.waits.discovery_ns == cli["discovery_time"] * NS_PER_S
    assert options.waits.ack_timeout_ns == cli["wait_for_all_acked"] * 1_000_000  # type: ignore[operator]
    assert options.seek_step_ns == cli["seek_step"]
    assert options.latched == LatchedOptions() and cli["no_latched"] is False
    assert options.service_requests is None and cli["publish_service_requests"] is False
    assert options.qos_overrides is cli["qos_overrides"] is None
    assert options.services and options.tune_process  # the CLI always offers the services


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({}, "^selection: nothing to record"),
        ({"all_topics": True, "duration_ns": -1}, "^duration_ns: must not be negative"),
        ({"all_topics": True, "max_messages": 0}, "^max_messages: must be positive"),
        ({"all_topics": True, "queue_bytes": 0}, "^queue_bytes: must be positive"),
        ({"all_topics": True, "discovery_period_ns": 0}, "^discovery_period_ns: must be positive"),
        (
            {
                "topics": ("/a",),
                "snapshot": SnapshotOptions(1 << 20),
                "files": FileOptions(max_bag_files=0, min_free_space=FreeSpace(1)),
            },
            "^files.min_free_space: does not apply to snapshot mode",
        ),
        (
            {
                "topics": ("/a",),
                "snapshot": SnapshotOptions(
                    1 << 20, triggers=(SnapshotTrigger.parse("/b: x > 1"),)
                ),
            },
            "^snapshot.triggers: '/b: x > 1': /b is not among the recorded topics",
        ),
    ],
)
def test_record_options_out_of_range(fields: dict[str, object], message: str) -> None:
    with pytest.raises(RecorderOptionsError, match=message):
        RecordOptions(Path("never"), **fields)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: FileOptions(max_bag_size=-1), "^files.max_bag_size: must be >= 0"),
        (
            lambda: FileOptions(max_bag_size=1),
            "^files.max_bag_size: a split size of 1 bytes is below",
        ),
        (lambda: FileOptions(max_bag_duration_ns=-1), "^files.max_bag_duration_ns: must be >= 0"),
        (lambda: FileOptions(max_bag_files=2), "^files.max_bag_files: needs the bag split"),
        (SnapshotOptions, "^snapshot.max_bytes, snapshot.max_duration_ns: one is needed"),
        (lambda: SnapshotOptions(1 << 20, post_ns=-1), "^snapshot.post_ns: must be >= 0"),
        (
            lambda: SnapshotTrigger.parse("no colon"),
            "^snapshot.triggers: 'no colon': expected 'TOPIC: CONDITION'",
        ),
    ],
)
def test_record_option_parts_name_their_fields(make: Callable[[], object], message: str) -> None:
    with pytest.raises(RecorderOptionsError, match=message):
        make()


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: SubscriberWaits(timeout_ns=-1), "^waits.timeout_ns: must be >= 0"),
        (lambda: SubscriberWaits(ack_timeout_ns=-1), "^waits.ack_timeout_ns: must be >= 0"),
        (lambda: ServiceRequestReplay(timeout_ns=-1), "^service_requests.timeout_ns: must be"),
        (lambda: PlayOptions(Path("b"), exclude_regex="(").selection, "^exclude_regex: '\\('"),
    ],
)
def test_play_option_parts_name_their_fields(make: Callable[[], object], message: str) -> None:
    with pytest.raises(PlayerError, match=message):
        make()


def test_record_options_make_names_absolute() -> None:
    selection = RecordOptions(topics=("imu/data",)).selection
    assert selection.topics == frozenset({"/imu/data"})


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"regex": "("}, "^regex: '\\(' is not a valid regular expression"),
        ({"progress_period_ns": 0}, "^progress_period_ns: must be positive"),
        ({"seek_step_ns": -1}, "^seek_step_ns: must be positive"),
        (
            {"latched": LatchedOptions(enabled=False, extra_topics=("/a",))},
            "^latched: extra topics without latched state",
        ),
        ({"start_offset": "5 mins"}, "^start_offset: bad start offset '5 mins': not a time"),
        ({"duration_ns": 0}, "^duration_ns: must be positive, got 0"),
    ],
)
def test_play_options_out_of_range(fields: dict[str, object], message: str) -> None:
    with pytest.raises(PlayerError, match=message):
        PlayOptions(Path("bag"), **fields)  # type: ignore[arg-type]


def test_live_health_names_its_field() -> None:
    from bagkit.errors import OptionError
    from bagkit.health import HealthSpec
    from bagkit.health.live import LiveHealth

    spec = HealthSpec.parse("topics:\n  /a: {max_gap: 1s}\n")
    assert LiveHealth(spec, stop_after_ns=2 * 10**9).stop_after_ns == 2 * 10**9
    with pytest.raises(OptionError, match=r"^stop_after_ns: must be positive") as error:
        LiveHealth(spec, stop_after_ns=0)
    assert error.value.field == "stop_after_ns"


@pytest.mark.parametrize(
    ("flags", "expected"),
    [
        (
            ["--trigger-on-health"],
            "error: --trigger-on-health triggers snapshots outside snapshot mode "
            "(add --snapshot-mode)",
        ),
        (["--stop-on-health", "0"], "error: --stop-on-health: must be positive, got 0"),
    ],
)
def test_record_health_errors_name_the_flags(
    flags: list[str], expected: str, tmp_path: Path
) -> None:
    """The library names its fields (health.trigger, stop_after_ns); the CLI its flags. Both
    are refused before the recorder starts: nothing is written."""
    import subprocess
    import sys

    spec = tmp_path / "health.yaml"
    spec.write_text("topics:\n  /imu/data: {max_gap: 1s}\n")
    bagkit = str(Path(sys.executable).with_name("bagkit"))
    result = subprocess.run(
        [bagkit, "record", "-a", "--health", str(spec), *flags, "-o", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert result.returncode == 2 and result.stderr.splitlines() == [expected], result.stderr
    assert not (tmp_path / "out").exists()
