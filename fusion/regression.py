"""fusion under bagkit's golden-bag regression: the lockstep factory its fixtures name.

``fixtures/<name>/spec.yaml`` says ``processor: fusion.regression:make_processors`` with
``processor_args: {nodes: {data_logger: {}, sensor_fusion: {qnh: 101325.0}}}``; bagkit calls
this function as it would any package's.
"""

from __future__ import annotations

from collections.abc import Mapping

from bagkit.regression import Processor
from fusion.params import flatten
from fusion.processors import Severity, create_processor


def make_processors(nodes: Mapping[str, Mapping[str, object] | None]) -> list[Processor]:
    """The processors of ``nodes`` (node name -> parameter overrides, nested or dotted).

    Raises:
        UnknownNodeError: a node name is not one of fusion's.
        ConfigError: a parameter is unknown, of the wrong type or out of range.
    """
    processors: list[Processor] = []
    for name, params in nodes.items():
        processor = create_processor(name, flatten(params or {}))
        # Nobody reads the log in lockstep; the per-sample debug lines alone cost a tenth of a run.
        processor.min_log_severity = Severity.WARN
        processors.append(processor)
    return processors
