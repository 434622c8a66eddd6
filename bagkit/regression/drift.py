"""A golden's topics against the installed definitions: a drifted topic fails the check.

A golden stores its messages in the definitions they were recorded with; lockstep and live
checks run today's code with today's types. When a golden topic's stored definition differs
from the installed one, comparing values would report every field of every message (or
decode the inputs wrongly): the check fails with the drift instead, and
``bagkit golden migrate FIXTURE`` rewrites the golden to today's definitions.
"""

from __future__ import annotations

from bagkit.bag import BagReader
from bagkit.decode.drift import DriftStatus, TopicDrift, topic_drift
from bagkit.regression.errors import RegressionError
from bagkit.regression.spec import FixtureSpec


class GoldenDriftError(RegressionError):
    """A golden that cannot be used as it is: its definitions drifted (``golden update``)."""

    exit_code = 1


def golden_drift(spec: FixtureSpec) -> list[TopicDrift]:
    """The topics of ``spec``'s inputs and outputs whose stored definition drifted."""
    wanted = dict.fromkeys([*spec.inputs, *spec.outputs])
    with BagReader(spec.bag, allow_empty=True) as reader:
        found = [
            topic_drift(
                reader.topics[name],
                reader.topic_definitions.get(
                    name, reader.definitions.get(reader.topics[name].type)
                ),
            )
            for name in wanted
            if name in reader.topics
        ]
    return [drift for drift in found if drift.status is DriftStatus.DRIFTED]


def drift_lines(spec: FixtureSpec, drifts: list[TopicDrift]) -> list[str]:
    """The drift report: per topic its changes, then what to do."""
    lines = [
        f"  {d.topic} ({d.type}): the golden's definition differs from the installed one: "
        + "; ".join(d.changes)
        for d in drifts
    ]
    return [*lines, f"  bagkit golden migrate {spec.directory} rewrites the golden to today's"]


def refuse_drift(spec: FixtureSpec) -> None:
    """Raise GoldenDriftError naming the drift of ``spec``'s golden, if any."""
    drifts = golden_drift(spec)
    if drifts:
        raise GoldenDriftError(
            f"{spec.name}: the golden's definitions drifted from the installed ones: "
            + "; ".join(line.strip() for line in drift_lines(spec, drifts))
        )
