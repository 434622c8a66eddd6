"""rosbag2's ``~/seek``, ``~/burst``, ``~/play`` and ``~/stop`` on the player's node, from wheels.

rosbag2's own types (``rosbag2_interfaces/srv/Seek``, ``Burst``, ``Play``, ``Stop``) have no
wheel, and no installable service type carries a time or a count, so:

- ``~/play`` and ``~/stop`` are ``std_srvs/srv/Trigger`` services: play resumes a paused replay
  (``success`` false when it was playing), stop ends it as the bag's end would (the report is
  printed, exit 0);
- seek is the node's ``seek`` parameter: ``ros2 param set /bagkit_player seek 1700000012.5``
  (epoch seconds, as rosbag2's absolute time), ``seek 30`` (seconds from the bag's start),
  ``seek -5`` (from its end), ``seek 1700000012500000000ns``; clamped to the window with a
  warning; refused (with the reason) when it is not a time;
- burst is the node's ``burst`` parameter: ``ros2 param set /bagkit_player burst 10`` publishes
  the next 10 messages at once while paused (0: the rest of the pass); refused, with how many
  went out, unless all of them did (not paused: none).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Protocol

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from bagkit.errors import BagkitError
from bagkit.ros.trigger_service import answer, trigger_callback
from bagkit.selection.times import TimeLike, format_ns

SEEK_PARAMETER = "seek"
BURST_PARAMETER = "burst"


class SeekablePlayer(Protocol):
    """What the services call: :class:`bagkit.ros.replay.player.Player`'s methods."""

    def seek(self, to: TimeLike) -> int: ...
    def burst(self, count: int) -> int: ...
    def resume(self) -> bool: ...
    def stop(self) -> None: ...


@contextmanager
def serve_seek(node: Node, player: SeekablePlayer) -> Iterator[None]:
    """Offer ``~/play``, ``~/stop`` and the ``seek`` and ``burst`` parameters on ``node``.

    Served by the executor of :func:`bagkit.ros.replay.services.serve_controls` (created
    before it starts spinning).
    """
    node.declare_parameter(SEEK_PARAMETER, "", ParameterDescriptor(dynamic_typing=True))
    node.declare_parameter(BURST_PARAMETER, 0)
    node.add_on_set_parameters_callback(lambda params: _on_parameters(player, params))
    services = {
        "play": lambda: answer(player.resume(), "playing", "was not paused"),
        "stop": lambda: (_stopped(player), "stopping"),
    }
    for name, action in services.items():
        node.create_service(Trigger, f"~/{name}", trigger_callback(action))
    yield


def _stopped(player: SeekablePlayer) -> bool:
    player.stop()
    return True


def _on_parameters(player: SeekablePlayer, parameters: list[Parameter]) -> SetParametersResult:
    for parameter in parameters:
        if parameter.name == SEEK_PARAMETER:
            result = _seek(player, parameter.value)
        elif parameter.name == BURST_PARAMETER:
            result = _burst(player, parameter.value)
        else:
            continue
        if not result.successful:
            return result
    return SetParametersResult(successful=True)


def _seek(player: SeekablePlayer, value: object) -> SetParametersResult:
    if value == "":
        return SetParametersResult(successful=True)  # the declared empty value
    if not isinstance(value, int | float | str) or isinstance(value, bool):
        return SetParametersResult(successful=False, reason="seek takes a time")
    try:
        target = player.seek(value)
    except BagkitError as exc:
        return SetParametersResult(successful=False, reason=str(exc))
    return SetParametersResult(successful=True, reason=f"seeking to {format_ns(target)}")


def _burst(player: SeekablePlayer, value: object) -> SetParametersResult:
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        return SetParametersResult(successful=False, reason="burst takes a count >= 0")
    published = player.burst(value)
    if (value and published < value) or not published:
        return SetParametersResult(
            successful=False,
            reason=f"burst published {published} of {value or 'the rest'}"
            + ("" if published else " (only while paused)"),
        )
    return SetParametersResult(successful=True, reason=f"burst published {published}")
