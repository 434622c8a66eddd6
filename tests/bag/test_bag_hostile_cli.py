"""Hostile bags through the CLI (subprocesses of ``bagkit``; in this process where a damaged
chunk lost a topic's every message): one ``error:`` line and exit 2 for an unusable file; a
damaged chunk is a warning and its messages are reported lost; ``--no-crc``."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process
from hostile_files import Layout, chunk_messages

from bagkit.words import counted

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, *map(str, args)], capture_output=True, text=True, timeout=120, check=False
    )


def _here(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` in this process (tests/bagkit_runs.py): the output a process gives."""
    return bagkit_in_process(list(args))


@pytest.fixture
def flipped(write_sample_bag: Callable[..., Path]) -> tuple[Path, Path, int]:
    """(intact bag, a copy with one byte flipped inside its second chunk, messages lost)."""
    intact = write_sample_bag(chunk_size=20_000, compression="none")
    damaged = intact.parent / "damaged"
    shutil.copytree(intact, damaged)
    layout = Layout.of(damaged / "sample_0.mcap")
    chunk = layout.chunks[1]
    layout.data[chunk.chunk_start_offset + chunk.chunk_length - 3] ^= 0x01
    layout.save()
    return intact, damaged, chunk_messages(layout, chunk)


@pytest.mark.parametrize("command", [["info"], ["stats", "summary"]])
def test_a_header_length_of_2_62_is_one_error_line(
    write_sample_bag: Callable[..., Path], command: list[str]
) -> None:
    bag = write_sample_bag()
    layout = Layout.of(bag / "sample_0.mcap")
    layout.put(9, "<Q", 2**62)
    layout.save()
    run = _run(*command, bag)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: ")
    assert "header record's length (4611686018427387904) runs past the end" in lines[0]


def test_stats_reports_a_damaged_chunk_and_no_crc_reads_it(
    flipped: tuple[Path, Path, int],
) -> None:
    intact, damaged, lost = flipped
    counts = {}
    for bag, options in ((intact, []), (damaged, []), (damaged, ["--no-crc"])):
        run = _run("stats", "summary", bag, "--format", "json", *options)
        assert run.returncode == 0, run.stderr
        document = json.loads(run.stdout)
        counts[(bag.name, *options)] = sum(t["count"] for t in document["topics"])
        assert ("CRC mismatch" in run.stderr) == (bag == damaged and not options)
    assert counts[("damaged",)] == counts[("sample",)] - lost
    assert counts[("damaged", "--no-crc")] == counts[("sample",)]
    run = _run("stats", "summary", damaged)
    assert f"CRC mismatch (the chunk is damaged); {counted(lost, 'message')} lost" in run.stderr


def test_compare_warns_of_a_damaged_chunk(flipped: tuple[Path, Path, int]) -> None:
    intact, damaged, _ = flipped
    run = _run("compare", intact, damaged)
    assert run.returncode == 1
    assert "warning:" in run.stderr and "CRC mismatch" in run.stderr
    run = _run("compare", intact, damaged, "--no-crc")
    assert "CRC mismatch" not in run.stderr


def test_info_accepts_no_crc(flipped: tuple[Path, Path, int]) -> None:
    _, damaged, _ = flipped
    for options in ([], ["--no-crc"]):
        run = _run("info", damaged, "--format", "json", *options)
        assert run.returncode == 0, run.stderr
        assert json.loads(run.stdout)["problems"] == []  # info reads no chunk


def test_echo_warns_of_a_damaged_chunk(flipped: tuple[Path, Path, int]) -> None:
    intact, damaged, lost = flipped
    fewer = 0
    for topic in ("/imu/data", "/text"):
        whole, cut = (_run("echo", bag, topic, "--format", "json") for bag in (intact, damaged))
        assert whole.returncode == cut.returncode == 0, cut.stderr
        missing = len(whole.stdout.splitlines()) - len(cut.stdout.splitlines())
        assert ("CRC mismatch" in cut.stderr) == (missing > 0), cut.stderr
        assert whole.stderr == ""
        fewer += missing
    assert fewer == lost


def test_echo_and_stats_of_a_bag_whose_every_chunk_is_lost_fail(
    write_sample_bag: Callable[..., Path],
) -> None:
    bag = write_sample_bag(n_imu=20, compression="none")
    layout = Layout.of(bag / "sample_0.mcap")
    (chunk,) = layout.chunks
    layout.data[chunk.chunk_start_offset + chunk.chunk_length - 3] ^= 0x01
    layout.save()
    run = _run("echo", bag, "/imu/data")
    assert run.returncode == 2, run.stdout
    assert run.stdout == ""
    (line,) = run.stderr.strip().splitlines()
    assert line.startswith("error: no message of /imu/data could be read (")
    assert "CRC mismatch" in line
    stats = _run("stats", "summary", bag)  # the cause, not only "no messages"
    assert stats.returncode == 2, stats.stdout
    (line,) = stats.stderr.strip().splitlines()
    assert line.startswith(f"error: no messages to summarize in {bag} (") and "CRC" in line


@pytest.fixture
def every_chunk_lost(write_sample_bag: Callable[..., Path]) -> tuple[Path, Path, str]:
    """(a bag whose only chunk is damaged, an intact one, the reader's line for the loss)."""
    intact = write_sample_bag("intact", n_imu=20, compression="none")
    bag = write_sample_bag(n_imu=20, compression="none")
    layout = Layout.of(bag / "sample_0.mcap")
    (chunk,) = layout.chunks
    layout.data[chunk.chunk_start_offset + chunk.chunk_length - 3] ^= 0x01
    layout.save()
    return bag, intact, f"; {counted(chunk_messages(layout, chunk), 'message')} lost"


_LOST_ALL = {
    "export": ["export", "{bag}", "-t", "/imu/data", "-o", "{out}/imu.csv"],
    "find": ["find", "{bag}", "--when", "/imu/data: linear_acceleration.z > -1e9"],
    "plot": ["plot", "{bag}", "/imu/data:linear_acceleration.z", "-o", "{out}/z.png"],
    "plot in a window": [
        "plot",
        "{bag}",
        "/imu/data:linear_acceleration.z",
        "-o",
        "{out}/z.png",
        "--start",
        "0.05",
    ],
}


@pytest.mark.parametrize("command", sorted(_LOST_ALL))
def test_a_topic_whose_every_chunk_is_lost_is_no_empty_result(
    every_chunk_lost: tuple[Path, Path, str], tmp_path: Path, command: str
) -> None:
    """As echo: 0 rows or 0 episodes made of lost data is not "no matches"."""
    bag, intact, loss = every_chunk_lost
    args = [a.format(bag=bag, out=tmp_path) for a in _LOST_ALL[command]]
    run = _here(*args)
    assert run.returncode == 2, run.stdout + run.stderr
    errors = [line for line in run.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and run.stderr.strip().splitlines()[-1] == errors[0]
    assert errors[0].startswith("error: no message of /imu/data could be read (")
    assert "CRC mismatch" in errors[0] and loss in errors[0]
    whole = _here(*(str(intact) if a == str(bag) else a for a in args))
    assert whole.returncode == 0, whole.stderr
    assert whole.stderr == ""


def test_a_fleet_with_the_topic_read_elsewhere_succeeds(
    every_chunk_lost: tuple[Path, Path, str], tmp_path: Path
) -> None:
    """Over several bags, a topic read in one of them is a result (the loss a warning)."""
    bag, intact, loss = every_chunk_lost
    for args in (
        ["export", "-t", "/imu/data", "-o", tmp_path / "out"],
        ["find", "--when", "/imu/data: linear_acceleration.z > -1e9"],
    ):
        run = _here(*args, bag, intact, "--workers", "0")
        assert run.returncode == 0, run.stderr
        assert "error:" not in run.stderr and loss in run.stderr


@pytest.mark.parametrize(
    "args",
    [
        ["echo", "{bag}", "/quiet"],
        ["export", "{bag}", "-o", "{out}/all"],
        ["find", "{bag}", "--when", "/quiet: linear_acceleration.z > 0"],
        [
            "plot",
            "{bag}",
            "/quiet:linear_acceleration.z",
            "/imu/data:linear_acceleration.z",
            "-o",
            "{out}/z.png",
        ],
    ],
    ids=["echo", "export", "find", "plot"],
)
def test_a_topic_the_summary_counts_empty_lost_nothing(
    flipped: tuple[Path, Path, int], tmp_path: Path, args: list[str]
) -> None:
    """A damaged chunk elsewhere: a topic the bag's summary counts no message of (rosbag2's
    /parameter_events, often) is empty, not lost; the others are read (exit 0)."""
    from bag_samples import IMU

    from bagkit.bag import BagReader, BagWriter, TopicInfo

    _, damaged, _ = flipped
    quiet = tmp_path / "quiet"
    with (
        BagReader(damaged, check_crc=False) as reader,
        BagWriter(quiet, compression="none", chunk_size=20_000) as out,
    ):
        for topic in reader.topics.values():
            out.add_topic(topic, definition=reader.definitions[topic.type])
        out.add_topic(TopicInfo("/quiet", IMU), definition=reader.definitions[IMU])
        for message in reader.messages():
            out.write(message.topic, message.data, log_time=message.log_time)
    layout = Layout.of(quiet / "quiet_0.mcap")
    chunk = layout.chunks[1]
    layout.data[chunk.chunk_start_offset + chunk.chunk_length - 3] ^= 0x01
    layout.save()
    run = _here(*(a.format(bag=quiet, out=tmp_path) for a in args))
    assert run.returncode == 0, run.stderr
    assert "error:" not in run.stderr
    # echo and find read no chunk: /quiet is in none; export and plot read the others.
    assert ("CRC mismatch" in run.stderr) == (args[0] in ("export", "plot")), run.stderr


def _logged_from(bag: Path, start_ns: int, topics: list[str] | None = None) -> int:
    """Messages (of ``topics``) of ``bag`` logged at or after ``start_ns``, by the mcap
    package's reader."""
    from mcap.reader import make_reader

    with (bag / f"{bag.name}_0.mcap").open("rb") as stream:
        messages = make_reader(stream).iter_messages(topics=topics, log_time_order=False)
        return sum(m.log_time >= start_ns for _, _, m in messages)


@pytest.mark.parametrize("command", ["stats", "export", "filter"])
@pytest.mark.parametrize("inside", [False, True], ids=["outside", "inside"])
def test_a_damaged_chunk_outside_the_window_is_not_read(
    flipped: tuple[Path, Path, int], tmp_path: Path, command: str, inside: bool
) -> None:
    """A window that starts after the damaged chunk reads none of it and reports no loss; one
    that holds its last message reports it."""
    intact, damaged, _ = flipped
    layout = Layout.of(damaged / "sample_0.mcap")
    bad, after = layout.chunks[1], layout.chunks[2]
    assert bad.message_end_time < after.message_start_time
    start_ns = bad.message_end_time if inside else after.message_start_time
    window = ["--start", f"{start_ns}ns"]
    out = tmp_path / "out"
    if command == "stats":
        run = _here("stats", "summary", damaged, *window, "--format", "json")
        read = sum(t["count"] for t in json.loads(run.stdout)["topics"]) if run.stdout else 0
    elif command == "export":
        run = _here("export", damaged, "-t", "/imu/data", *window, "-o", out.with_suffix(".csv"))
        read = len(out.with_suffix(".csv").read_text().splitlines()) - 1  # the header line
    else:
        run = _here("filter", damaged, "-o", out, *window)
        read = _logged_from(out, start_ns)
    assert run.returncode == 0, run.stderr
    assert ("CRC mismatch" in run.stderr) == inside, run.stderr
    expected = _logged_from(intact, start_ns, ["/imu/data"] if command == "export" else None)
    if not inside:
        assert read == expected
    else:  # the damaged chunk's messages in the window are lost, no more
        assert 0 < expected - read <= chunk_messages(layout, bad)


@pytest.mark.parametrize("cut", ["metadata", "data_end"])
@pytest.mark.parametrize(
    "args",
    [
        ["export", "{bag}", "-o", "{out}/all"],
        ["find", "{bag}", "--when", "/quiet: linear_acceleration.z > 0"],
    ],
    ids=["export", "find"],
)
def test_a_file_cut_after_its_last_message_lost_nothing(
    write_sample_bag: Callable[..., Path], tmp_path: Path, args: list[str], cut: str
) -> None:
    """Cut in rosbag2's Metadata record or in Data End (written as the file closes, after every
    message): a topic without messages is empty, not lost (it failed with 'no message of /quiet
    could be read'); every written message is read."""
    import pyarrow.parquet as pq
    from bag_samples import IMU
    from ros2_messages import imu_cdr

    from bagkit.bag import BagWriter, TopicInfo

    bag = tmp_path / "cut"
    with BagWriter(bag, chunk_size=4_000) as out:
        out.add_topic(TopicInfo("/imu/data", IMU))
        out.add_topic(TopicInfo("/quiet", IMU))
        for i in range(300):
            out.write("/imu/data", imu_cdr(i), log_time=1_700_000_000_000_000_000 + i * 10**7)
    file = bag / "cut_0.mcap"
    data = file.read_bytes()
    # The first "rosbag2" name is the Metadata record's (the summary's index repeats it later).
    metadata_at = data.index(b"\x07\x00\x00\x00rosbag2") - 9
    assert data[metadata_at] == 0x0C
    metadata_end = (
        metadata_at + 9 + int.from_bytes(data[metadata_at + 1 : metadata_at + 9], "little")
    )
    assert data[metadata_end] == 0x0F  # Data End follows it
    file.write_bytes(data[: metadata_at + 30] if cut == "metadata" else data[: metadata_end + 5])
    run = _here(*(a.format(bag=bag, out=tmp_path) for a in args))
    assert run.returncode == 0, run.stderr
    assert "error:" not in run.stderr and "lost" not in run.stderr, run.stderr
    if args[0] == "export":
        assert pq.read_table(tmp_path / "all" / "imu" / "data.parquet").num_rows == 300


def test_deeply_nested_json_in_custom_data_is_shown_not_a_crash(
    write_sample_bag: Callable[..., Path],
) -> None:
    # Python's json decoder recurses per level: info and doctor ended in a RecursionError.
    bag = write_sample_bag()
    deep = "[" * 200_000 + "]" * 200_000
    metadata = bag / "metadata.yaml"
    text = metadata.read_text()
    assert "\n  custom_data:\n" in text
    custom = f"\n  custom_data:\n    bagkit.record.loss: '{deep}'\n    note: '{deep}'\n"
    metadata.write_text(text.replace("\n  custom_data:\n", custom))
    info = bagkit_in_process(["info", bag])
    assert info.returncode == 0 and info.stderr == "", info.stderr
    doctor = bagkit_in_process(["doctor", bag])
    assert "internal error" not in doctor.stderr
    assert "loss counts (custom_data bagkit.record.loss) are not readable" in doctor.stdout
