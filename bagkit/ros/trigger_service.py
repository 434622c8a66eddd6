"""``std_srvs/srv/Trigger`` services: bagkit's stand-in for rosbag2_interfaces, which has no wheel.

The recorder (``~/pause``, ``~/snapshot`` ...) and the player (``~/pause``, ``~/play`` ...) serve
their controls as Trigger services: ``success`` says whether it was done, ``message`` what.
"""

from __future__ import annotations

from collections.abc import Callable

from std_srvs.srv import Trigger

from bagkit.errors import BagkitError

# What a service does: returns the response's success and message; BagkitError: it failed.
Action = Callable[[], tuple[bool, str]]


def answer(done: bool, yes: str, no: str) -> tuple[bool, str]:
    """A control's answer: whether it was done, and a message saying so either way (a
    ``success=False`` with an empty message tells the caller nothing)."""
    return done, yes if done else no


def trigger_callback(
    action: Action,
) -> Callable[[Trigger.Request, Trigger.Response], Trigger.Response]:
    """A Trigger service callback that answers with ``action()`` (its error as a failure)."""

    def serve(_request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        try:
            response.success, response.message = action()
        except BagkitError as exc:
            response.success, response.message = False, str(exc)
        return response

    return serve
