"""Help paragraphs joined for the terminal to wrap; example commands kept as written."""

from __future__ import annotations

from bagkit.cli.help_text import reflow


def test_paragraph_lines_are_joined_and_indented_paragraphs_kept() -> None:
    text = """First line.

    Second paragraph, cut
    at the source's width.

    Examples:

      bagkit echo bag /imu -n 3
      bagkit echo bag /gps
    """
    assert reflow(text) == (
        "First line.\n\nSecond paragraph, cut at the source's width.\n\nExamples:\n\n"
        "  bagkit echo bag /imu -n 3\n  bagkit echo bag /gps"
    )
