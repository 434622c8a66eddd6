"""Control a running recorder or player from another process, without the ROS 2 CLI.

What ``ros2 service call /bagkit_player/pause std_srvs/srv/Trigger`` and ``ros2 param set
/bagkit_player rate 2.0`` do, for users whose ROS comes from wheels (no ``ros2`` command): the
node offering a control is found on the graph, its ``std_srvs/srv/Trigger`` service called or
its parameter set through ``rcl_interfaces/srv/SetParameters``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from rcl_interfaces.srv import SetParameters
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from bagkit.ros.errors import ControlError
from bagkit.words import counted

TRIGGER_TYPE = "std_srvs/srv/Trigger"
# The player's services (bagkit.ros.replay.services, seek_services) and the recorder's
# (bagkit.ros.record.control_services): every one a Trigger.
PLAYER_SERVICES = (
    "pause", "resume", "toggle_paused", "play_next", "is_paused", "get_rate", "play", "stop",
)  # fmt: skip
RECORDER_SERVICES = ("pause", "resume", "is_paused", "split_bagfile", "snapshot")
SERVICES = tuple(dict.fromkeys(PLAYER_SERVICES + RECORDER_SERVICES))
# The player's parameters and how a value given as text becomes the parameter's value.
PARAMETERS: dict[str, Callable[[str], Any]] = {"rate": float, "seek": str, "burst": int}
# The player offers this service and nothing else does: a node with it holds the parameters.
_PLAYER_MARK = "get_rate"
# Who offers a control that a running recorder or player may lack.
_OFFERED_BY = {
    "snapshot": "bagkit record --snapshot-mode offers it",
    "split_bagfile": "bagkit record offers it",
    **{
        c: "bagkit play offers it"
        for c in (*PLAYER_SERVICES, *PARAMETERS)
        if c not in RECORDER_SERVICES
    },
}
# rosbag2's names that bagkit serves under another: ``split`` for ``split_bagfile``.
ALIASES = {"split": "split_bagfile", "set_rate": "rate"}


@dataclass(frozen=True, slots=True)
class ControlAnswer:
    """What a node answered.

    Attributes:
        node: the node's fully qualified name.
        control: the service or parameter.
        success: whether it was done (``is_paused``: whether paused).
        message: what was done, or why not.
    """

    node: str
    control: str
    success: bool
    message: str

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready form."""
        return {
            "node": self.node,
            "control": self.control,
            "success": self.success,
            "message": self.message,
        }


def canonical_control(name: str) -> str:
    """The service or parameter a control name stands for (``split`` -> ``split_bagfile``).

    Raises:
        ControlError: no recorder or player offers it.
    """
    name = ALIASES.get(name, name)
    if name not in SERVICES and name not in PARAMETERS:
        known = ", ".join(sorted({*SERVICES, *PARAMETERS, *ALIASES}))
        raise ControlError(f"no control named {name!r} (known: {known})")
    return name


class Controller:
    """A node of its own that finds recorders and players on the graph and controls them.

    Args:
        timeout_s: how long to wait for a control to appear and for an answer.

    Example:
        >>> with Controller() as controller:
        ...     controller.control("pause").message
        'paused'
    """

    def __init__(self, timeout_s: float = 5.0) -> None:
        self.timeout_s = timeout_s
        self._context: Context | None = None
        self._node: Node | None = None
        self._executor: SingleThreadedExecutor | None = None

    def __enter__(self) -> Controller:
        import rclpy

        self._context = Context()
        rclpy.init(context=self._context)
        self._node = Node(
            f"bagkit_control_{os.getpid()}",
            context=self._context,
            start_parameter_services=False,
            enable_rosout=False,
        )
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._executor is not None:
            self._executor.shutdown(timeout_sec=1.0)
        if self._node is not None:
            self._node.destroy_node()
        if self._context is not None:
            self._context.try_shutdown()

    @property
    def node(self) -> Node:
        """The controller's node (entered)."""
        if self._node is None:
            raise ControlError("the controller is not entered")
        return self._node

    def offers(self) -> dict[str, list[str]]:
        """Node name -> the controls it offers (services, and the player's parameters)."""
        found: dict[str, list[str]] = {}
        for name, types in self.node.get_service_names_and_types():
            owner, _, service = name.rpartition("/")
            if service in SERVICES and TRIGGER_TYPE in types:
                found.setdefault(owner or "/", []).append(service)
        for controls in found.values():
            if _PLAYER_MARK in controls:
                controls.extend(PARAMETERS)
        return found

    def targets(self, control: str, node: str | None = None) -> list[str]:
        """The nodes offering ``control`` (only ``node`` when given), waiting for discovery.

        Raises:
            ControlError: none appeared within the timeout.
        """
        wanted = _qualified(node) if node else None
        deadline = time.monotonic() + self.timeout_s
        while True:
            found = sorted(
                owner
                for owner, controls in self.offers().items()
                if control in controls and wanted in (None, owner)
            )
            if found or time.monotonic() >= deadline:
                break
            self._executor_spin(0.1)
        if not found:
            where = f"node {wanted}" if wanted else "no recorder or player"
            domain = os.environ.get("ROS_DOMAIN_ID", "0")
            others = {o: c for o, c in self.offers().items() if wanted in (None, o)}
            if not others:
                raise ControlError(
                    f"{where} offers {control!r} on ROS_DOMAIN_ID {domain} "
                    f"(waited {self.timeout_s:g} s; is it running, on this domain?)"
                )
            # Running, but not offering it: say what they offer and who would.
            offered = "; ".join(f"{o} offers {', '.join(c)}" for o, c in sorted(others.items()))
            raise ControlError(
                f"{where} offers {control!r} on ROS_DOMAIN_ID {domain}: {offered}"
                f" ({_OFFERED_BY.get(control, 'a recorder or a player offers it')})"
            )
        return found

    def control(
        self, name: str, value: str | None = None, node: str | None = None
    ) -> ControlAnswer:
        """Call service ``name``, or set parameter ``name`` to ``value``, on the one node that
        offers it (or ``node``).

        Raises:
            ControlError: an unknown control, a missing or extra value, no node or several
                offering it, no answer within the timeout.
        """
        control = canonical_control(name)
        if control in PARAMETERS and value is None:
            raise ControlError(f"{control} needs a value (bagkit control {control} VALUE)")
        if control not in PARAMETERS and value is not None:
            raise ControlError(f"{control} takes no value (got {value!r})")
        targets = self.targets(control, node)
        if len(targets) > 1:
            raise ControlError(
                f"{counted(len(targets), 'node')} offer {control!r} ({', '.join(targets)}): "
                "name one with --node"
            )
        if control in PARAMETERS:
            assert value is not None
            return self._set(targets[0], control, value)
        return self._call(targets[0], control)

    def _call(self, node: str, service: str) -> ControlAnswer:
        client = self.node.create_client(Trigger, f"{node}/{service}")
        try:
            response = self._answer(client, Trigger.Request(), f"{node}/{service}")
        finally:
            self.node.destroy_client(client)
        return ControlAnswer(node, service, bool(response.success), str(response.message))

    def _set(self, node: str, parameter: str, text: str) -> ControlAnswer:
        try:
            value = PARAMETERS[parameter](text)
        except ValueError:
            kind = PARAMETERS[parameter].__name__
            raise ControlError(f"{parameter} takes a {kind}, not {text!r}") from None
        request = SetParameters.Request()
        request.parameters = [Parameter(parameter, value=value).to_parameter_msg()]
        client = self.node.create_client(SetParameters, f"{node}/set_parameters")
        try:
            response = self._answer(client, request, f"{node}/set_parameters")
        finally:
            self.node.destroy_client(client)
        result = response.results[0]
        message = f"{parameter} set to {value!r}" if result.successful else str(result.reason)
        return ControlAnswer(node, parameter, bool(result.successful), message)

    def _answer(self, client: Any, request: Any, name: str) -> Any:
        if not client.wait_for_service(timeout_sec=self.timeout_s):
            raise ControlError(f"{name} did not become available within {self.timeout_s:g} s")
        future = client.call_async(request)
        deadline = time.monotonic() + self.timeout_s
        while not future.done() and time.monotonic() < deadline:
            self._executor_spin(0.05)
        if not future.done():
            raise ControlError(f"{name} did not answer within {self.timeout_s:g} s")
        return future.result()

    def _executor_spin(self, seconds: float) -> None:
        assert self._executor is not None
        self._executor.spin_once(timeout_sec=seconds)


def _qualified(node: str) -> str:
    return node if node.startswith("/") else f"/{node}"
