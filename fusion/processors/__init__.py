"""The nodes' logic without rclpy, by node name: what the nodes and lockstep replay both run.

>>> processor = create_processor("sensor_fusion", {"moving_average_window": 3})
>>> outputs = processor.on_message("/imu/data", imu_msg, now_ns)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from fusion.errors import UnknownNodeError
from fusion.processors import alert_system, data_logger, sensor_fusion, sensor_publisher
from fusion.processors.base import LogLine, ProcessorBase, Severity

NODE_NAMES: tuple[str, ...] = ("sensor_publisher", "data_logger", "alert_system", "sensor_fusion")

_FACTORIES: dict[str, Callable[[Mapping[str, object] | None], ProcessorBase]] = {
    "sensor_publisher": sensor_publisher.SensorPublisher,
    "data_logger": data_logger.DataLogger,
    "alert_system": alert_system.AlertSystem,
    "sensor_fusion": sensor_fusion.SensorFusion,
}

_DESCRIPTIONS: dict[str, dict[str, str]] = {
    "sensor_publisher": sensor_publisher.PARAMETER_DESCRIPTIONS,
    "data_logger": data_logger.PARAMETER_DESCRIPTIONS,
    "alert_system": alert_system.PARAMETER_DESCRIPTIONS,
    "sensor_fusion": sensor_fusion.PARAMETER_DESCRIPTIONS,
}


def _check_name(node_name: str) -> None:
    if node_name not in _FACTORIES:
        raise UnknownNodeError(f"unknown node {node_name!r} (known: {', '.join(NODE_NAMES)})")


def create_processor(node_name: str, params: Mapping[str, object] | None = None) -> ProcessorBase:
    """The processor of ``node_name``; ``params`` (dotted names) override params.yaml defaults.

    Raises:
        UnknownNodeError: ``node_name`` is not in ``NODE_NAMES``.
        ConfigError: a parameter is unknown, of the wrong type or out of range.
    """
    _check_name(node_name)
    return _FACTORIES[node_name](params)


def parameter_descriptions(node_name: str) -> dict[str, str]:
    """Parameter name -> description of ``node_name`` (every parameter in params.yaml)."""
    _check_name(node_name)
    return dict(_DESCRIPTIONS[node_name])


__all__ = [
    "NODE_NAMES",
    "LogLine",
    "ProcessorBase",
    "Severity",
    "create_processor",
    "parameter_descriptions",
]
