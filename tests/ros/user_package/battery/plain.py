"""A message as plain JSON values (what `bagkit echo --format json` prints for it)."""

from __future__ import annotations

import json
from typing import Any


def plain(value: Any) -> Any:
    """Fields in definition order; arrays as lists; floats as the float64 of their value."""
    if hasattr(value, "get_fields_and_field_types"):
        return {name: plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if isinstance(value, str | bytes):
        return value
    if hasattr(value, "__len__"):
        return [plain(item) for item in value]
    if hasattr(value, "item"):  # numpy scalars of fixed arrays
        return value.item()
    return value


def print_json(msg: Any) -> None:
    print(json.dumps(plain(msg)), flush=True)
