"""Health contracts: what a recording must look like (``bagkit check --spec``).

:class:`HealthSpec` reads a contract (topics required and forbidden, their type, rate bounds
over a window, the longest gap, value bounds, conditions that must never hold);
:func:`check_bag` evaluates it on a bag with the condition language's evaluator over time.
"""

from bagkit.health.check import Assertion, HealthReport, check_bag
from bagkit.health.spec import HealthSpec, SpecError, TopicContract

__all__ = ["Assertion", "HealthReport", "HealthSpec", "SpecError", "TopicContract", "check_bag"]
