"""fusion under bagkit's golden-bag regression: the lockstep factory its fixtures name.

``fixtures/<name>/spec.yaml`` says ``processor: fusion.regression:make_processors`` with
``processor_args: {nodes: {data_logger: {}, sensor_fusion: {qnh: 101325.0}}}``; bagkit calls
this function as it would any package's.
"""

from __future__ import annotations

from collections.abc import Mapping

from fusion.params import flatten
from fusion.processors import Severity, create_processor
from fusion.processors.base import Processor


def make_processors(nodes: Mapping[str, Mapping[str, object] | None]) -> list[Processor]:
    """The processors of ``nodes`` (node name -> parameter overrides, nested or dotted).

    Raises:
        UnknownNodeError: a node name is not one of fusion's.
        ConfigError: a parameter is unknown, of the wrong type or out of range.
    """
    processors = [create_processor(name, flatten(params or {})) for name, params in nodes.items()]
    for processor in processors:
        # Nobody reads the log in lockstep; the per-sample debug lines alone cost a tenth of a run.
        processor.min_log_severity = Severity.WARN
    return processors
