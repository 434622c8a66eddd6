"""bagkit: recording, replay and golden-bag regression for ROS 2 MCAP bags."""

from __future__ import annotations

from typing import TYPE_CHECKING

from bagkit.version import __version__

if TYPE_CHECKING:
    from bagkit.data.frames import read_arrow, read_dataframe

__all__ = ["__version__", "read_arrow", "read_dataframe"]


def __getattr__(name: str) -> object:
    # Imported on first use: `import bagkit` stays cheap (no pandas, no pyarrow).
    if name in __all__:
        from bagkit.data import frames

        return getattr(frames, name)
    raise AttributeError(f"module 'bagkit' has no attribute {name!r}")
