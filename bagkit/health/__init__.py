"""Health contracts: what a recording must look like (``bagkit check --spec``).

:class:`HealthSpec` reads a contract (topics required and forbidden, their type, rate bounds
over a window, the longest gap, value bounds, conditions that must never hold);
:func:`check_bags` evaluates it on bags (on Dask when given a client) with the condition
language's evaluator over time; :func:`suggest_spec` writes a starting contract from a good bag.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from bagkit.health.check import check, check_bag, check_bags
from bagkit.health.spec import HealthSpec, SpecError, TopicContract
from bagkit.health.verdicts import Assertion, CheckResult, HealthReport

if TYPE_CHECKING:
    from bagkit.health.suggest import suggest_spec

__all__ = [
    "Assertion",
    "CheckResult",
    "HealthReport",
    "HealthSpec",
    "SpecError",
    "TopicContract",
    "check",
    "check_bag",
    "check_bags",
    "suggest_spec",
]


# Imported on first use: checking a contract needs neither the suggestion nor the statistics
# it is made from. An import statement, as bagkit.bag's: -X importtime sees it.
def __getattr__(name: str) -> object:
    if name == "suggest_spec":
        from bagkit.health.suggest import suggest_spec

        return suggest_spec
    raise AttributeError(f"module 'bagkit.health' has no attribute {name!r}")
