"""A golden spec's ``health:`` contract, checked on the golden and on each run's outputs.

The golden is checked against the whole contract; a run's candidate (lockstep or live) holds
only the outputs, so it is checked against the contract's topics among them (and the forbidden
topics). Each assertion is a :class:`bagkit.health.Assertion`, named ``TOPIC: ASSERTION``: the
pytest plugin makes one test item of each.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import replace

from bagkit.health import Assertion, HealthReport, HealthSpec
from bagkit.words import counted


def outputs_contract(health: HealthSpec, outputs: Collection[str]) -> HealthSpec:
    """The part of ``health`` a run's outputs can keep: its topics among ``outputs``."""
    return replace(health, topics=tuple(c for c in health.topics if c.topic in outputs))


def assertion_names(health: HealthSpec) -> list[str]:
    """``TOPIC: ASSERTION`` for each assertion of ``health``, in :func:`check_bag`'s order."""
    names = [f"{topic}: forbidden" for topic in health.forbidden]
    for contract in health.topics:
        names.append(f"{contract.topic}: present")
        if contract.type is not None:
            names.append(f"{contract.topic}: type {contract.type}")
        names += [f"{contract.topic}: {text}" for text, _ in contract.never]
    return names


def assertion_name(assertion: Assertion) -> str:
    """``TOPIC: ASSERTION``, as :func:`assertion_names` names it."""
    return f"{assertion.topic}: {assertion.what}"


def by_name(report: HealthReport, health: HealthSpec) -> dict[str, Assertion]:
    """Each assertion of ``health`` in ``report`` by name; those of a topic the bag lacks are
    broken with its reason (check_bag stops at ``present`` for such a topic)."""
    found = {assertion_name(a): a for a in report.assertions}
    missing = {a.topic: a.reason for a in report.assertions if a.what == "present" and not a.passed}
    for name in assertion_names(health):
        topic, what = name.split(": ", 1)
        if name not in found and topic in missing:
            found[name] = Assertion(topic, what, False, reason=f"topic {missing[topic]}")
    return found


def broken_lines(report: HealthReport, where: str) -> list[str]:
    """One line per broken assertion of ``report``: where it broke first (bag seconds)."""
    return [
        f"  health ({where}): {describe(a, report.start_ns)}"
        for a in report.assertions
        if not a.passed
    ]


def describe(assertion: Assertion, start_ns: int) -> str:
    """``TOPIC: ASSERTION broken N times, first at S s`` (or its reason)."""
    name = assertion_name(assertion)
    if not len(assertion.spans):
        return f"{name}: broken ({assertion.reason or 'no message'})"
    first = (int(assertion.spans[0][0]) - start_ns) / 1e9
    return f"{name}: broken {counted(len(assertion.spans), 'time')}, first at {first:.3f} s"
