"""Why a topic lost messages, where the counts say it: a line for the report and the doctor.

A camera recorded here (30 Hz 640x480 rgb8, 0.9 MB a frame, best effort, Fast DDS defaults)
got 95 of 300 frames, the rest lost in the middleware; a plain rclpy subscriber got 95 too,
and 300 once the *publisher* had a 16 MiB shared-memory segment (docs/record.md, "Large
messages"). Middleware loss with messages larger than the publisher's likely segment is named
with that cause and fix. No rclpy import.
"""

from __future__ import annotations

# Fast DDS's default shared-memory segment of a participant, where its samples are sent from.
FASTDDS_DEFAULT_SEGMENT = 512 * 1024


def large_message_cause(topic: str, gaps: int, messages: int, nbytes: int) -> str | None:
    """The cause line for ``topic`` when its middleware loss (``gaps``) comes with messages
    (``nbytes`` over ``messages``) larger than the publisher's default segment; else None."""
    if not gaps or not messages:
        return None
    mean = nbytes / messages
    if mean <= FASTDDS_DEFAULT_SEGMENT:
        return None
    return (
        f"{topic}: {gaps} of {gaps + messages} lost in the middleware with "
        f"{mean / (1 << 20):.1f} MiB messages, larger than the publisher's shared-memory "
        f"segment (Fast DDS's default {FASTDDS_DEFAULT_SEGMENT >> 10} KiB): give the "
        "publishing process a larger segment (the large_data profile in docs/record.md, "
        '"Large messages")'
    )
