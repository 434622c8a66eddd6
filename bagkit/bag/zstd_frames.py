"""The content sizes that zstd frames declare in their headers, read for many frames at once.

rosbag2's message compression stores each payload as one zstd frame; the bulk path
decompresses a run of them in one call, sized and bounded from these declarations (RFC 8878,
3.1.1.1: the Frame_Header_Descriptor says where the Frame_Content_Size field is and how wide).
Imported with numpy, by the compression layer only.
"""

from __future__ import annotations

import numpy as np

ZSTD_MAGIC = 0xFD2FB528
# The longest frame header: magic, descriptor, window descriptor, 4-byte dictionary id, 8-byte
# content size.
MAX_HEADER = 18
MAX_WINDOW_LOG = 31
_DICTIONARY_ID_SIZES = np.array([0, 1, 2, 4], np.int64)
# The bits of a content size field of each width (0, 1, 2, 4 or 8 bytes).
_FIELD_MASKS = np.array([0, 0xFF, 0xFFFF, 0, 0xFFFFFFFF, 0, 0, 0, (1 << 64) - 1], np.uint64)
_INT64_MAX = np.uint64((1 << 63) - 1)


def declared_sizes(stored: np.ndarray, starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The content size declared by the zstd frame at the start of each payload.

    Args:
        stored: the payloads back to back (uint8).
        starts, lengths: int64, each payload's place in ``stored``.

    Returns:
        int64 per payload: the declared size, or -1 where the payload does not start with a
        whole zstd frame header that declares one (no magic number, a reserved bit set, no
        content size field, a window too large for zstd, a header longer than the payload,
        a size beyond int64).
    """
    from numpy.lib.stride_tricks import sliding_window_view

    count = len(starts)
    if count and starts.max() > len(stored) - MAX_HEADER:
        # Bytes past the end: of no header, refused below by the header's length.
        stored = np.concatenate([stored, np.zeros(MAX_HEADER, np.uint8)])
    if not count:
        return np.zeros(0, np.int64)
    head = sliding_window_view(stored, MAX_HEADER)[starts]
    magic = np.ascontiguousarray(head[:, :4]).view("<u4").ravel() == ZSTD_MAGIC
    descriptor = head[:, 4].astype(np.int64)
    flag = descriptor >> 6
    single_segment = (descriptor >> 5) & 1
    reserved = (descriptor >> 3) & 1
    # Flag 0 has a 1-byte field only in a single-segment frame; flags 1, 2, 3: 2, 4, 8 bytes.
    field = np.where(flag == 0, single_segment, 1 << flag)
    at = 5 + (1 - single_segment) + _DICTIONARY_ID_SIZES[descriptor & 3]
    # zstd refuses a window over 2**31 bytes (the exponent in the window descriptor's top bits).
    window_log = np.where(single_segment == 1, 0, 10 + (head[:, 5].astype(np.int64) >> 3))
    whole = magic & (reserved == 0) & (window_log <= MAX_WINDOW_LOG) & (field > 0)
    whole &= at + field <= lengths
    if (at == at[0]).all():  # one header layout for all (one writer's frames)
        raw = head[:, int(at[0]) : int(at[0]) + 8]
    else:
        raw = np.take_along_axis(head, at[:, None] + np.arange(8), axis=1)
    value = np.ascontiguousarray(raw).view("<u8").ravel()
    value = (value & _FIELD_MASKS[field]) + np.where(field == 2, np.uint64(256), np.uint64(0))
    return np.where(whole & (value <= _INT64_MAX), value.astype(np.int64), -1)
