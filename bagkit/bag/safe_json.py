"""JSON from bags we did not write (custom_data values): a parse error, never a crash.

Python's json decoder recurses once per nesting level: 200,000 ``[`` in a metadata.yaml's
custom_data were a RecursionError that no ``except ValueError`` caught.
"""

from __future__ import annotations

import json
from typing import Any


def loads(text: str) -> Any:
    """``json.loads``, with nesting deeper than the interpreter's stack as a ValueError.

    Raises:
        ValueError: not JSON (json.JSONDecodeError), or nested too deeply.
    """
    try:
        return json.loads(text)
    except RecursionError:
        raise ValueError("JSON nested too deeply") from None
