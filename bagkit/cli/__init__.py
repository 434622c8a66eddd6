"""The ``bagkit`` command line; what another command line built on bagkit may share with it.

The public names: one ``error: ...`` line and its exit code for a ``BagkitError``
(``handle_errors``, ``fail``), the console-script runner (``run_app``), ``OutputFormat``,
``print_json``, and the consoles ``console`` (stdout) and ``err_console`` (stderr), made on
first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from bagkit.cli.common import OutputFormat, fail, handle_errors, print_json, run_app

if TYPE_CHECKING:
    from rich.console import Console

    console: Console
    err_console: Console

__all__ = [
    "OutputFormat",
    "console",
    "err_console",
    "fail",
    "handle_errors",
    "print_json",
    "run_app",
]


def __getattr__(name: str) -> Any:
    # The consoles import rich: made on first use, as in bagkit.cli.common (PEP 562).
    if name in ("console", "err_console"):
        from bagkit.cli import common

        return getattr(common, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
