"""A simulated room sensor: a cold room warming up, 10 readings a second, seeded noise.

Run: python -m thermostat.sensor
"""

from __future__ import annotations

import math
import random
import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from sensor_msgs.msg import Temperature

from thermostat.core import INPUT

RATE_HZ = 10.0


class RoomSensor(Node):
    def __init__(self) -> None:
        super().__init__("room_sensor")
        self.publisher = self.create_publisher(Temperature, INPUT, 10)
        self.random = random.Random(7)
        self.count = 0
        self.create_timer(1.0 / RATE_HZ, self.publish)

    def publish(self) -> None:
        t = self.count / RATE_HZ
        self.count += 1
        msg = Temperature()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = "office"
        msg.temperature = 17.0 + 4.5 * (1 - math.exp(-t / 8.0)) + self.random.gauss(0.0, 0.05)
        msg.variance = 0.05**2
        self.publisher.publish(msg)


def main() -> None:
    rclpy.init(args=sys.argv)
    node = RoomSensor()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
