"""``bagkit golden add``: a time window of a bag made into a golden fixture folder.

The window is cut with ``filter``'s code (the latched state from before it written first).
With a spec to copy (``like``), the window's inputs are run through that spec's processors in
lockstep, the system under test starting at the window's start, and the golden holds the
inputs and those outputs, as ``golden update`` makes them; with no spec, the golden is the
window as recorded and ``spec.yaml`` a commented template naming its topics.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.errors import OptionError
from bagkit.regression.errors import RegressionError
from bagkit.regression.lockstep import LockstepResult, run_lockstep
from bagkit.regression.processor import make_processors
from bagkit.regression.spec import BAG_DIR, SPEC_FILE, FixtureSpec, load_spec
from bagkit.selection.query import Query
from bagkit.selection.windows import TimeRange, Window
from bagkit.surgery.around import SPAN_SET_BY_EPISODES, Around, episode_window
from bagkit.surgery.rewrite import filter_bag
from bagkit.surgery.select import Selection
from bagkit.words import counted


@dataclass(frozen=True, slots=True)
class AddOptions:
    """Where a new fixture comes from.

    Attributes:
        bag: the recording to cut.
        span: the window, as a query holds it (``Query.create(start=..., end=...).span``),
            read against ``bag``.
        like: a fixture folder whose ``spec.yaml`` the new fixture copies (None: a template).
        around: instead of a span, ``TOPIC: CONDITION``: the window of its ``episode``-th
            episode (1: the first; matches less than ``gap_ns`` apart merged), ``before_ns``
            before its first match to ``after_ns`` after its last.
    """

    bag: Path
    span: TimeRange = field(default_factory=TimeRange)
    like: Path | None = None
    around: str | None = None
    before_ns: int = 0
    after_ns: int = 0
    gap_ns: int = 0
    episode: int = 1


@dataclass(frozen=True, slots=True)
class AddedFixture:
    """What ``golden add`` wrote: the folder, its spec (None for a template), the window's
    topics with their message counts, and the lockstep run that made the outputs."""

    directory: Path
    spec: FixtureSpec | None
    counts: dict[str, int]
    lockstep: LockstepResult | None = None
    episodes: int = 0
    """With ``around``: the episodes found (``options.episode`` is the fixture's window)."""


def add_fixture(directory: Path, options: AddOptions) -> AddedFixture:
    """Write the fixture folder ``directory`` (``spec.yaml`` and ``golden/``) from a window.

    Raises:
        RegressionError: ``directory`` exists and is not empty, or the window is empty.
        BagError, SelectionError, SurgeryError: the bag or the window cannot be read.
        OptionError: a span beside ``around``, a negative margin, ``like``'s spec without a
            processor (the error names the field).
        SpecError: ``like`` has no valid spec.
    """
    if directory.exists() and any(directory.iterdir()):
        raise RegressionError(f"{directory} exists and is not empty: choose a new folder")
    like = None if options.like is None else load_spec(options.like)
    options, episodes = _around(options)
    window, duration_s = _bag_window(options)
    # On a failure, the folders made here go too (``fixtures/`` as well as ``fixtures/new``).
    made = next((p for p in reversed([directory, *directory.parents]) if not p.exists()), None)
    directory.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryDirectory(dir=directory, prefix=".add-") as tmp:
            cut = Path(tmp) / "window"
            filter_bag(options.bag, cut, Selection(span=TimeRange.of_window(window)))
            with BagReader(cut, allow_empty=True) as reader:
                counts = dict(sorted(reader.topic_counts.items()))
                types = {name: info.type for name, info in reader.topics.items()}
            if not any(counts.values()):
                raise RegressionError(f"no message of {options.bag} in the window")
            if like is None:
                cut.rename(directory / BAG_DIR)
                (directory / SPEC_FILE).write_text(_template(options, window, counts, types))
                return AddedFixture(directory, None, counts, episodes=episodes)
            (directory / SPEC_FILE).write_text(_copied(options, window, like, duration_s))
            spec = load_spec(directory)
            result = run_lockstep(
                cut,
                directory / BAG_DIR,
                processors=make_processors(spec.processor or "", spec.processor_args),
                input_topics=spec.inputs,
                output_topics=spec.outputs,
                copy_topics=[t for t in counts if t not in spec.outputs],
            )
    except BaseException:
        shutil.rmtree(made or directory, ignore_errors=True)
        raise
    return AddedFixture(directory, spec, counts, result, episodes)


def _bag_window(options: AddOptions) -> tuple[Window, float]:
    """The window in the bag's log times, and how long it lasts within the bag in seconds.

    Raises:
        RegressionError: the window holds none of the bag's messages (the one warning's text):
            a window outside the bag is no fixture (its latched state alone would pass any
            test).
    """
    with BagReader(options.bag, allow_empty=True) as reader:
        resolved = Query(span=options.span).resolve(reader, label=str(options.bag))
        first, last = reader.start_ns, reader.end_ns
    if resolved.outside is not None:
        raise RegressionError(resolved.outside)
    window = resolved.window
    start = first if window.start_ns is None else max(window.start_ns, first)
    end = last if window.end_ns is None else min(window.end_ns, last)
    return window, round(max(end - start, 0) / 1e9, 3)


def _around(options: AddOptions) -> tuple[AddOptions, int]:
    """``options`` with the window of the chosen episode of ``around`` as its span (absolute
    times), and how many episodes there were."""
    if options.around is None:
        return options, 0
    if options.span.bounded:
        raise OptionError(SPAN_SET_BY_EPISODES, "span")
    around = Around.create(options.around, options.before_ns, options.after_ns, options.gap_ns)
    window, episodes = episode_window(options.bag, around, options.episode)
    return replace(options, span=TimeRange.of_window(window)), episodes


def _origin(options: AddOptions, window: Window) -> str:
    why = (
        ""
        if options.around is None
        else f" (around episode {options.episode} of {options.around!r})"
    )
    return f"# Cut by `bagkit golden add` from {options.bag}, {window.describe()}{why}.\n"


def _copied(options: AddOptions, window: Window, like: FixtureSpec, duration_s: float) -> str:
    """``like``'s spec.yaml made to fit the new fixture, under a line saying where the window
    comes from: no description (the old one tells of another recording), the window's
    duration, and no ``record_launch`` that reads files of the old fixture's folder (the new
    one lacks them); the rest (system under test, topics, tolerances) as written there."""
    if like.processor is None:
        raise OptionError(
            f"{like.directory / SPEC_FILE} has no processor (lockstep makes the expected "
            "outputs of the window from it)",
            "like",
        )
    lines = (like.directory / SPEC_FILE).read_text().splitlines()
    kept: list[str] = []
    skipping = False  # inside the block of a key left out
    for n, line in enumerate(lines):
        if skipping and not _top_level(line):
            continue
        skipping = False
        key = line.split(":", 1)[0] if _top_level(line) else None
        if key == "description":
            kept.append("description: ''   # say what this window shows")
        elif key == "duration":
            kept.append(f"duration: {duration_s:g}   # seconds: the window's")
        elif key == "record_launch" and "{fixture}" in "\n".join(_block(lines, n)):
            kept.append(f"# record_launch of {like.directory} left out: it reads its files")
            skipping = True
        else:
            kept.append(line)
    origin = _origin(options, window)
    return origin + f"# Spec adapted from {like.directory}.\n" + "\n".join(kept) + "\n"


def _top_level(line: str) -> bool:
    """Whether a spec line starts a top-level key (not a comment, an item or indented)."""
    return line[:1].isalpha()


def _block(lines: list[str], n: int) -> list[str]:
    """Top-level key line ``n`` and the lines under it (indented, list items, blank)."""
    end = next((i for i in range(n + 1, len(lines)) if _top_level(lines[i])), len(lines))
    return lines[n:end]


def _template(
    options: AddOptions, window: Window, counts: dict[str, int], types: dict[str, str]
) -> str:
    topics = "\n".join(f"#   {t}: {types[t]}, {counted(n, 'message')}" for t, n in counts.items())
    return (
        _origin(options, window)
        + "# golden/ holds the window as recorded. Name the system under test, split the\n"
        "# topics into inputs and outputs, then `bagkit golden update` makes the expected\n"
        "# outputs from the inputs (docs/regression.md, 'The spec').\n"
        f"# Topics of the window:\n{topics}\n"
        "description: ''\n"
        "# processor: my_package.regression:make_processors   # lockstep\n"
        "# launch: ros2 run my_package my_node                # live\n"
        f"inputs: [{', '.join(counts)}]\n"
        "outputs: []\n"
    )
