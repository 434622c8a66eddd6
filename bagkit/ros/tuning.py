"""The process tuning a recording or a replay gets: Fast DDS queues, malloc, timers (glibc).

Three settings, each with its own scope:

- the Fast DDS shared-memory profile (:func:`bagkit.ros.fastdds.large_receive_queue`): read
  when a participant is created, so it must be in effect around the node's creation;
- malloc thresholds (:func:`bagkit.native.keep_freed_memory`): process-wide, for good;
- timer slack (:func:`bagkit.native.precise_timers`): the calling thread's, for the block.

:func:`process_tuning` applies the first two; ``Recorder.start`` and ``Player.open`` open it
around their node's creation, and the player's publishing loop runs under
:func:`~bagkit.native.precise_timers`. So the CLI, the regression harness, the benchmarks and a
Python user of ``Recorder(options).run()`` or ``Player(options).run()`` get the same run;
``tune_process=False`` in the options leaves the host process alone. No rclpy import: the
adapter that configures the middleware (Fast DDS) before a node exists.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, MutableMapping

from bagkit.native import keep_freed_memory
from bagkit.ros.fastdds import large_receive_queue


@contextlib.contextmanager
def process_tuning(
    enabled: bool = True,
    environ: MutableMapping[str, str] | None = None,
    *,
    segment_size: int | None = None,
) -> Iterator[bool]:
    """Tune the process for a recording or a replay; open it around the node's creation.

    Keeps freed memory (:func:`keep_freed_memory`) and gives the participants created in the
    block a large shared-memory queue (:func:`~bagkit.ros.fastdds.large_receive_queue`, unless
    the user has a Fast DDS setting of their own).

    Args:
        enabled: False: change nothing (``tune_process=False`` in the options).
        environ: the environment to change (default: ``os.environ``).
        segment_size: the shared-memory segment a sender needs (the player's, for the bag's
            largest messages); None: Fast DDS's default.

    Yields:
        Whether the Fast DDS profile is in effect.
    """
    if not enabled:
        yield False
        return
    keep_freed_memory()
    with large_receive_queue(environ, segment_size=segment_size) as profile:
        yield profile
