"""The pack check node: PackCheck behind a subscription and a publisher.

Run: python -m battery.node [--ros-args -p use_sim_time:=true]
"""

from __future__ import annotations

import sys

import rclpy
from my_robot_msgs.msg import BatteryReport
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from battery.core import INPUT, OUTPUT, PackCheck


class PackCheckNode(Node):
    def __init__(self) -> None:
        super().__init__("pack_check")
        self.core = PackCheck()
        self.publisher = self.create_publisher(BatteryReport, OUTPUT, 10)
        self.create_subscription(BatteryReport, INPUT, self.on_report, 10)

    def on_report(self, msg: BatteryReport) -> None:
        now_ns = self.get_clock().now().nanoseconds
        for _, out in self.core.on_message(INPUT, msg, now_ns):
            self.publisher.publish(out)


def main() -> None:
    rclpy.init(args=sys.argv)
    node = PackCheckNode()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
