"""The recorder's services: ``~/snapshot`` (rosbag2's name) and the others it is given.

``rosbag2_interfaces`` has no wheel, so the services use ``std_srvs`` types: ``Trigger`` for
actions (``~/snapshot``). They live on a node of their own, ``<node_name>_control``, spun by an
executor in a thread: the recorder's node has no executor (its take thread drains its raw
subscriptions itself, which an executor would compete for). The names are the recorder node's
private ones (``/<node_name>/snapshot``), as ``ros2 bag record`` offers them.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Mapping

from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger

from bagkit.errors import BagkitError

# What an action service does: returns the response's message, raises BagkitError on failure.
Action = Callable[[], str]


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
            self._node.create_service(Trigger, f"/{node_name}/{name}", _trigger_callback(action))
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


def _trigger_callback(
    action: Action,
) -> Callable[[Trigger.Request, Trigger.Response], Trigger.Response]:
    def serve(_request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        try:
            response.message = action()
            response.success = True
        except BagkitError as exc:
            response.message = str(exc)
            response.success = False
        return response

    return serve
