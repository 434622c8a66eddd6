"""``filter --around``: one bag per time window (``OUT/<bag>_<n>/``), each a ``filter`` of the
input with the latched state from before the window (:mod:`~bagkit.surgery.carry`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from bagkit.selection.windows import TimeRange, Window
from bagkit.surgery.errors import SurgeryError
from bagkit.surgery.output_paths import single_file
from bagkit.surgery.rewrite import OutputOptions, RewriteReport, check_output, filter_bag
from bagkit.surgery.select import Selection


def window_bag_name(bag: Path, n: int) -> str:
    """``<bag>_<n>``: the input's name (a ``.mcap`` file's without its suffix), from 0."""
    name = bag.stem if bag.is_file() else bag.name
    return f"{name}_{n}"


def check_windows_output(bag: Path, output: Path, options: OutputOptions) -> None:
    """Raise SurgeryError unless ``output`` can be the directory of ``bag``'s window bags: it
    is a directory or can be created, outside the input, and not named as one MCAP file."""
    if single_file(output, options):
        raise SurgeryError(f"{output}: --around writes a directory of bags: name it without .mcap")
    check_output([bag], output, options)
    if output.exists() and not output.is_dir():
        raise SurgeryError(f"{output} is not a directory")
    if not output.parent.is_dir():
        raise SurgeryError(f"{output.parent}: no such directory")


def cut_windows(
    bag: Path,
    output: Path,
    windows: Sequence[Window],
    selection: Selection,
    options: OutputOptions | None = None,
) -> list[RewriteReport]:
    """Write one bag per window of ``bag`` under the directory ``output`` (created).

    Args:
        bag: the input.
        output: the directory of the bags written (``<bag>_<n>``, n from 0 in window order).
        windows: absolute log-time windows, both sides set (``[start, end)``).
        selection: the topics (and ``--where`` filters, latched options) of every window;
            its time range is replaced by each window.
        options: how each bag is written (``force`` replaces an existing ``<bag>_<n>``).

    Raises:
        SurgeryError: a window without both sides, ``output`` not a directory, or a bag that
            exists without ``force``, ``output`` ending in ``.mcap`` (one file); what
            :func:`filter_bag` raises.
    """
    if any(w.start_ns is None or w.end_ns is None for w in windows):
        raise SurgeryError("a window to cut needs a start and an end")
    options = options or OutputOptions()
    check_windows_output(bag, output, options)
    output.mkdir(exist_ok=True)
    reports = []
    for n, window in enumerate(windows):
        assert window.start_ns is not None and window.end_ns is not None
        cut = replace(selection, span=TimeRange.of_window(window), window=Window())
        reports.append(filter_bag(bag, output / window_bag_name(bag, n), cut, options))
    return reports
