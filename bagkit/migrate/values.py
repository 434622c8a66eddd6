"""One value made to fit a field of the new definition, or refused.

Values are those of the decoders (:mod:`bagkit.decode`): Python numbers and strings, numpy
arrays for arrays and sequences of numbers, lists of message objects. A number fits an integer
field when it is whole and in range, a float32 field when it is in float32's range (rounded as
ROS rounds); a string fits a bounded string when it is short enough; an array fits a fixed
array of its length or a sequence within its bound. Nothing is truncated or wrapped: a value
that does not fit raises :class:`ValueMismatchError`, which the caller turns into an error naming
the rule or field.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bagkit.decode.layout import PRIMITIVE_FORMATS
from bagkit.decode.msgdef import Nodetype
from bagkit.words import counted

# numpy dtype of each primitive as the rosbags serializer packs it: CDR's formats, except that
# bool is numpy's own and byte is signed there.
NUMPY_TYPES: dict[str, np.dtype] = {
    name: np.dtype(code) for name, code in {**PRIMITIVE_FORMATS, "bool": "?", "byte": "i1"}.items()
}
FLOAT32_MAX = float(np.finfo(np.float32).max)


class ValueMismatchError(ValueError):
    """A value that does not fit the field (the message says why)."""


def describe(desc: Any) -> str:
    """A field description as the ``.msg`` type it stands for."""
    from bagkit.decode.drift import describe as drift_describe

    return drift_describe(desc)


def is_integer_type(base: str) -> bool:
    return base in NUMPY_TYPES and NUMPY_TYPES[base].kind in "iu"


def fit_scalar(value: Any, base: str, bound: int = 0) -> Any:
    """``value`` as a field of primitive ``base`` holds it.

    Raises:
        ValueMismatchError: it does not fit.
    """
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bytes) and len(value) == 1:  # rclpy's byte fields
        value = value[0]
    if base in ("string", "wstring"):
        if not isinstance(value, str):
            raise ValueMismatchError(f"{value!r} is not text ({base})")
        if bound and len(value) > bound:
            raise ValueMismatchError(f"{value!r} is longer than {base}<={bound}")
        return value
    if isinstance(value, str) or not isinstance(value, bool | int | float):
        raise ValueMismatchError(f"{value!r} is not a number ({base})")
    if base == "bool":
        if value not in (0, 1):
            raise ValueMismatchError(f"{value!r} is not a bool")
        return bool(value)
    if base in ("float32", "float64"):
        number = float(value)
        if base == "float32" and math.isfinite(number) and abs(number) > FLOAT32_MAX:
            raise ValueMismatchError(f"{value!r} is outside float32's range")
        return number
    if isinstance(value, float) and not value.is_integer():
        raise ValueMismatchError(f"{value!r} is not a whole number ({base})")
    info = np.iinfo(NUMPY_TYPES[base])
    number = int(value)
    if not info.min <= number <= info.max:
        raise ValueMismatchError(f"{number} is outside {base}'s range ({info.min}..{info.max})")
    return number


def fit_numbers(value: Any, base: str) -> np.ndarray:
    """An array or list of numbers as an array of primitive ``base``.

    Raises:
        ValueMismatchError: an element does not fit.
    """
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValueMismatchError(f"not an array of numbers ({exc})") from None
    if array.ndim != 1 and array.size:
        raise ValueMismatchError(
            f"an array of {counted(array.ndim, 'dimension')} is not a {base} array"
        )
    array = array.reshape(-1)
    dtype = NUMPY_TYPES[base]
    if array.dtype.kind not in "biuf" and array.size:
        raise ValueMismatchError(f"{array.dtype} values are not {base}")
    if not array.size:
        return np.zeros(0, dtype)
    if dtype.kind in "iu":
        if array.dtype.kind == "f" and not np.all(np.isfinite(array) & (array == np.round(array))):
            raise ValueMismatchError(f"values that are not whole numbers do not fit {base}")
        info = np.iinfo(dtype)
        low, high = array.min(), array.max()
        if low < info.min or high > info.max:
            raise ValueMismatchError(f"values {low}..{high} are outside {base}'s range")
    elif dtype.kind == "b":
        if not np.all((array == 0) | (array == 1)):
            raise ValueMismatchError("values other than 0 and 1 are not bool")
    elif dtype == np.float32:
        finite = array[np.isfinite(array)] if array.dtype.kind == "f" else array
        if finite.size and np.abs(finite).max() > FLOAT32_MAX:
            raise ValueMismatchError("values outside float32's range")
    return array.astype(dtype)


def check_length(count: int, kind: Any, size: int) -> None:
    """Raise ValueMismatchError when ``count`` elements do not fit an array (fixed ``size``) or a
    sequence (bound ``size``, 0: none)."""
    if kind == Nodetype.ARRAY and count != size:
        raise ValueMismatchError(f"{counted(count, 'element')} for an array of {size}")
    if kind == Nodetype.SEQUENCE and size and count > size:
        raise ValueMismatchError(f"{counted(count, 'element')}, over the bound of {size}")


def default_value(desc: Any, make: Any) -> Any:
    """The value a new field takes: zero, false, empty, a default message (``make(type)``)."""
    kind, rest = desc
    if kind == Nodetype.BASE:
        base = rest[0]
        if base in ("string", "wstring"):
            return ""
        return False if base == "bool" else (0.0 if base.startswith("float") else 0)
    if kind == Nodetype.NAME:
        return make(rest)
    sub, size = rest
    count = size if kind == Nodetype.ARRAY else 0
    if sub[0] == Nodetype.BASE and sub[1][0] in NUMPY_TYPES:
        return np.zeros(count, NUMPY_TYPES[sub[1][0]])
    return [default_value(sub, make) for _ in range(count)]
