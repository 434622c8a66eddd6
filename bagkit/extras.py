"""Optional dependencies: which extra of ``pip install 'bagkit[...]'`` brings what a command needs.

``pip install bagkit`` gives the offline tools. What needs more checks here first, so that a
missing package is one line naming the install command (exit 2), not an ImportError.
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass

from bagkit.errors import BagkitError


class MissingExtraError(BagkitError):
    """A command needs packages of an extra that is not installed."""


@dataclass(frozen=True, slots=True)
class Extra:
    """An extra: its name, the modules it provides, what to call them, another way to get them."""

    name: str
    modules: tuple[str, ...]
    needs: str
    otherwise: str = ""


ROS = Extra("ros", ("rclpy",), "ROS 2 (rclpy)", " or source your ROS 2 Jazzy install")
FLEET = Extra("fleet", ("dask", "distributed"), "Dask (dask, distributed)")
PLOT = Extra("plot", ("plotly",), "plotly")


def installed(extra: Extra) -> bool:
    """Whether every module of ``extra`` can be found (without importing it)."""
    return all(importlib.util.find_spec(module) is not None for module in extra.modules)


def require(extra: Extra, what: str) -> None:
    """Import ``extra``'s modules, or raise MissingExtraError naming the install command.

    Args:
        extra: the extra ``what`` needs.
        what: the command or feature, as the user knows it (``bagkit record``).

    Raises:
        MissingExtraError: a module is absent, or present but fails to import (then its error
            is named too: e.g. an rclpy built for another Python).
    """
    for module in extra.modules:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            found = importlib.util.find_spec(module) is not None
            broken = f" ({module} is there but does not import: {exc})" if found else ""
            raise MissingExtraError(
                f"{what} needs {extra.needs}: pip install 'bagkit[{extra.name}]'"
                f"{extra.otherwise}{broken}"
            ) from None
