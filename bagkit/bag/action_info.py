"""An action's parts in a bag, grouped under the action's name for ``bagkit info``."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass
from typing import Any

from bagkit.bag.info import TopicSummary
from bagkit.selection.actions import FEEDBACK_TOPIC, STATUS_TOPIC, action_topic_part


@dataclass(frozen=True, slots=True)
class ActionSummary:
    """One action's recorded parts: message counts of its feedback and status topics and of
    its services' introspection events (goal, result, cancel; none before Kilted).

    ``type`` is ``pkg/action/Name`` when the feedback topic names it, else ``""``.
    """

    action: str
    type: str
    feedback: int
    status: int
    service_events: int

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``bagkit info --format json``, ``actions[]``)."""
        return asdict(self)


def action_summaries(topics: Iterable[TopicSummary]) -> list[ActionSummary]:
    """The actions whose parts are among ``topics``, sorted by name."""
    parts: dict[str, dict[str, TopicSummary]] = {}
    for topic in topics:
        found = action_topic_part(topic.topic, [topic.type])
        if found is not None:
            parts.setdefault(found[0], {})[found[1]] = topic
    summaries = []
    for action, by_part in sorted(parts.items()):
        feedback = by_part.get(FEEDBACK_TOPIC)
        status = by_part.get(STATUS_TOPIC)
        events = [t for part, t in by_part.items() if part not in (FEEDBACK_TOPIC, STATUS_TOPIC)]
        summaries.append(
            ActionSummary(
                action=action,
                type=feedback.type.removesuffix("_FeedbackMessage") if feedback else "",
                feedback=feedback.count if feedback else 0,
                status=status.count if status else 0,
                service_events=sum(t.count for t in events),
            )
        )
    return summaries
