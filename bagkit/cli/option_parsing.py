"""How command-line values become the library's: list options (repeated, comma lists,
several values after one flag as ``ros2 bag`` takes them), sizes, free space, durations and
bag locations (a path, or a URL)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, cast

import typer

# typer 0.29 vendors click; its exception classes are only importable from there (typer is pinned).
from typer.core import TyperCommand

from bagkit.errors import BagkitError

if TYPE_CHECKING:
    from bagkit.bag.file_rotation import FreeSpace


def split_list(values: list[str] | tuple[str, ...] | None) -> list[str]:
    """A list option's values, given repeated (``-t a -t b``) or as comma lists (``-t a,b``).

    Every list option of every command goes through here, so both spellings work everywhere.
    """
    return [v.strip() for value in values or () for v in value.split(",") if v.strip()]


def expand_multi_value_options(
    args: list[str],
    options: frozenset[str],
    *,
    value_options: frozenset[str] = frozenset(),
    path_ends_values: bool = False,
) -> list[str]:
    """``--topics a b c`` -> ``--topics a --topics b --topics c`` (argparse's ``nargs='+'``).

    ``ros2 bag`` takes several values after one option; click takes one. Values run until the
    next token that starts with ``-``, as in argparse. The value of one of ``value_options``
    (options taking one value) is passed through. With ``path_ends_values`` (a command whose
    positional argument is a bag), an existing path after at least one value ends the values
    until the first positional is seen: ``--topics /a /b BAG`` leaves BAG positional.
    """
    expanded: list[str] = []
    positional_seen = False
    index = 0
    while index < len(args):
        arg = args[index]
        index += 1
        expanded.append(arg)
        if arg == "--":
            expanded.extend(args[index:])
            break
        if arg in options:
            first = True
            while index < len(args) and not args[index].startswith("-"):
                value = args[index]
                ends = path_ends_values and not positional_seen and Path(value).exists()
                if not first and ends:
                    break
                expanded.extend((value,) if first else (arg, value))
                first = False
                index += 1
        elif arg in value_options and index < len(args):
            expanded.append(args[index])
            index += 1
        elif not arg.startswith("-"):
            positional_seen = True
    return expanded


class MultiValueCommand(TyperCommand):
    """A command whose ``multi_value`` options take several values after one flag.

    Subclasses name the options; ``bag_positional`` says whether the positional argument is a
    bag path (see :func:`expand_multi_value_options`).
    """

    multi_value: ClassVar[frozenset[str]] = frozenset()
    bag_positional: ClassVar[bool] = True

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        expanded = expand_multi_value_options(
            args,
            self.multi_value,
            value_options=self.value_options(),
            path_ends_values=self.bag_positional,
        )
        return list(super().parse_args(ctx, expanded))

    def value_options(self) -> frozenset[str]:
        """The names of this command's options that take one value."""
        return frozenset(
            name
            for param in self.params
            if not getattr(param, "is_flag", True) and param.param_type_name == "option"
            for name in param.opts
        )


def byte_size(text: str) -> int:
    """A size option's value in bytes: ``2GiB``, ``500MB``, ``1.5G``, ``1000000``
    (:mod:`bagkit.bag.sizes`, the grammar of every size option)."""
    from bagkit.bag.sizes import GRAMMAR, parse_size

    try:
        return parse_size(text, "size")
    except BagkitError:
        raise typer.BadParameter(f"{text!r}: expected {GRAMMAR}") from None


def free_space(text: str) -> FreeSpace:
    """A free-space option's value: a size (:func:`byte_size`) or a share of the filesystem
    (``5%``)."""
    from bagkit.bag.file_rotation import FreeSpace
    from bagkit.bag.sizes import GRAMMAR

    try:
        return FreeSpace.parse(text)
    except BagkitError as exc:
        if text.strip().endswith("%"):
            raise typer.BadParameter(str(exc).removeprefix("min_free_space ")) from None
        raise typer.BadParameter(f"{text!r}: expected {GRAMMAR} or a share (5%)") from None


def duration_ns(text: str) -> int:
    """A duration option's value in ns: ``90`` (seconds), ``1.5``, ``1m30s``, ``250ms``
    (:func:`bagkit.selection.times.parse_duration`, the grammar of every duration option)."""
    from bagkit.selection.times import parse_duration

    try:
        return parse_duration(text, "duration")
    except BagkitError as exc:
        raise typer.BadParameter(str(exc).removeprefix("bad duration ")) from None


LOCAL_BAG_HELP = "Bag directory, .mcap/.db3 file (or .zstd), or ROS 1 .bag file."
BAG_HELP = LOCAL_BAG_HELP.removesuffix(".") + ", or its URL (s3://, https:// ...)."
"""A bag argument's help: every kind of bag the readers open (docs/bag-format.md)."""


def bag_location(text: str) -> Path:
    """A bag argument (``parser=`` of a ``Path`` argument): a local path, or for a URL
    (``s3://``, ``https://`` ...) a :class:`~bagkit.storage.paths.UrlPath`, which the readers open
    by range requests (``Path`` would fold its ``//``)."""
    from bagkit.storage.urls import is_url

    if not is_url(text):
        return Path(text)
    from bagkit.storage.paths import UrlPath

    return cast(Path, UrlPath(text))
