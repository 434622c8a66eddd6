"""``bagkit plot``: fields over time as a PNG or a self-contained interactive HTML page."""

from __future__ import annotations

from pathlib import Path

import typer

from bagkit.cli import common
from bagkit.cli.common import console, handle_errors, none_decoded, warn
from bagkit.cli.option_parsing import BAG_HELP, bag_location, split_list
from bagkit.cli.selection_options import Distro, End, Start, Where, build_query
from bagkit.words import counted

HELP = """Plot fields of BAG over time into OUT: .png (matplotlib) or .html (an interactive page
with zoom, hover and series toggled in the legend, that opens with no network access).

SERIES are TOPIC:FIELD, the field a dotted path or glob (/imu/data:linear_acceleration.*):
one panel per field, labelled with its unit where the message definition or the type implies
one. --bag adds bags drawn over the first (golden against candidate), aligned on each bag's
start; --absolute puts every bag on UTC log time instead. --where plots only the messages
satisfying a condition (each series' topic must have its fields).

Examples:

  bagkit plot flight1 /imu/data:linear_acceleration.z \\
    /barometer/pressure:fluid_pressure -o p.png

  bagkit plot golden /fusion/odometry:pose.pose.position.z \\
    --bag candidate -o altitude.html

  bagkit plot flight1 /imu/data:linear_acceleration.z \\
    --where 'angular_velocity.z > 0.1' -o t.png
"""


@handle_errors
def plot(  # noqa: PLR0917 (typer maps parameters to options)
    bag: Path = typer.Argument(
        ...,
        help=BAG_HELP,
        metavar="BAG",
        show_default=False,
        parser=bag_location,
    ),
    series: list[str] = typer.Argument(
        ..., help="TOPIC:FIELD, field paths or globs.", metavar="SERIES...", show_default=False
    ),
    out: Path = typer.Option(..., "--output", "-o", help="The .png or .html file to write."),
    more_bags: list[str] | None = typer.Option(
        None, "--bag", help="Other bags to overlay (repeat, or a comma list).", metavar="BAG"
    ),
    absolute: bool = typer.Option(
        False, "--absolute", help="X axis in UTC log time (default: seconds from each bag's start)."
    ),
    start: Start = None,
    end: End = None,
    where: Where = None,
    distro: Distro = None,
) -> None:
    from bagkit.data.errors import DataError, nothing_read
    from bagkit.data.series import read_series

    query = build_query(start=start, end=end, where=where)
    suffix = out.suffix.lower()
    if suffix not in (".png", ".html"):
        raise DataError(f"{out}: the output must end in .png or .html")
    bags = [bag, *(bag_location(b) for b in split_list(more_bags))]
    with common.status("reading ..."):
        reading = read_series(bags, series, absolute=absolute, query=query)
    for problem in reading.problems:
        warn(problem)
    found, lost, unread = reading.series, reading.none_decoded(), reading.nothing_read()
    if lost and not found:
        raise none_decoded(lost)
    if unread and not found:  # "nothing in the window" made of lost chunks is no answer
        raise nothing_read(unread, reading.lost)
    if not found and (start is not None or end is not None):
        console.print(f"0 series: nothing in the time window, {out} not written", highlight=False)
        return  # the window's warning said why: an empty result, as every command gives
    if not found and where is not None:
        console.print(f"0 series: no message satisfies {where!r}, {out} not written")
        return
    if not found:
        raise DataError("no message of the requested topics in the bag")
    if suffix == ".png":
        from bagkit.data.plot_png import write_png

        write_png(found, out, absolute=absolute)
    else:
        from bagkit.data.plot_html import write_html

        title = " vs ".join(dict.fromkeys(s.bag for s in found))
        write_html(found, out, title=title, absolute=absolute)
    console.print(
        f"{counted(len(found), 'series', 'series')} -> {out}", highlight=False, soft_wrap=True
    )
    if lost:  # the other series are drawn; a requested one is not there
        raise none_decoded(lost)
    if unread:
        raise nothing_read(unread, reading.lost)
