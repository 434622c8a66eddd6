"""Every table the CLI prints, under one rule: a cell is never cut nor wrapped.

Topic, type, field and file names are what users copy into ``--topics`` and scripts, so a name
broken over two lines is a wrong name. A table is printed in aligned columns when its widest
row fits the console (80 columns when stdout is no terminal, or ``COLUMNS``); otherwise each
row becomes a record: its first cell on a line, the other cells (``header value``) as many to
a line as fit, indented below it. Lines are then as long as their names, never broken inside one.

Colours go through rich on a terminal only: piped output is plain text, written without
importing rich (`bagkit info` is a cold start).
"""

from __future__ import annotations

import os
import sys
import textwrap
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

from bagkit.words import counted

if TYPE_CHECKING:
    from rich.console import Console

GAP = "  "  # between columns
INDENT = "  "  # a record's first line; its figures are indented three times this
DEFAULT_WIDTH = 80  # rich's width of a console that is no terminal


# A NamedTuple, not a frozen dataclass: a printed table makes one per cell and piece of a
# line, and a tuple is made several times faster (so is its class, at every start).
class Styled(NamedTuple):
    """Text in a rich style (``"red"``, ``"bold green"``): coloured on a terminal only."""

    text: str
    style: str = ""


Cell = str | Styled
Line = list[Styled]


@dataclass(frozen=True)
class Column:
    """A column: its header, alignment and the style of its cells."""

    header: str
    numeric: bool = False  # right-aligned
    style: str = ""


@dataclass
class Table:
    """Rows of cells under columns; ``footer`` rows (totals) come after a rule."""

    columns: Sequence[Column]
    title: str | None = None
    rows: list[Sequence[Cell]] = field(default_factory=list)
    footer: list[Sequence[Cell]] = field(default_factory=list)

    def add_row(self, *cells: Cell) -> None:
        """Append a row of one cell per column."""
        self.rows.append(self._checked(cells))

    def add_footer(self, *cells: Cell) -> None:
        """Append a row shown after a rule (a total)."""
        self.footer.append(self._checked(cells))

    def _checked(self, cells: Sequence[Cell]) -> Sequence[Cell]:
        if len(cells) != len(self.columns):
            raise ValueError(
                f"{counted(len(cells), 'cell')} for {counted(len(self.columns), 'column')}"
            )
        return cells

    def widths(self) -> list[int]:
        """The width of each column: its widest cell or header."""
        rows = [[c.header for c in self.columns], *self.rows, *self.footer]
        return [max(cell_len(_plain(row[i])) for row in rows) for i in range(len(self.columns))]

    def fits(self, width: int) -> bool:
        """Whether aligned columns fit ``width`` characters."""
        return sum(self.widths()) + len(GAP) * (len(self.columns) - 1) + len(INDENT) <= width


def print_table(table: Table) -> None:
    """Print ``table`` in aligned columns if it fits the console, else one record per row."""
    console = _rich_console()  # once a table: each lookup asks whether stdout is a terminal
    if table.title is not None:
        _write_line([Styled(table.title, "bold")], console)
    if table.fits(_width(console)):
        _print_columns(table, console)
    else:
        _print_records(table, console)


def _print_columns(table: Table, console: Console | None) -> None:
    widths = table.widths()
    rule = [Styled(INDENT + GAP.join("─" * w for w in widths), "dim")]
    _write_line(_row(table.columns, [c.header for c in table.columns], widths, "bold"), console)
    _write_line(rule, console)
    for row in table.rows:
        _write_line(_row(table.columns, row, widths), console)
    if table.footer:
        _write_line(rule, console)
        for row in table.footer:
            _write_line(_row(table.columns, row, widths), console)


def _row(
    columns: Sequence[Column], cells: Sequence[Cell], widths: list[int], style: str = ""
) -> Line:
    line = [Styled(INDENT)]
    for index, (column, cell, width) in enumerate(zip(columns, cells, widths, strict=True)):
        text = _styled(cell, style or column.style)
        pad = Styled(" " * (width - cell_len(text.text)))
        last = index == len(columns) - 1
        line += [pad, text] if column.numeric else [text] + ([] if last else [pad])
        if not last:
            line.append(Styled(GAP))
    return line


def _print_records(table: Table, console: Console | None) -> None:
    """Each row as its first cell, then ``header value`` of the others, as many to a line
    as fit (one alone when even that does not)."""
    first = table.columns[0]
    labels = [Styled(f"{column.header.lower()} ") for column in table.columns[1:]]
    for row in [*table.rows, *table.footer]:
        _write_line([Styled(INDENT), _styled(row[0], first.style or "bold")], console)
        figures = [
            [label, _styled(cell, column.style)]
            for label, column, cell in zip(labels, table.columns[1:], row[1:], strict=True)
            if _plain(cell)
        ]
        _print_packed(figures, sep=", ", lead=INDENT * 3, indent=INDENT * 3, console=console)


def print_wrapped(
    pieces: Sequence[Cell], *, sep: str = " ", lead: str = "", indent: str = INDENT * 2
) -> None:
    """Print ``pieces`` joined by ``sep`` after ``lead``, as many to a line as fit the
    console's width, the following lines after ``indent``; a piece (a name, ``10 msgs``) is
    never split."""
    pieces_alone = [[_styled(piece, "")] for piece in pieces]
    _print_packed(pieces_alone, sep=sep, lead=lead, indent=indent, console=_rich_console())


def _print_packed(
    pieces: list[Line], *, sep: str, lead: str, indent: str, console: Console | None
) -> None:
    width = _width(console)
    line, used, empty = [Styled(lead)], cell_len(lead), True
    for piece in pieces:
        size = sum(cell_len(part.text) for part in piece)
        if not empty and used + len(sep) + size > width:
            _write_line(line, console)
            line, used, empty = [Styled(indent)], cell_len(indent), True
        if not empty:
            line.append(Styled(sep))
            used += len(sep)
        line += piece
        used += size
        empty = False
    if not empty:
        _write_line(line, console)


def print_command(command: str, *, lead: str) -> None:
    """Print the shell ``command`` after ``lead`` within the console's width: a long one goes
    on over lines ending in `` \\`` (pasted into a shell, it is the one command), an option
    kept with its value, no word broken (a line is then as long as its word)."""
    console = _rich_console()
    lines = shell_lines(command, _width(console) - cell_len(lead))
    for line in lines:
        _write_line([Styled(lead + line)], console)


def shell_lines(command: str, width: int) -> list[str]:
    """``command`` (words quoted as :func:`shlex.quote` quotes them) over lines of at most
    ``width`` cells, each but the last ending in `` \\``, the following indented by two."""
    import shlex  # here: most commands print no shell command

    pieces: list[str] = []
    for word in map(shlex.quote, shlex.split(command)):
        if pieces and pieces[-1].startswith("-") and " " not in pieces[-1] and word[0] != "-":
            pieces[-1] += " " + word  # an option and its value
        else:
            pieces.append(word)
    lines = [pieces[0]]
    for piece in pieces[1:]:
        if cell_len(lines[-1]) + 1 + cell_len(piece) + len(" \\") > width:
            lines.append("  " + piece)
        else:
            lines[-1] += " " + piece
    return [line + " \\" for line in lines[:-1]] + lines[-1:]


def print_fields(rows: Sequence[tuple[str, str]], *, names: frozenset[str] = frozenset()) -> None:
    """``key: value`` lines with the values aligned; a value on several lines keeps the column.

    A value under a key of ``names`` (file names) is never cut; other long values (free text,
    JSON documents) wrap at spaces within the console's width.
    """
    console = _rich_console()
    key_width = max((len(key) for key, _ in rows), default=0) + 1
    room = max(_width(console) - key_width - len(GAP), 20)
    for key, value in rows:
        lines = value.split("\n") if key in names else _wrapped(value, room)
        for index, text in enumerate(lines):
            label = f"{key}:" if index == 0 else ""
            _write_line([Styled(label.ljust(key_width), "bold"), Styled(GAP + text)], console)


def _wrapped(value: str, width: int) -> list[str]:
    return [
        wrapped
        for line in value.split("\n")
        for wrapped in textwrap.wrap(line, width, break_on_hyphens=False) or [""]
    ]


def print_line(parts: Sequence[Cell]) -> None:
    """Write one line of literal text to stdout: styled through rich on a terminal, plain
    (and without importing rich) otherwise."""
    _write_line(parts, _rich_console())


def _write_line(parts: Sequence[Cell], console: Console | None) -> None:
    """:func:`print_line` on ``console`` (:func:`_rich_console`'s answer)."""
    if console is None:
        sys.stdout.write("".join(_plain(part) for part in parts).rstrip() + "\n")
        return
    from rich.text import Text

    text = Text()
    for part in (_styled(part, "") for part in parts):
        text.append(part.text, style=part.style or None)
    text.rstrip()
    console.print(text, soft_wrap=True)


def _rich_console() -> Console | None:
    """bagkit's stdout console where colours can show (a terminal, or FORCE_COLOR), else None."""
    if not (sys.stdout.isatty() or os.environ.get("FORCE_COLOR")):
        return None
    from bagkit.cli import common

    return common.console


def _width(console: Console | None) -> int:
    """The width lines are laid out for on ``console`` (:func:`_rich_console`'s answer):
    rich's console width (``COLUMNS``, the terminal's, or 80 when stdout is no terminal)."""
    if console is not None:
        return console.width
    columns = os.environ.get("COLUMNS", "")
    return int(columns) if columns.isdigit() and int(columns) > 0 else DEFAULT_WIDTH


def cell_len(text: str) -> int:
    """Terminal cells taken by ``text``: East Asian wide characters take two."""
    if text.isascii():
        return len(text)
    return sum(2 if unicodedata.east_asian_width(c) in "WF" else 1 for c in text)


def _styled(cell: Cell, style: str) -> Styled:
    return Styled(cell, style) if isinstance(cell, str) else cell


def _plain(cell: Cell) -> str:
    return cell if isinstance(cell, str) else cell.text
