"""``bagkit`` run in this process, answered as a subprocess run would be.

A subprocess costs the interpreter's and the CLI's start (a few tenths of a second) per run;
tests that check what many commands answer run them here, and keep a subprocess where the
process boundary is the point (what reaches the terminal, the exit status a shell sees).
"""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

from bagkit.cli.common import run_app
from bagkit.cli.main import app

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def bagkit_in_process(
    args: list[str | Path], cwd: Path | None = None, env: dict[str, str | None] | None = None
) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` through the console script's ``run_app``, in ``cwd`` (default: here),
    with ``env`` over this process's environment (None: unset) while it runs: its exit status
    and what it wrote to stdout and stderr."""
    argv = [str(arg) for arg in args]
    out, err = io.StringIO(), io.StringIO()
    code: int | str | None = 0
    before = Path.cwd()
    os.chdir(cwd or before)
    try:
        # sys.argv as the console script has it: click names the program from it (Usage: bagkit).
        with (
            _environment(env or {}),
            mock.patch.object(sys, "argv", [BAGKIT, *argv]),
            contextlib.redirect_stdout(out),
            contextlib.redirect_stderr(err),
        ):
            run_app(app, argv)
    except SystemExit as exc:
        code = exc.code
    finally:
        os.chdir(before)
    returncode = code if isinstance(code, int) else (0 if code is None else 1)
    return subprocess.CompletedProcess([BAGKIT, *argv], returncode, out.getvalue(), err.getvalue())


@contextlib.contextmanager
def _environment(env: dict[str, str | None]) -> Iterator[None]:
    """``env`` over ``os.environ`` (None: unset), restored after."""
    with mock.patch.dict(os.environ):
        for name, value in env.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        yield


def bagkit_subprocess(args: list[str | Path], cwd: Path) -> subprocess.CompletedProcess[str]:
    """``bagkit ARGS`` as a user's shell runs it, in ``cwd``."""
    return subprocess.run(
        [BAGKIT, *map(str, args)], capture_output=True, text=True, timeout=120, cwd=cwd, check=False
    )
