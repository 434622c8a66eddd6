"""What every command shares: error reporting, output formats and consoles.

Exit codes (docs/hostile-input.md): 0 done, 1 the run failed or found differences, 2 unusable
input or usage, 70 internal error (a bug, whatever the input: please report it), 130
interrupted, 141 the reader of our output went away (broken pipe; quiet, as ``yes | head``).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import os
import sys
import traceback
import warnings
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, NoReturn, ParamSpec, TypeVar, cast, overload

import typer

from bagkit.cli.interrupts import InterruptLatch
from bagkit.compat import StrEnum
from bagkit.errors import BagkitError, OptionError, SettingWarning
from bagkit.words import counted

if TYPE_CHECKING:
    from rich.console import Console
    from rich.status import Status


P = ParamSpec("P")
R = TypeVar("R")


# Tables and results go to stdout; progress, warnings and errors to stderr, so that
# `--format json` output can be piped.
if TYPE_CHECKING:
    console: Console
    err_console: Console


def __getattr__(name: str) -> Any:
    """``console`` and ``err_console``, made on first use (PEP 562).

    Importing rich costs more than ``bagkit --help`` itself; commands that print import them.
    """
    if name not in ("console", "err_console"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from rich.console import Console

    class StdoutConsole(Console):
        """Rich's console, except that a closed pipe ends like any other broken pipe."""

        def on_broken_pipe(self) -> None:
            """Raise BrokenPipeError for handle_errors (rich would exit 1)."""
            raise BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE))

    made = globals()[name] = Console(stderr=True) if name == "err_console" else StdoutConsole()
    return made


def _made(name: str) -> Console:
    """The console ``name`` from inside this module (``__getattr__`` serves importers only)."""
    return cast("Console", globals()[name] if name in globals() else __getattr__(name))


EXIT_INTERNAL = 70  # sysexits.h EX_SOFTWARE
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE, what a shell reports for a process SIGPIPE ended
# Set (to anything but "" or "0") to print the traceback of an internal error before its line.
TRACEBACK_ENV = "BAGKIT_TRACEBACK"
MAX_LINE = 1000  # characters of an error or warning message
_PACKAGE_DIR = Path(__file__).resolve().parents[1]


class OutputFormat(StrEnum):
    """Output format of an inspection command."""

    TABLE = "table"
    JSON = "json"
    CSV = "csv"


def _one_line(message: str, *, markup: bool = True) -> str:
    """A message as one line of literal text, at most ``MAX_LINE`` characters: names and values
    from a bag may be huge, hold newlines and (``markup``: escaped for rich) what rich would
    take for markup (``[/]``)."""
    line = " ".join(message.splitlines())
    if len(line) > MAX_LINE:
        line = f"{line[:MAX_LINE]}... ({counted(len(line) - MAX_LINE, 'character')} cut)"
    if not markup:
        return line
    from rich.markup import escape

    return escape(line)


class ReportFormat(StrEnum):
    """Output format of a command whose output is a report, not rows: no csv."""

    TABLE = "table"
    JSON = "json"


# For commands that read bags (stats, compare); surgery's --crc also says what a bad CRC costs.
CheckCrcOnRead = Annotated[
    bool,
    typer.Option(
        "--crc/--no-crc", help="Check each chunk's CRC as it is read (--no-crc: skip it)."
    ),
]

# Every command answers -h as well as --help (ros2 bag's habit).
CONTEXT_SETTINGS: dict[str, Any] = {"help_option_names": ["-h", "--help"]}


@contextlib.contextmanager
def option_flags(flags: Mapping[str, str]) -> Iterator[None]:
    """In the block, an options error that names a field (:class:`bagkit.errors.OptionError`)
    is one ``error:`` line naming its flag instead (``flags``: field -> flag, or a template
    with ``{}`` for the problem); the library names its own fields, the CLI its flags, in this
    one place."""
    try:
        yield
    except OptionError as exc:
        if exc.field is None:
            raise
        raise fail(_naming_flags(exc, flags), exc.exit_code) from None


# Fields every command that has them sets with the same flag (for handle_errors and every
# option_flags block), and the settings that SettingWarnings name.
SHARED_FLAGS = {
    "output.force": "{} (use --force to replace it)",
    "output.compression": "--compression {}",
    "output.max_bag_size": "--max-bag-size",
    "output.max_bag_duration_s": "--max-bag-duration",
    "output.storage": "--storage",
    "allow_drop": "{}, or pass --allow-drop",
    "regex": "--regex {}",
    "exclude_regex": "--exclude-regex {}",
    "where": "--where {}",
    "events": "--events {}",
    "workers": "--workers {}; for more, start a cluster and give --scheduler",
    "BAGKIT_DISTRO": "--distro NAME",
}


def _naming_flags(exc: OptionError, flags: Mapping[str, str]) -> str:
    """``exc``'s message with its fields named by their flags (or templates) in ``flags``,
    else in SHARED_FLAGS."""
    assert exc.field is not None
    fields = [name.strip() for name in exc.field.split(",")]
    names = ", ".join(flags.get(name, SHARED_FLAGS.get(name, name)) for name in fields)
    return names.format(exc.problem) if "{}" in names else f"{names}: {exc.problem}"


def format_rate(rate_hz: float | None, digits: int = 2) -> str:
    """A topic's rate for a table: ``10.00 Hz``, or ``-`` when it cannot be measured."""
    return "-" if rate_hz is None else f"{rate_hz:.{digits}f} Hz"


def fail(message: str, exit_code: int = 2) -> typer.Exit:
    """Print ``error: message`` on stderr (one line) and return the Exit to raise."""
    if not _stderr_styled():
        sys.stderr.write(f"error: {_one_line(message, markup=False)}\n")
    else:
        _made("err_console").print(
            f"[bold red]error:[/] {_one_line(message)}", highlight=False, soft_wrap=True
        )
    return typer.Exit(exit_code)


def none_decoded(counts: Mapping[str, int]) -> typer.Exit:
    """Say that the topics of ``counts`` (topic -> its messages) decoded none of them, in one
    error line, and return the Exit (2) to raise: a result without a requested topic is no
    success (echo, stats, export, plot, find)."""
    return fail(
        "; ".join(
            f"none of the {counted(n, 'message')} of {topic} decode" for topic, n in counts.items()
        )
    )


def _stderr_styled() -> bool:
    """Whether stderr shows rich's styles and spinners (a terminal, or FORCE_COLOR): else its
    lines are written plain, without importing rich."""
    return sys.stderr.isatty() or bool(os.environ.get("FORCE_COLOR"))


def warn(message: str) -> None:
    """Print ``warning: message`` on stderr (one line)."""
    if not _stderr_styled():
        sys.stderr.write(f"warning: {_one_line(message, markup=False)}\n")
        return
    _made("err_console").print(
        f"[yellow]warning:[/] {_one_line(message)}", highlight=False, soft_wrap=True
    )


def status(text: str) -> contextlib.AbstractContextManager[Status | None]:
    """A spinner saying ``text`` on stderr while the block runs (its ``update`` changes the
    text), on a terminal only: None otherwise (rich's live display costs more to import than
    many commands' work, and older rich writes cursor codes into a pipe)."""
    if not sys.stderr.isatty():
        return contextlib.nullcontext()
    return _made("err_console").status(text)


def note(message: str) -> None:
    """Print an informational line on stderr (dim: what a run is doing, not a result)."""
    _made("err_console").print(f"[dim]{message}[/]", highlight=False, soft_wrap=True)


def print_json(data: Any) -> None:
    """Write ``data`` as JSON on stdout (plain, no colour, so scripts can parse it)."""
    import json  # here: --help and tables do without it (start-up time)

    sys.stdout.write(json.dumps(data, indent=2, allow_nan=True) + "\n")


@overload
def handle_errors(func: Callable[P, R], /) -> Callable[P, R]: ...


@overload
def handle_errors(*, take_sigint: bool) -> Callable[[Callable[P, R]], Callable[P, R]]: ...


def handle_errors(
    func: Callable[P, R] | None = None, /, *, take_sigint: bool = False
) -> Callable[P, R] | Callable[[Callable[P, R]], Callable[P, R]]:
    """Turn bagkit errors into one stderr line and their exit code; Ctrl-C into exit 130.

    Anything else is a bug and goes on to :func:`run_app`. ``take_sigint``: a command that
    runs until stopped (play) stops on SIGINT even when its process started with SIGINT
    ignored, as a shell script's ``bagkit play ... &`` does (``ros2 bag play`` stops too).
    """
    if func is None:
        return functools.partial(_handling_errors, take_sigint=take_sigint)
    return _handling_errors(func, take_sigint=take_sigint)


def _handling_errors(func: Callable[P, R], *, take_sigint: bool) -> Callable[P, R]:
    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        warnings.showwarning = _warning_line
        interrupted = InterruptLatch(take_ignored=take_sigint)
        try:
            with interrupted:
                result = func(*args, **kwargs)
            if interrupted.seen:
                raise KeyboardInterrupt
            return result
        except OptionError as exc:
            message = str(exc) if exc.field is None else _naming_flags(exc, SHARED_FLAGS)
            raise fail(message, exc.exit_code) from None
        except BagkitError as exc:
            raise fail(str(exc), exc.exit_code) from None
        except KeyboardInterrupt:
            raise fail("interrupted", EXIT_INTERRUPTED) from None
        except BrokenPipeError:
            # Here, not in run_app: typer would turn it into exit 1 on the way.
            raise _broken_pipe() from None
        except OSError as exc:
            raise fail(f"{exc.strerror or exc}: {exc.filename or ''}".rstrip(": "), 2) from None

    return wrapper


def _warning_line(message: Warning | str, *_: object, **__: object) -> None:
    """The library's warnings (an empty time window, data loss) as ``warning:`` lines, a
    setting that chooses otherwise named by its flag."""
    if isinstance(message, SettingWarning):
        flag = SHARED_FLAGS.get(message.setting, message.setting)
        warn(f"{message.problem} ({flag} chooses)")
    else:
        warn(str(message))


def _broken_pipe() -> typer.Exit:
    """The reader of stdout went away (``| head``): exit 141 without a word, as a process that
    SIGPIPE ended. stdout then points at /dev/null so that the interpreter's final flush does
    not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout without a file descriptor (captured in-process)
        pass
    return typer.Exit(EXIT_BROKEN_PIPE)


def internal_error_message(exc: BaseException) -> str:
    """One line naming an unexpected exception and the innermost bagkit line it came from."""
    frames = traceback.extract_tb(exc.__traceback__)
    ours = [f for f in frames if Path(f.filename).resolve().is_relative_to(_PACKAGE_DIR)]
    where = ""
    if ours or frames:
        frame = (ours or frames)[-1]
        path = Path(frame.filename).resolve()
        shown = path.relative_to(_PACKAGE_DIR.parent) if ours else path.name
        where = f" at {shown}:{frame.lineno}"
    kind = "out of memory" if isinstance(exc, MemoryError) else "internal error"
    name = type(exc).__qualname__
    if type(exc).__module__ != "builtins":
        name = f"{type(exc).__module__}.{name}"  # struct.error, not "error"
    detail = " ".join(str(exc).split())[:200]
    return (
        f"{kind}: {name}{': ' + detail if detail else ''}{where}; please report it "
        f"({TRACEBACK_ENV}=1 prints the traceback)"
    )


# typer builds its commands on a click of its own that it keeps private (typer._click), and
# bagkit imports no private module: a command or a context of that click is typed Any.
ClickCommand = Any
"""A click command (``TyperCommand``, ``TyperGroup``, or click's base class)."""
ClickContext = Any
"""A click context (``typer.Context`` is a subclass)."""


def run_app(app: typer.Typer | ClickCommand, args: list[str] | None = None) -> NoReturn:
    """Run a typer app or command as a console script (``args``: sys.argv[1:] when None), exit.

    Usage errors are one ``error:`` line (exit 2): click would print a usage block and a boxed
    message; a wrong flag is bad input like any other, so it gets the same one-line treatment,
    with a pointer to ``--help``. An exception that is not a BagkitError is a bug: one
    ``error: internal error ...`` line and exit 70, never a traceback (unless asked for).
    """
    try:
        result = app(args=args, standalone_mode=False)
    except typer.TyperException as exc:
        # click's usage errors carry the command's context; the one that is the help itself
        # (no arguments to a command that has no_args_is_help) prints it, exit 2 as click does.
        ctx = getattr(exc, "ctx", None)
        message = exc.format_message()
        if ctx is not None and message == ctx.get_help():
            _made("err_console").print(message, highlight=False)
            sys.exit(2)
        hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
        raise SystemExit(fail(message + hint, exc.exit_code).exit_code) from None
    except typer.Abort:
        raise SystemExit(fail("interrupted", EXIT_INTERRUPTED).exit_code) from None
    except Exception as exc:
        # The last line of defence: a bug, reported as one line and fixed where it was raised.
        if os.environ.get(TRACEBACK_ENV, "") not in ("", "0"):
            traceback.print_exception(exc)
        raise SystemExit(fail(internal_error_message(exc), EXIT_INTERNAL).exit_code) from None
    try:
        sys.stdout.flush()  # what is still buffered, while a broken pipe can still be reported
    except BrokenPipeError:
        raise SystemExit(_broken_pipe().exit_code) from None
    sys.exit(result if isinstance(result, int) else 0)
