"""The thermostat node: the controller behind a subscription and a publisher.

Run: python -m thermostat.node [--ros-args -p use_sim_time:=true]
"""

from __future__ import annotations

import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.service_introspection import ServiceIntrospectionState
from sensor_msgs.msg import Temperature
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from thermostat.core import INPUT, OUTPUT, STATUS, Controller


class ThermostatNode(Node):
    def __init__(self) -> None:
        super().__init__("thermostat")
        self.controller = Controller()
        self.publisher = self.create_publisher(Float64, OUTPUT, 10)
        self.create_subscription(Temperature, INPUT, self.on_temperature, 10)
        status = self.create_service(Trigger, STATUS, self.on_status)
        # Introspection: each call's events on /thermostat/status/_service_event, for the
        # recorder. Depth 100: with depth 1 a call's request event is overwritten by its
        # response event before delivery.
        status.configure_introspection(
            self.get_clock(), QoSProfile(depth=100), ServiceIntrospectionState.CONTENTS
        )

    def on_status(self, request: Trigger.Request, _response: Trigger.Response) -> Trigger.Response:
        now_ns = self.get_clock().now().nanoseconds
        return self.controller.on_request(STATUS, request, now_ns)

    def on_temperature(self, msg: Temperature) -> None:
        now_ns = self.get_clock().now().nanoseconds
        for _, out in self.controller.on_message(INPUT, msg, now_ns):
            self.publisher.publish(out)


def main() -> None:
    rclpy.init(args=sys.argv)
    node = ThermostatNode()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
