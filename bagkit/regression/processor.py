"""The system under test in lockstep: the ``Processor`` protocol and the spec's factory.

A spec names a factory, ``processor: my_pkg.cores:make_processors``; bagkit imports it and
calls it with the spec's ``processor_args`` as keyword arguments. It returns the processors,
one per node of the system, each a plain Python object (no rclpy) that satisfies
``Processor``::

    class Doubler:
        input_topics = ("/value",)
        output_topics = ("/doubled",)
        timer_period_ns = None

        def on_message(self, topic, msg, now_ns):
            return [("/doubled", Float64(data=2.0 * msg.data))]

        def on_timer(self, now_ns):
            return []

    def make_processors():
        return [Doubler()]

Lockstep hands each input message (a ROS message object) to every processor whose
``input_topics`` hold its topic, with the message's log time as ``now_ns``, and calls
``on_timer`` on bag time every ``timer_period_ns``; what they return is written to the
candidate bag. A processor must take time only from ``now_ns`` and own its random generators,
so that the same bag gives the same bytes.

A processor may also answer service requests: ``services`` maps service names to their rclpy
service types and ``on_request(service, request, now_ns)`` returns the response. Lockstep
hands it the golden's recorded requests of the services the spec names (``services:``) at
their log times (:mod:`bagkit.regression.services`); both are optional.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

from bagkit.regression.errors import SpecError

Output = tuple[str, Any]
"""A message to publish: ``(topic, message object)``."""


@runtime_checkable
class Processor(Protocol):
    """One node's logic without rclpy: ROS message objects in, ROS message objects out.

    ``drain_log() -> list`` is optional: where a processor has it, lockstep calls it after
    each callback (and discards what it returns) so that a log buffer stays bounded.
    """

    @property
    def input_topics(self) -> Sequence[str]:
        """Topics whose messages go to ``on_message``."""
        ...

    @property
    def output_topics(self) -> Sequence[str]:
        """Topics the outputs may name (their types are read from the golden bag)."""
        ...

    @property
    def timer_period_ns(self) -> int | None:
        """Period of ``on_timer`` calls on the node clock (bag time); None: no timer."""
        ...

    def on_message(self, topic: str, msg: Any, now_ns: int) -> Sequence[Output]:
        """Handle one received message; return the messages to publish."""
        ...

    def on_timer(self, now_ns: int) -> Sequence[Output]:
        """Handle a timer tick; return the messages to publish."""
        ...


def load_factory(reference: str) -> Any:
    """The callable named by ``module.path:function``.

    Raises:
        SpecError: the reference is malformed, the module cannot be imported or has no such
            attribute, or the attribute is not callable.
    """
    module_name, sep, attribute = reference.partition(":")
    if not sep or not module_name or not attribute:
        raise SpecError(f"processor must read module.path:function, not {reference!r}")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise SpecError(f"processor {reference}: cannot import {module_name}: {exc}") from exc
    factory: Any = module
    for part in attribute.split("."):
        factory = getattr(factory, part, None)
    if not callable(factory):
        raise SpecError(f"processor {reference}: {module_name} has no callable {attribute}")
    return factory


def make_processors(reference: str, args: Mapping[str, Any]) -> list[Processor]:
    """Call the factory ``reference`` with ``args`` and check what it returns.

    Raises:
        SpecError: the factory cannot be loaded, fails, or returns something that is not a
            non-empty sequence of processors.
    """
    factory = load_factory(reference)
    try:
        made = factory(**args)
    except Exception as exc:  # the user's code: any failure is a bad spec or bad args
        raise SpecError(f"processor {reference} failed: {type(exc).__name__}: {exc}") from exc
    processors = list(made) if isinstance(made, Sequence) else [made]
    wrong = [type(p).__name__ for p in processors if not isinstance(p, Processor)]
    if not processors or wrong:
        raise SpecError(
            f"processor {reference} must return Processor objects (input_topics, "
            f"output_topics, timer_period_ns, on_message, on_timer); got {wrong or 'nothing'}"
        )
    return processors
