"""play's topics are a query resolved against the bags as every command's: a service by its
name, a name the bags lack one error naming the closest (no ROS: the options and the bags)."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import pytest

from bagkit.bag import BagReader
from bagkit.playback.options import PlayOptions
from bagkit.playback.source import MessageOrder, PlaySource
from bagkit.selection.errors import UnknownTopicError

SERVICES = "rosbag2_tests/resources/mcap/bag_with_topics_and_service_events"


def _selected(options: PlayOptions) -> list[str]:
    with ExitStack() as stack:
        source = PlaySource.open(options.bags, MessageOrder.RECEIVED, stack)
        selection = options.selection_in(source, source.name)
        return sorted(name for name in source.topics if selection.matches(name))


def test_a_service_name_selects_its_event_topic(interop_dir: Path) -> None:
    bag = interop_dir / SERVICES
    with BagReader(bag) as reader:
        events = sorted(t for t in reader.topics if t.endswith("/_service_event"))
        every = sorted(reader.topics)
    service = events[0].removesuffix("/_service_event")
    assert _selected(PlayOptions(bag, topics=(service,))) == [events[0]]
    # Named without its leading slash, as echo takes it; excluded by its name, too.
    assert _selected(PlayOptions(bag, topics=(service.lstrip("/"),))) == [events[0]]
    assert _selected(PlayOptions(bag, exclude_topics=(service,))) == [
        t for t in every if t != events[0]
    ]
    # An exclusion the bag lacks excludes nothing (as ros2 bag play).
    assert _selected(PlayOptions(bag, exclude_topics=("/nope",))) == every


def test_a_name_the_bags_lack_is_an_error_even_beside_known_ones(interop_dir: Path) -> None:
    bag = interop_dir / SERVICES
    with BagReader(bag) as reader:
        known = sorted(reader.topics)[0]
    misspelt = known[:-1]
    with pytest.raises(UnknownTopicError, match=f"{misspelt} not in .*did you mean {known}"):
        _selected(PlayOptions(bag, topics=(known, misspelt)))
