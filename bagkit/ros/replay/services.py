"""rosbag2's player services on the player's node, in ``std_srvs`` types; a ``rate`` parameter.

rosbag2's own service types (``rosbag2_interfaces``) cannot be installed from wheels, so:

- ``~/pause``, ``~/resume``, ``~/toggle_paused``, ``~/play_next`` are ``std_srvs/srv/Trigger``
  (``success`` as rosbag2's; ``play_next`` succeeds once the next message is published, and
  only while paused);
- ``~/is_paused`` is a ``Trigger`` whose ``success`` says whether playback is paused;
- ``~/get_rate`` is a ``Trigger`` whose ``message`` is the current rate;
- ``~/set_rate`` is the node's ``rate`` parameter: ``ros2 param set /bagkit_player rate 2.0``
  (rejected unless positive); the parameter follows rate changes made from the keyboard.

The services are served by an executor on a thread of their own while the player is open.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager, suppress

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from bagkit.playback.controls import PlayControls
from bagkit.ros.trigger_service import Action, answer, trigger_callback

RATE_PARAMETER = "rate"


@contextmanager
def serve_controls(node: Node, controls: PlayControls) -> Iterator[None]:
    """Offer the control services and the ``rate`` parameter on ``node`` until exit."""
    # Dynamic typing: `ros2 param set ... rate 2` sends an integer.
    node.declare_parameter(RATE_PARAMETER, controls.rate, ParameterDescriptor(dynamic_typing=True))
    node.add_on_set_parameters_callback(lambda params: _set_rate(controls, params))

    def sync_parameter(rate: float) -> None:
        node.set_parameters([Parameter(RATE_PARAMETER, value=rate)])

    controls.on_rate_change = sync_parameter
    answers: dict[str, Action] = {
        "pause": lambda: answer(controls.pause(), "paused", "was paused already"),
        "resume": lambda: answer(controls.resume(), "resumed", "was not paused"),
        "toggle_paused": lambda: (True, "paused" if controls.toggle_paused() else "playing"),
        "play_next": lambda: answer(
            controls.play_next(), "published the next message", "not paused, or no message left"
        ),
        "is_paused": lambda: (controls.paused, "paused" if controls.paused else "playing"),
        "get_rate": lambda: (True, f"{controls.rate:g}"),
    }
    for name, action in answers.items():
        node.create_service(Trigger, f"~/{name}", trigger_callback(action))
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    thread = threading.Thread(target=_spin, args=(executor,), name="player-services", daemon=True)
    thread.start()
    try:
        yield
    finally:
        controls.on_rate_change = None
        executor.shutdown(timeout_sec=1.0)
        thread.join(timeout=2.0)


def _set_rate(controls: PlayControls, parameters: list[Parameter]) -> SetParametersResult:
    for parameter in parameters:
        if parameter.name != RATE_PARAMETER:
            continue
        value = parameter.value
        if not isinstance(value, int | float) or not controls.set_rate(float(value)):
            return SetParametersResult(successful=False, reason="rate must be a positive number")
    return SetParametersResult(successful=True)


def _spin(executor: SingleThreadedExecutor) -> None:
    # The context may be shut down under the executor while the player closes.
    with suppress(ExternalShutdownException):
        executor.spin()
