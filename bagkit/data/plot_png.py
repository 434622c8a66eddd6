"""Series as a PNG: one panel per ``topic:field``, bags overlaid, with matplotlib (Agg)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from bagkit.data.series import Series, axis_label, decimate

# Points drawn per series: more than a PNG's width can show, far fewer than a long bag holds.
POINTS = 8000
WIDTH_IN, PANEL_HEIGHT_IN, DPI = 11.0, 2.6, 100


def write_png(series: Sequence[Series], path: Path, *, absolute: bool = False) -> None:
    """Draw ``series`` into ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = list(dict.fromkeys(s.key for s in series))
    figure, axes = plt.subplots(
        len(panels),
        1,
        sharex=True,
        squeeze=False,
        figsize=(WIDTH_IN, 0.8 + PANEL_HEIGHT_IN * len(panels)),
        dpi=DPI,
    )
    bags = list(dict.fromkeys(s.bag for s in series))
    for row, key in enumerate(panels):
        ax = axes[row][0]
        members = [s for s in series if s.key == key]
        for s in members:
            times, values = decimate(s.times, s.values, POINTS)
            ax.plot(times, values, linewidth=0.9, label=s.bag, color=f"C{bags.index(s.bag)}")
        ax.set_title(key, fontsize=9, loc="left")
        ax.set_ylabel(axis_label(members[0]), fontsize=8)
        ax.grid(True, alpha=0.3)
        if len(bags) > 1:
            ax.legend(fontsize=8, loc="upper right")
    axes[-1][0].set_xlabel("log time (UTC)" if absolute else "time since bag start [s]")
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    plt.close(figure)
