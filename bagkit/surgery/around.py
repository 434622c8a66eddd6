"""``--around 'TOPIC: CONDITION'``: the episodes of a condition and the windows around them.

One implementation for ``filter --around`` (one bag per episode) and ``golden add --around``
(the window of one episode). Episodes are found by :func:`bagkit.data.episodes.find_episodes`;
a window runs from ``before`` before an episode's first match to ``after`` after its last.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

from bagkit.bag import BagReader
from bagkit.data.episodes import Episodes, episode_windows, find_episodes
from bagkit.errors import OptionError
from bagkit.selection.conditions import TopicCondition, parse_topic_condition
from bagkit.selection.topics import absolute_topic_name
from bagkit.selection.windows import Window
from bagkit.surgery.content import with_content
from bagkit.surgery.cut import check_windows_output, cut_windows
from bagkit.surgery.errors import NothingToCutError, SurgeryError
from bagkit.surgery.options import OutputOptions, RewriteReport
from bagkit.surgery.select import Selection

SPAN_SET_BY_EPISODES = "must be empty (each episode of the trigger sets its window)"


@dataclass(frozen=True, slots=True)
class Around:
    """A trigger and the margins around its episodes.

    Attributes:
        trigger: ``TOPIC: CONDITION``.
        before_ns, after_ns: kept before an episode's first match and after its last.
        gap_ns: matches less than this apart are one episode.
        state_topics: topics whose messages hold until the next one, as transient-local
            ones do (an episode lasts until the state changes).
    """

    trigger: TopicCondition
    before_ns: int = 0
    after_ns: int = 0
    gap_ns: int = 0
    state_topics: frozenset[str] = frozenset()

    @classmethod
    def create(
        cls,
        trigger: str,
        before_ns: int = 0,
        after_ns: int = 0,
        gap_ns: int = 0,
        state_topics: Collection[str] = (),
    ) -> Around:
        """Parse ``TOPIC: CONDITION``.

        Raises:
            SelectionError: the trigger does not parse. OptionError: a margin is negative
                (the error names its field).
        """
        for name, value in (("before_ns", before_ns), ("after_ns", after_ns), ("gap_ns", gap_ns)):
            if value < 0:
                raise OptionError(f"must be 0 or more, got {value}", name)
        return cls(
            parse_topic_condition(trigger),
            before_ns,
            after_ns,
            gap_ns,
            frozenset(absolute_topic_name(t) for t in state_topics),
        )

    @property
    def merge_ns(self) -> int:
        """Matches closer than this are one episode when each gets a bag of its own: windows
        that would overlap are one, so that each message is in one bag."""
        return max(self.gap_ns, self.before_ns + self.after_ns + 1)


def find_around(reader: BagReader, around: Around, gap_ns: int, label: str) -> Episodes:
    """The episodes of ``around``'s trigger in an open bag, matches ``gap_ns`` apart merged.

    Raises:
        NothingToCutError: the condition holds for no message. UnknownTopicError,
        UnknownFieldError, UndecodableTopicError.
    """
    found = find_episodes(reader, around.trigger, gap_ns, state_topics=around.state_topics)
    if not found.episodes:
        raise NothingToCutError(f"{label}: {around.trigger.text!r} holds for no message")
    return found


def cut_around(
    bag: Path,
    output: Path,
    around: Around,
    selection: Selection,
    options: OutputOptions | None = None,
) -> tuple[Episodes, list[RewriteReport]]:
    """One bag per episode of ``around`` (``OUT/<bag>_<n>/``), overlapping windows merged;
    ``selection``'s topics, condition and latched state in each.

    Raises:
        OptionError: ``selection`` has a time range (``selection.span``: the episodes set the
            windows); what :func:`find_around` and :func:`~bagkit.surgery.cut.cut_windows`
            raise.
    """
    if selection.span.bounded:
        raise OptionError(SPAN_SET_BY_EPISODES, "selection.span")
    check_windows_output(bag, output, options or OutputOptions())  # before the search
    with BagReader(bag) as reader:
        found = find_around(reader, around, around.merge_ns, str(bag))
    windows = episode_windows(found.episodes, around.before_ns, around.after_ns)
    selection = with_content([bag], selection)  # once, not once per window
    return found, cut_windows(bag, output, windows, selection, options)


def episode_window(bag: Path, around: Around, episode: int) -> tuple[Window, int]:
    """The window around the ``episode``-th episode (from 1, as ``bagkit find`` numbers
    them: matches ``gap_ns`` apart merged) and how many episodes there are.

    Raises:
        SurgeryError: no such episode; what :func:`find_around` raises.
    """
    with BagReader(bag) as reader:
        found = find_around(reader, around, around.gap_ns, str(bag))
    if not 1 <= episode <= len(found.episodes):
        raise SurgeryError(
            f"{bag}: episode {episode} of {around.trigger.text!r} asked for, "
            f"there are {len(found.episodes)} (bagkit find lists them)"
        )
    (window,) = episode_windows([found.episodes[episode - 1]], around.before_ns, around.after_ns)
    return window, len(found.episodes)
