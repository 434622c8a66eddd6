"""``bagkit record``: record topics into a rosbag2-compatible MCAP bag, counting every loss."""

from __future__ import annotations

import enum
import signal
import threading
import time
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

import typer
from rich import box
from rich.table import Table

from bagkit.cli.common import (
    EXIT_INTERRUPTED,
    OutputFormat,
    console,
    err_console,
    fail,
    handle_errors,
    print_json,
    warn,
)

if TYPE_CHECKING:
    # The recorder imports rclpy: only `bagkit record` itself pays for that import.
    from bagkit.ros.record_report import RecordProgress, RecordReport
    from bagkit.ros.recorder import Recorder

HELP = (
    "Record TOPICS (or --all, or --regex) into an MCAP bag that ros2 bag, Foxglove and rosbags "
    "read.\n\n"
    "Topics are discovered at start and while recording (the graph is polled every 100 ms); "
    "each is subscribed with QoS adapted to its publishers (reliable / transient-local only if "
    "every publisher is). Stops on Ctrl-C, SIGTERM or --duration, finishes the bag and prints "
    "per topic: messages, lost, rate and bytes. Lost counts gaps in the publishers' sequence "
    "numbers (loss inside the middleware), write-queue overflows and write failures.\n\n"
    "Exit status: 0 after --duration, 130 after Ctrl-C, 143 after SIGTERM (the bag is complete "
    "in all three), 1 when recording failed (disk full: the bag keeps what was written), "
    "2 for bad options or an existing output."
)


class Compression(enum.StrEnum):
    """Chunk compression."""

    ZSTD = "zstd"
    LZ4 = "lz4"
    NONE = "none"


def _human_bytes(count: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if count < 1024 or unit == "GiB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1024
    raise AssertionError("unreachable")


def _print_table(report: RecordReport) -> None:
    table = Table(
        title=f"{report.path} ({report.duration_s:.1f} s)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
    )
    # Numbers never wrap; on a narrow terminal (80 columns when piped) the type, last, folds.
    table.add_column("topic", no_wrap=True)
    for column in ("messages", "lost", "rate", "bytes"):
        table.add_column(column, justify="right", no_wrap=True)
    table.add_column("type", overflow="fold", min_width=16)
    for topic in report.topics:
        lost = f"[red]{topic.lost}[/]" if topic.lost else "0"
        table.add_row(
            topic.topic,
            str(topic.messages),
            lost,
            f"{topic.rate_hz:.1f} Hz",
            _human_bytes(topic.bytes),
            topic.type,
        )
    table.add_section()
    table.add_row(
        "total", str(report.messages), str(report.lost), "", _human_bytes(report.bytes), ""
    )
    console.print(table)
    lossy = [t for t in report.topics if t.lost]
    for topic in lossy:
        console.print(
            f"  {topic.topic}: {topic.gaps} lost in the middleware (sequence gaps), "
            f"{topic.overflow} in queue overflows, {topic.write_failed} in write failures",
            highlight=False,
            markup=False,
        )


def _progress_line(progress: RecordProgress) -> str:
    lost = f", [red]{progress.lost} lost[/]" if progress.lost else ""
    return (
        f"recording {progress.topics} topics: {progress.messages} messages, "
        f"{_human_bytes(progress.bytes)}{lost} ({progress.elapsed_s:.0f} s)"
    )


@handle_errors
def record(  # noqa: PLR0917 (typer maps parameters to options)
    topics: list[str] = typer.Argument(
        None, help="Topics to record (always recorded, even hidden ones).", show_default=False
    ),
    all_topics: bool = typer.Option(False, "--all", "-a", help="Record every topic."),
    regex: str | None = typer.Option(
        None, "--regex", "-e", help="Also record topics whose name contains a match of RE."
    ),
    exclude: str | None = typer.Option(
        None, "--exclude", "-x", help="Leave out every topic matching RE, named ones too."
    ),
    output: Path | None = typer.Option(
        None,
        "--output",
        "-o",
        help="Bag directory to create (default: rosbag2_YYYY_MM_DD-HH_MM_SS); never overwritten.",
        show_default=False,
    ),
    duration: float | None = typer.Option(
        None, "--duration", "-d", help="Stop after this many seconds.", min=0.0
    ),
    max_bag_size: int = typer.Option(
        0,
        "--max-bag-size",
        "-b",
        help="Split into a new file at this many bytes (0: never).",
        min=0,
    ),
    max_bag_duration: float = typer.Option(
        0, "--max-bag-duration", help="Split when a file spans this many seconds (0: never).", min=0
    ),
    compression: Compression = typer.Option(
        Compression.ZSTD, "--compression", help="Chunk compression."
    ),
    qos_overrides: Path | None = typer.Option(
        None,
        "--qos-overrides",
        help="YAML {topic: {reliability: ..., durability: ..., ...}} (ros2 bag's format): "
        "subscribe with these profiles instead of the adapted ones.",
    ),
    use_sim_time: bool = typer.Option(
        False, "--use-sim-time", help="Stamp messages (log time) with the latest /clock time."
    ),
    include_hidden: bool = typer.Option(
        False, "--include-hidden", help="Let --all/--regex select hidden topics (/_name)."
    ),
    output_format: OutputFormat = typer.Option(
        OutputFormat.TABLE, "--format", "-f", help="Final report as a table or JSON (no csv)."
    ),
) -> None:
    from bagkit.ros.memory import keep_freed_memory
    from bagkit.ros.qos import load_qos_overrides
    from bagkit.ros.recorder import Recorder, default_output_name
    from bagkit.ros.selection import absolute_topic_name

    if output_format == OutputFormat.CSV:
        raise fail("--format csv is not supported by record (table or json)")
    overrides = {}
    if qos_overrides is not None:
        overrides = {
            absolute_topic_name(k): v for k, v in load_qos_overrides(qos_overrides).items()
        }
    recorder = Recorder(
        output or Path(default_output_name()),
        topics=topics or [],
        all_topics=all_topics,
        regex=regex,
        exclude=exclude,
        include_hidden=include_hidden,
        compression=compression.value,
        max_bag_size=max_bag_size,
        max_bag_duration_s=max_bag_duration,
        qos_overrides=overrides,
        use_sim_time=use_sim_time,
        on_warning=warn,
    )

    keep_freed_memory()
    report, received = _record_until_stopped(recorder, duration)

    if output_format == OutputFormat.JSON:
        print_json(report.to_dict())
    else:
        _print_table(report)
    for topic, reason in report.skipped.items():
        warn(f"not recorded: {topic}: {reason}")
    if report.error is not None:
        raise fail(report.error, 1)
    if received:
        raise typer.Exit(EXIT_INTERRUPTED if received[0] == signal.SIGINT else 128 + received[0])


def _record_until_stopped(
    recorder: Recorder, duration: float | None
) -> tuple[RecordReport, list[int]]:
    """Record until a signal, ``duration`` or a failure; return the report and the signals."""
    from bagkit.ros.fastdds import large_receive_queue

    stop = threading.Event()
    received: list[int] = []

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        if received:
            # A second signal: give up finishing (what is on disk stays salvageable).
            raise KeyboardInterrupt
        received.append(signum)
        stop.set()
        err_console.print("stopping: finishing the bag (Ctrl-C again to abort)")

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        with large_receive_queue():  # read when the participant is created
            recorder.start()
        err_console.print(f"recording to {recorder.path} (Ctrl-C to stop)", highlight=False)
        deadline = None if duration is None else time.monotonic() + duration
        with err_console.status(_progress_line(recorder.progress())) as status:
            while not stop.is_set() and not recorder.stopped.is_set():
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    break
                stop.wait(0.5 if remaining is None else min(0.5, remaining))
                status.update(_progress_line(recorder.progress()))
    finally:
        report = recorder.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return report, received
