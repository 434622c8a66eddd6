"""Command help that the terminal wraps: a paragraph is one line of text, not the source's lines;
option names whole at any width.

typer (0.29) keeps a docstring's line breaks inside a paragraph; lines cut at 100 columns in
the source then wrap again on an 80-column terminal, every other line a stub. Paragraphs with
an indented line (example commands) are printed as written: keep them within 76 columns.
"""

from __future__ import annotations

import inspect

from typer.core import TyperGroup

from bagkit.cli.common import ClickCommand

# click's mark for a paragraph it must not wrap: a wrapped example command cannot be pasted.
VERBATIM = "\b"


def reflow(text: str) -> str:
    """``text`` with the lines of each paragraph joined, but for paragraphs with indented lines,
    which click then prints as they are."""
    paragraphs = inspect.cleandoc(text).split("\n\n")
    return "\n\n".join(
        f"{VERBATIM}\n{paragraph}"
        if any(line.startswith(" ") for line in paragraph.splitlines())
        else " ".join(line.strip() for line in paragraph.splitlines())
        for paragraph in paragraphs
    )


def reflow_command_help(command: ClickCommand) -> None:
    """Reflow the help of ``command`` and of its subcommands, printed as click prints it.

    typer's rich panels cut option names to fit a column at 80 characters
    (``--max-bag-durat…``); click's list never cuts one (a long name gets its help on the
    next line), as ``ros2 bag``'s argparse help.
    """
    if hasattr(command, "rich_markup_mode"):
        command.rich_markup_mode = None
    if command.help:
        command.help = reflow(command.help)
    if isinstance(command, TyperGroup):
        for sub in command.commands.values():
            reflow_command_help(sub)
