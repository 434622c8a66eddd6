"""Which recorded topics are latched, and their last messages for the start of every file.

A topic is latched when every publisher offers transient-local durability (the offered QoS the
recorder stores per topic), or when ``--repeat-transient-local`` names it. The recorder's
writer keeps their last messages (:class:`~bagkit.recording.latched.LatchedState`) and the bag
writer writes them at the start of every split file; snapshot mode does the same per snapshot.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy

from bagkit.bag import TopicInfo
from bagkit.recording.latched import DEFAULT_DEPTH, LatchedState
from bagkit.recording.options import RecordOptions
from bagkit.ros.qos import parse_offered_qos_profiles


def latched_depth(topic: TopicInfo, options: RecordOptions) -> int:
    """How many of ``topic``'s last messages start every file (0: none)."""
    named = options.repeat_transient_local.get(topic.name)
    if named is not None:
        return named
    if options.repeats_all_transient_local and offered_transient_local(topic):
        return DEFAULT_DEPTH
    return 0


def offered_transient_local(topic: TopicInfo) -> bool:
    """Whether every publisher of ``topic`` offered transient-local durability (latched)."""
    offered = parse_offered_qos_profiles(topic.offered_qos_profiles)
    return bool(offered) and all(
        profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for profile in offered
    )


class LatchedRepeats:
    """The latched state a recording repeats at the start of each split file.

    Args:
        options: the recording's options (which topics, how many messages).
    """

    def __init__(self, options: RecordOptions) -> None:
        self.state = LatchedState()
        self._options = options

    @staticmethod
    def wanted(options: RecordOptions) -> bool:
        """Whether the options ask for repeats at all."""
        return bool(options.repeat_transient_local) or options.repeats_all_transient_local

    def add_topic(self, topic: TopicInfo) -> None:
        """Track ``topic`` if it is latched."""
        depth = latched_depth(topic, self._options)
        if depth:
            self.state.track(topic.name, depth)
