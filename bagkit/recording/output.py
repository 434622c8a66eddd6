"""A recording's output: the bag it writes, or in snapshot mode the sink of its snapshots.

Created before the node, so that an output that exists or cannot be created is a bad option
(exit 2) and a full disk a failed run (exit 1) before anything subscribes.
"""

from __future__ import annotations

import contextlib
import errno
from collections.abc import Callable, Sequence
from pathlib import Path

from bagkit.bag import BagWriteError, BagWriter
from bagkit.bag.errors import BagError
from bagkit.bag.messages import BagMessage
from bagkit.recording.errors import RecorderOptionsError, RecordingFailedError
from bagkit.recording.options import RecordOptions
from bagkit.recording.snapshot import SnapshotSink, SnapshotTriggers
from bagkit.recording.write_loop import FLUSH_PERIOD_S

# A recording that cannot be written for these reasons is a failed run (exit 1), not a bad option.
_DISK_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}


def create_output(
    path: Path,
    options: RecordOptions,
    *,
    file_preamble: Callable[[], Sequence[BagMessage]] | None,
    triggers: SnapshotTriggers | None = None,
    on_snapshot_error: Callable[[str, int], None],
) -> BagWriter | SnapshotSink:
    """The recording's bag, opened (in snapshot mode: its snapshot sink, opened).

    Args:
        path: the output directory.
        options: the recording's options.
        file_preamble: the latched state that starts each split file (see ``BagWriter``).
        triggers: the sink's triggers in snapshot mode.
        on_snapshot_error: the sink's ``on_error`` in snapshot mode.

    Raises:
        RecorderOptionsError: the output exists or cannot be created, or a bag option is
            invalid.
        RecordingFailedError: the bag cannot be written (a full disk); nothing is left.
    """
    floor = options.files.min_free_space
    if floor is not None:
        existing = next(p for p in [path, *path.parents] if p.exists())
        if floor.below(existing):
            raise RecorderOptionsError(f"{existing}: less than {floor.text} free: not started")
    if options.snapshot_mode:
        assert triggers is not None, "snapshot mode needs its triggers"
        return _create_snapshot_sink(path, options, triggers, on_snapshot_error)
    try:
        bag = BagWriter(
            path,
            compression=options.files.compression,
            max_bag_size=options.files.max_bag_size,
            max_bag_duration_ns=options.files.max_bag_duration_ns,
            chunk_interval_s=FLUSH_PERIOD_S,
            file_preamble=file_preamble,
            rotation=options.files.rotation,
        ).open()
        bag.custom_data.update(options.custom_data)
        return bag
    except BagWriteError as exc:
        cause = exc.__cause__
        if isinstance(cause, OSError) and cause.errno in _DISK_FULL:
            _remove_empty_bag(path)
            raise RecordingFailedError(str(exc)) from None
        raise RecorderOptionsError(str(exc)) from None
    except BagError as exc:
        raise RecorderOptionsError(str(exc)) from None


def _create_snapshot_sink(
    path: Path,
    options: RecordOptions,
    triggers: SnapshotTriggers,
    on_error: Callable[[str, int], None],
) -> SnapshotSink:
    try:
        return SnapshotSink(path, options, triggers, on_error).open()
    except FileExistsError:
        raise RecorderOptionsError(
            f"{path} already exists (bagkit never overwrites a bag)"
        ) from None
    except OSError as exc:
        raise RecorderOptionsError(f"cannot create {path}: {exc.strerror or exc}") from None


def _remove_empty_bag(path: Path) -> None:
    """Remove what a bag that could not even start left behind: empty files, the directory."""
    if not path.is_dir():
        return
    for child in path.iterdir():
        if child.is_file() and child.stat().st_size == 0:
            child.unlink()
    with contextlib.suppress(OSError):  # something else is in there: not ours to remove
        path.rmdir()
