"""One byte-size grammar for every size option (``bagkit.bag.sizes``)."""

from __future__ import annotations

import pytest

from bagkit.bag import BagError
from bagkit.bag.file_rotation import FreeSpace
from bagkit.bag.sizes import parse_share, parse_size, split_size_problem


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("2GiB", 2 * 1024**3),
        ("500MB", 500 * 1000**2),
        ("1.5G", 1_500_000_000),
        ("64k", 64_000),
        ("16KiB", 16 * 1024),
        ("1000000", 1_000_000),
        (" 3 mib ", 3 * 1024**2),
        ("0", 0),
    ],
)
def test_sizes_parse_to_bytes(text: str, expected: int) -> None:
    assert parse_size(text, "-b") == expected


@pytest.mark.parametrize("text", ["", "2 parsecs", "-1G", "1.5x", "5%", "G"])
def test_a_bad_size_names_the_option_and_the_grammar(text: str) -> None:
    with pytest.raises(BagError, match=r"^-b .*: expected a size \(2GiB, 500MB, 1.5G"):
        parse_size(text, "-b")


def test_a_share_only_where_asked_for() -> None:
    assert parse_share("5%", "--min-free-space") == pytest.approx(0.05)
    assert parse_share("2GiB", "--min-free-space") is None
    assert FreeSpace.parse("1.5G").bytes == 1_500_000_000
    assert FreeSpace.parse("5%").fraction == pytest.approx(0.05)


def test_a_split_size_below_the_minimum_says_why() -> None:
    assert split_size_problem(0, 1 << 20) is None
    assert split_size_problem(1 << 20, 1 << 20) is None
    problem = split_size_problem(1, 1 << 20)
    assert problem is not None and "below 1048576 bytes" in problem
