"""Byte sizes as users write them, one grammar for every size option.

``2GiB``, ``500MB``, ``1.5G``, ``64k``, ``1000000`` (bytes); units are case-insensitive, ``K``,
``M``, ``G``, ``T`` (and ``KB`` ...) powers of 1000, ``KiB`` ... powers of 1024. ``5%`` (a share
of the filesystem) only where a share makes sense (``--min-free-space``).
"""

from __future__ import annotations

import re

from bagkit.bag.errors import BagError

_UNITS = {
    "": 1,
    "b": 1,
    "k": 1000,
    "kb": 1000,
    "m": 1000**2,
    "mb": 1000**2,
    "g": 1000**3,
    "gb": 1000**3,
    "t": 1000**4,
    "tb": 1000**4,
    "kib": 1 << 10,
    "mib": 1 << 20,
    "gib": 1 << 30,
    "tib": 1 << 40,
}
_SIZE = re.compile(r"\s*(\d+(?:\.\d+)?)\s*([a-zA-Z]*|%)\s*")
GRAMMAR = "a size (2GiB, 500MB, 1.5G, 1000000)"


def parse_size(text: str | int, what: str) -> int:
    """``text`` in bytes; ``what`` names the value in the error.

    Raises:
        BagError: not a size.
    """
    if isinstance(text, int):
        return text
    match = _SIZE.fullmatch(text)
    if match is None or match[2].lower() not in _UNITS:
        raise BagError(f"{what} {text!r}: expected {GRAMMAR}")
    return int(float(match[1]) * _UNITS[match[2].lower()])


def parse_share(text: str, what: str) -> float | None:
    """``5%`` -> 0.05; None when ``text`` is not a percentage (then a size).

    Raises:
        BagError: a percentage not between 0 and 100.
    """
    match = _SIZE.fullmatch(text)
    if match is None or match[2] != "%":
        return None
    number = float(match[1])
    if not 0 < number < 100:
        raise BagError(f"{what} {text!r}: a percentage between 0 and 100")
    return number / 100


def split_size_problem(size: int, minimum: int) -> str | None:
    """Why ``size`` is no split size for a writer whose files hold at least ``minimum`` bytes
    (one chunk, or a few small ones), or None (0 never splits)."""
    if 0 < size < minimum:
        return (
            f"a split size of {size} bytes is below {minimum} bytes: files end on chunk "
            "boundaries, each with its own header, definitions and summary"
        )
    return None
