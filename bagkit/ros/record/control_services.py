"""The recorder's services, with rosbag2's names: ``~/pause``, ``~/resume``, ``~/is_paused``,
and ``~/split_bagfile`` or, in snapshot mode, ``~/snapshot``.

``rosbag2_interfaces`` has no wheel, so every service is a ``std_srvs/srv/Trigger``: ``success``
says whether it was done (``~/is_paused``: whether the recording is paused, as rosbag2's
``IsPaused.paused``), ``message`` what was done. They live on a node of their own,
``<node_name>_control``, spun by an executor in a thread: the recorder's node has no executor
(its take thread drains its raw subscriptions itself, which an executor would compete for).
The names are the recorder node's private ones (``/<node_name>/pause``), as ``ros2 bag
record`` offers them.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Mapping
from typing import Protocol

from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger

from bagkit.recording.options import RecordOptions
from bagkit.recording.report import SnapshotRecord
from bagkit.ros.trigger_service import Action, trigger_callback
from bagkit.selection.times import format_ns
from bagkit.words import counted


class Controlled(Protocol):
    """What the services control: the recorder (:class:`~bagkit.ros.record.recorder.Recorder`)."""

    options: RecordOptions

    @property
    def is_paused(self) -> bool: ...
    def pause(self) -> bool: ...
    def resume(self) -> bool: ...
    def split(self) -> str: ...
    def snapshot(self, reason: str = ...) -> SnapshotRecord: ...


def recorder_actions(recorder: Controlled) -> dict[str, Action]:
    """The services of ``recorder`` by name."""

    def is_paused() -> tuple[bool, str]:
        return recorder.is_paused, "paused" if recorder.is_paused else "recording"

    actions: dict[str, Action] = {
        "pause": lambda: (True, "paused" if recorder.pause() else "was paused already"),
        "resume": lambda: (True, "resumed" if recorder.resume() else "was not paused"),
        "is_paused": is_paused,
    }
    if recorder.options.snapshot_mode:
        actions["snapshot"] = lambda: (True, describe_snapshot(recorder.snapshot("service")))
    else:
        actions["split_bagfile"] = lambda: (True, recorder.split())
    return actions


def describe_snapshot(snapshot: SnapshotRecord) -> str:
    """The ``~/snapshot`` service's answer: which snapshot, and its window."""
    return (
        f"{snapshot.path}: {format_ns(snapshot.start_ns)} - {format_ns(snapshot.end_ns)} "
        f"({counted(snapshot.triggers, 'trigger')})"
    )


class ControlServices:
    """Serve ``Trigger`` services named ``/<node_name>/<name>`` until :meth:`close`.

    Args:
        context: the recorder's rclpy context.
        node_name: the recorder node's name (the services' namespace).
        actions: service name (``snapshot``) -> what it does.
    """

    def __init__(self, context: Context, node_name: str, actions: Mapping[str, Action]) -> None:
        self._node = Node(
            f"{node_name}_control",
            context=context,
            start_parameter_services=False,
            enable_rosout=False,
        )
        for name, action in actions.items():
            self._node.create_service(Trigger, f"/{node_name}/{name}", trigger_callback(action))
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self._node)
        self._thread = threading.Thread(
            target=self._spin, name="bagkit-record-services", daemon=True
        )
        self._thread.start()

    def _spin(self) -> None:
        # The context may be shut down first when the recorder is finishing.
        with contextlib.suppress(ExternalShutdownException):
            self._executor.spin()

    def close(self) -> None:
        """Stop serving and destroy the node."""
        self._executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        self._node.destroy_node()
