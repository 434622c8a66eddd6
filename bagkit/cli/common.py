"""What every command shares: error reporting, output formats and consoles."""

from __future__ import annotations

import enum
import functools
import json
import sys
from collections.abc import Callable
from typing import Any, ParamSpec, TypeVar

import typer
from rich.console import Console

# typer 0.29 vendors click; its exception classes are only importable from there (typer is pinned).
from typer._click.exceptions import NoArgsIsHelpError, UsageError

from bagkit.errors import BagkitError

P = ParamSpec("P")
R = TypeVar("R")

# Tables and results go to stdout; progress, warnings and errors to stderr, so that
# `--format json` output can be piped.
console = Console()
err_console = Console(stderr=True)

EXIT_INTERRUPTED = 130


class OutputFormat(enum.StrEnum):
    """Output format of an inspection command."""

    TABLE = "table"
    JSON = "json"
    CSV = "csv"


def fail(message: str, exit_code: int = 2) -> typer.Exit:
    """Print ``error: message`` on stderr and return the Exit to raise."""
    err_console.print(f"[bold red]error:[/] {message}", highlight=False, soft_wrap=True)
    return typer.Exit(exit_code)


def warn(message: str) -> None:
    """Print ``warning: message`` on stderr."""
    err_console.print(f"[yellow]warning:[/] {message}", highlight=False, soft_wrap=True)


def note(message: str) -> None:
    """Print an informational line on stderr (dim: what a run is doing, not a result)."""
    err_console.print(f"[dim]{message}[/]", highlight=False, soft_wrap=True)


def print_json(data: Any) -> None:
    """Write ``data`` as JSON on stdout (plain, no colour, so scripts can parse it)."""
    sys.stdout.write(json.dumps(data, indent=2, allow_nan=True) + "\n")


def handle_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Turn bagkit errors into one stderr line and their exit code; Ctrl-C into exit 130."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except BagkitError as exc:
            raise fail(str(exc), exc.exit_code) from None
        except KeyboardInterrupt:
            err_console.print("interrupted")
            raise typer.Exit(EXIT_INTERRUPTED) from None
        except OSError as exc:
            raise fail(f"{exc.strerror or exc}: {exc.filename or ''}".rstrip(": "), 2) from None

    return wrapper


def run_app(app: typer.Typer) -> None:
    """Run a typer app as a console script, with usage errors as one ``error:`` line (exit 2).

    Click would print a usage block and a boxed message; a wrong flag is bad input like any
    other, so it gets the same one-line treatment, with a pointer to ``--help``.
    """
    try:
        result = app(standalone_mode=False)
    except NoArgsIsHelpError as exc:
        # Help asked for by omission: print it, exit 2 as click does.
        err_console.print(exc.ctx.get_help() if exc.ctx is not None else "", highlight=False)
        sys.exit(2)
    except UsageError as exc:
        hint = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
        raise SystemExit(fail(exc.format_message() + hint, exc.exit_code).exit_code) from None
    except typer.TyperException as exc:
        raise SystemExit(fail(exc.format_message(), exc.exit_code).exit_code) from None
    except typer.Abort:
        err_console.print("interrupted")
        sys.exit(EXIT_INTERRUPTED)
    sys.exit(result if isinstance(result, int) else 0)
