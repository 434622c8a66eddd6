"""bagkit: recording, replay and golden-bag regression for ROS 2 MCAP bags."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from bagkit.version import __version__

if TYPE_CHECKING:
    from bagkit.data.call_frames import read_calls
    from bagkit.data.frames import read_arrow, read_dataframe
    from bagkit.health import (
        Assertion,
        CheckResult,
        HealthReport,
        HealthSpec,
        SpecError,
        TopicContract,
        check,
        suggest_spec,
    )
    from bagkit.selection.conditions import (
        Condition,
        TopicCondition,
        parse_condition,
        parse_topic_condition,
    )

# Imported on first use: `import bagkit` stays cheap (no pandas, no pyarrow, no numpy).
_LAZY = {
    "read_arrow": "bagkit.data.frames",
    "read_dataframe": "bagkit.data.frames",
    "read_calls": "bagkit.data.call_frames",
    "check": "bagkit.health",
    "suggest_spec": "bagkit.health",
    "HealthSpec": "bagkit.health",
    "TopicContract": "bagkit.health",
    "HealthReport": "bagkit.health",
    "CheckResult": "bagkit.health",
    "Assertion": "bagkit.health",
    "SpecError": "bagkit.health",
    "Condition": "bagkit.selection.conditions",
    "TopicCondition": "bagkit.selection.conditions",
    "parse_condition": "bagkit.selection.conditions",
    "parse_topic_condition": "bagkit.selection.conditions",
}

__all__ = [
    "Assertion",
    "CheckResult",
    "Condition",
    "HealthReport",
    "HealthSpec",
    "SpecError",
    "TopicCondition",
    "TopicContract",
    "__version__",
    "check",
    "parse_condition",
    "parse_topic_condition",
    "read_arrow",
    "read_calls",
    "read_dataframe",
    "suggest_spec",
]


def __dir__() -> list[str]:
    # The lazy names too: what tab completion in IPython or Jupyter offers after `bagkit.`.
    return sorted({*globals(), *__all__})


def __getattr__(name: str) -> object:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'bagkit' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
