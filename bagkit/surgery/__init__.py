"""Bag surgery: ``doctor`` (check), ``recover`` (rewrite a crashed bag), ``filter``, ``merge``.

Built on the MCAP record layer (:mod:`bagkit.bag.mcapio`): a chunk whose messages all pass
and whose compression is the one asked for is copied as it is, without decompressing it.

- :mod:`~bagkit.surgery.select`: which messages pass (topics, exclusions, regexes, time range)
- :mod:`~bagkit.surgery.output`: the bag being written (temp name, split, raw chunk copies)
- :mod:`~bagkit.surgery.copy`, :mod:`~bagkit.surgery.runs`: the streaming, log-time ordered copy
- :mod:`~bagkit.surgery.rewrite`: ``filter``, ``merge`` and ``recover`` on top of it
- :mod:`~bagkit.surgery.message_copy`: the same message by message, for inputs or outputs
  that are not MCAP (SQLite3, ROS 1); :mod:`~bagkit.surgery.convert`: ``convert``
- :mod:`~bagkit.surgery.doctor`, :mod:`~bagkit.surgery.file_check`: every check, one line each
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bagkit.surgery.doctor import Finding, diagnose
    from bagkit.surgery.rewrite import RewriteReport, filter_bag, merge_bags, recover_bag
    from bagkit.surgery.select import Selection

# Imported on first use: doctor decodes schemas (numpy, rosbags), which filter, merge and
# recover never do, and `bagkit filter` should not pay for that import.
_HOMES = {
    "Finding": "doctor",
    "diagnose": "doctor",
    "RewriteReport": "rewrite",
    "filter_bag": "rewrite",
    "merge_bags": "rewrite",
    "recover_bag": "rewrite",
    "Selection": "select",
}

__all__ = [
    "Finding",
    "RewriteReport",
    "Selection",
    "diagnose",
    "filter_bag",
    "merge_bags",
    "recover_bag",
]


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'bagkit.surgery' has no attribute {name!r}")
    return getattr(importlib.import_module(f"bagkit.surgery.{home}"), name)
