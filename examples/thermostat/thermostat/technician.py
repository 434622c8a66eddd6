"""A technician's panel: asks the thermostat for its status every 2 s (a service client).

Run: python -m thermostat.technician
"""

from __future__ import annotations

import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from std_srvs.srv import Trigger

from thermostat.core import STATUS

PERIOD_S = 2.0


class Technician(Node):
    def __init__(self) -> None:
        super().__init__("technician")
        self.client = self.create_client(Trigger, STATUS)
        self.create_timer(PERIOD_S, self.ask)

    def ask(self) -> None:
        if self.client.service_is_ready():
            self.client.call_async(Trigger.Request())


def main() -> None:
    rclpy.init(args=sys.argv)
    node = Technician()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
