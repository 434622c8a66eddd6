"""Every table the CLI prints, under one rule: a cell is never cut nor wrapped.

Topic, type, field and file names are what users copy into ``--topics`` and scripts, so a name
broken over two lines is a wrong name. A table is printed in aligned columns when its widest
row fits the console (80 columns when stdout is no terminal); otherwise each row becomes a
record: its first cell on a line, the other cells (``header value``) indented below it. Lines
are then as long as their names, never broken inside one.

Plain text and padding only (no ``rich.table``): `bagkit info` is a cold start.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from bagkit.cli import common

if TYPE_CHECKING:
    from rich.console import Console
    from rich.text import Text

    Cell = str | Text

GAP = "  "  # between columns
INDENT = "  "  # a record's first line; its figures are indented twice


@dataclass(frozen=True)
class Column:
    """A column: its header, alignment and the style of its cells."""

    header: str
    numeric: bool = False  # right-aligned
    style: str = ""


@dataclass
class Table:
    """Rows of cells under columns; ``footer`` rows (totals) come after a rule.

    A ``str`` cell is literal text; a rich ``Text`` cell carries its own colours.
    """

    columns: Sequence[Column]
    title: str | None = None
    rows: list[Sequence[Cell]] = field(default_factory=list)
    footer: list[Sequence[Cell]] = field(default_factory=list)

    def add_row(self, *cells: Cell) -> None:
        """Append a row of one cell per column."""
        if len(cells) != len(self.columns):
            raise ValueError(f"{len(cells)} cells for {len(self.columns)} columns")
        self.rows.append(cells)

    def add_footer(self, *cells: Cell) -> None:
        """Append a row shown after a rule (a total)."""
        if len(cells) != len(self.columns):
            raise ValueError(f"{len(cells)} cells for {len(self.columns)} columns")
        self.footer.append(cells)

    def widths(self) -> list[int]:
        """The width of each column: its widest cell or header."""
        return [
            max(
                _width(row[i])
                for row in [[c.header for c in self.columns], *self.rows, *self.footer]
            )
            for i in range(len(self.columns))
        ]

    def fits(self, width: int) -> bool:
        """Whether aligned columns fit ``width`` characters."""
        return sum(self.widths()) + len(GAP) * (len(self.columns) - 1) + len(INDENT) <= width


def _console() -> Console:
    # Made on first use (common's PEP 562 attribute): a JSON report never imports rich.
    return common.console


def print_table(table: Table) -> None:
    """Print ``table`` in aligned columns if it fits the console, else one record per row."""
    console = _console()
    if table.title is not None:
        console.print(table.title, style="bold", highlight=False, markup=False, soft_wrap=True)
    if table.fits(console.width):
        _print_columns(table)
    else:
        _print_records(table)


def _print_columns(table: Table) -> None:
    from rich.text import Text

    console = _console()
    widths = table.widths()
    rule = Text(INDENT + GAP.join("─" * w for w in widths), style="dim")
    header = _line(table.columns, [c.header for c in table.columns], widths, "bold")
    console.print(header, soft_wrap=True)
    console.print(rule, soft_wrap=True)
    for row in table.rows:
        console.print(_line(table.columns, row, widths), soft_wrap=True)
    if table.footer:
        console.print(rule, soft_wrap=True)
        for row in table.footer:
            console.print(_line(table.columns, row, widths), soft_wrap=True)


def _line(
    columns: Sequence[Column], cells: Sequence[Cell], widths: list[int], style: str = ""
) -> Text:
    from rich.text import Text

    line = Text(INDENT, style=style, end="")
    for index, (column, cell, width) in enumerate(zip(columns, cells, widths, strict=True)):
        text = Text(cell, style=column.style) if isinstance(cell, str) else cell
        pad = " " * (width - text.cell_len)
        last = index == len(columns) - 1
        if column.numeric:
            line.append(pad).append_text(text)
        else:
            line.append_text(text).append("" if last else pad)
        if not last:
            line.append(GAP)
    line.rstrip()
    return line


def _print_records(table: Table) -> None:
    """Each row as its first cell, then ``header value`` of the others, as many to a line
    as fit (one alone when even that does not)."""
    from rich.text import Text

    console = _console()
    indent = INDENT * 3
    first = table.columns[0]
    for row in [*table.rows, *table.footer]:
        console.print(
            Text(INDENT).append_text(_text(row[0], first.style or "bold")), soft_wrap=True
        )
        line = Text(indent)
        for column, cell in zip(table.columns[1:], row[1:], strict=True):
            if not _plain(cell):
                continue
            figure = Text(f"{column.header.lower()} ").append_text(_text(cell, column.style))
            if line.cell_len > len(indent) and line.cell_len + 2 + figure.cell_len > console.width:
                console.print(line, soft_wrap=True)
                line = Text(indent)
            elif line.cell_len > len(indent):
                line.append(", ")
            line.append_text(figure)
        if line.cell_len > len(indent):
            console.print(line, soft_wrap=True)


def print_fields(rows: Sequence[tuple[str, str]], *, names: frozenset[str] = frozenset()) -> None:
    """``key: value`` lines with the values aligned; a value on several lines keeps the column.

    A value under a key of ``names`` (file names) is never cut; other long values (free text,
    JSON documents) wrap at spaces within the console's width.
    """
    from rich.text import Text

    console = _console()
    key_width = max((len(key) for key, _ in rows), default=0) + 1
    room = max(console.width - key_width - len(GAP), 20)
    for key, value in rows:
        lines = value.split("\n") if key in names else _wrapped(value, room)
        for index, line in enumerate(lines):
            label = f"{key}:" if index == 0 else ""
            text = Text().append(label.ljust(key_width), style="bold").append(GAP + line)
            console.print(text, soft_wrap=True)


def print_wrapped(
    pieces: Sequence[Cell], *, sep: str = " ", lead: str = "", indent: str = INDENT * 2
) -> None:
    """Print ``pieces`` joined by ``sep`` after ``lead``, as many to a line as fit the
    console's width, the following lines after ``indent``; a piece (a name, ``10 msgs``) is
    never split."""
    from rich.text import Text

    console = _console()
    line, empty = Text(lead), True
    for piece in pieces:
        text = _text(piece, "")
        if not empty and line.cell_len + len(sep) + text.cell_len > console.width:
            console.print(line, soft_wrap=True)
            line, empty = Text(indent), True
        line.append(sep if not empty else "").append_text(text)
        empty = False
    console.print(line, soft_wrap=True)


def _wrapped(value: str, width: int) -> list[str]:
    return [
        wrapped
        for line in value.split("\n")
        for wrapped in textwrap.wrap(line, width, break_on_hyphens=False) or [""]
    ]


def _text(cell: Cell, style: str) -> Text:
    from rich.text import Text

    return Text(cell, style=style) if isinstance(cell, str) else cell


def _plain(cell: Cell) -> str:
    return cell if isinstance(cell, str) else cell.plain


def _width(cell: Cell) -> int:
    if isinstance(cell, str):
        from rich.cells import cell_len

        return cell_len(cell)
    return cell.cell_len
