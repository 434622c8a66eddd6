"""What a surgery output path names (a bag directory, or one MCAP file) and what ``--force``
may replace there."""

from __future__ import annotations

from pathlib import Path

from bagkit.surgery.errors import SurgeryError
from bagkit.surgery.options import OutputOptions

# What --force may replace: a bag directory holds these files only (rosbag2 writes no folders).
_BAG_SUFFIXES = (".mcap", ".db3", ".yaml", ".zstd", ".lz4")


def single_file(path: Path, options: OutputOptions) -> bool:
    """Whether ``path`` names one MCAP file (it ends in ``.mcap``) rather than a bag directory.

    Raises:
        SurgeryError: ``options`` ask what one MCAP file cannot carry: another storage, or a
            split.
    """
    if path.suffix.lower() != ".mcap":
        return False
    if options.storage != "mcap":
        raise SurgeryError(
            f"{options.storage} writes a bag directory and {path} names one MCAP file "
            "(name it without .mcap)",
            "output.storage",
        )
    if options.max_bag_size or options.max_bag_duration_s:
        raise SurgeryError(
            f"{path} names one MCAP file, which is not split (name it without .mcap)",
            "output.max_bag_size, output.max_bag_duration_s",
        )
    return True


def check_replaceable(path: Path) -> None:
    """Raise SurgeryError unless ``path`` is something ``--force`` may replace: a bag or file.

    A directory that holds folders or other files, or holds the working directory, is not
    replaced: ``-o .`` or a mistyped name must not delete what was never a bag.
    """
    if path.is_symlink() or path.is_file():
        return
    resolved = path.resolve()
    if Path.cwd().resolve().is_relative_to(resolved):
        raise SurgeryError(f"{path} holds the working directory: not replaced")
    others = [
        c.name for c in resolved.iterdir() if c.is_dir() or not c.name.endswith(_BAG_SUFFIXES)
    ]
    if others:
        raise SurgeryError(
            f"{path} is not a bag directory (it holds {', '.join(sorted(others)[:3])}): "
            "not replaced, remove it yourself or choose another name"
        )
