"""``doctor``'s walk of a ROS 1 chunk: its records against its chunk info and index data
(messages, times, connections), one line per disagreement."""

from __future__ import annotations

from collections.abc import Mapping

from rosbags.rosbag1.reader import ChunkInfo, IndexData

from bagkit.bag.rosbag1_records import RECORD_ERRORS, chunk_contents
from bagkit.words import counted


def disagreements(
    where: str,
    info: ChunkInfo,
    data: bytes,
    *,
    index: Mapping[int, list[IndexData]],
    topic_of: Mapping[int, str],
    known: set[int],
) -> list[str]:
    """What is wrong with the chunk ``where`` whose decompressed ``data``, chunk ``info`` and
    index data (``index``: entries by connection) disagree; ``topic_of`` names connections,
    ``known`` are those of the bag's index."""
    try:
        held, connections = chunk_contents(data)
    except RECORD_ERRORS as exc:
        return [f"{where}: its records do not parse ({exc})"]
    found = []
    for conn in sorted(set(held) | set(index) | set(info.connection_counts)):
        name = topic_of.get(conn, f"connection {conn}")
        stored = sorted(held.get(conn, ()))
        indexed = sorted((e.time, e.offset) for e in index.get(conn, ()))
        info_count = info.connection_counts.get(conn, 0)
        if stored != indexed or len(stored) != info_count:
            found.append(
                f"{where}: holds {counted(len(stored), 'message')} of {name}, its index data "
                f"lists {len(indexed)} ({len(set(indexed) - set(stored))} at no message), its "
                f"chunk info counts {info_count}"
            )
        times = [t for t, _ in stored]
        # The chunk info's end time is one past the last message's (rosbags).
        if times and (min(times) < info.start_time or max(times) >= info.end_time):
            found.append(f"{where}: {name} has messages outside the chunk info's times")
    unknown = sorted((connections | set(held)) - known)
    if unknown:
        found.append(f"{where}: connections {unknown} are not in the bag's index")
    return found
