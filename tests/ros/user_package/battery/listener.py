"""A subscriber of /battery/report that prints every report it receives as a JSON line.

Run: python -m battery.listener --count N   (exits after N reports)
"""

from __future__ import annotations

import argparse
import sys

import rclpy
from my_robot_msgs.msg import BatteryReport
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args

from battery.core import INPUT
from battery.plain import print_json


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--count", type=int, required=True)
    args = parser.parse_args(remove_ros_args(sys.argv)[1:])
    rclpy.init(args=sys.argv)
    node = Node("battery_listener")
    received: list[BatteryReport] = []

    def on_report(msg: BatteryReport) -> None:
        received.append(msg)
        print_json(msg)

    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(BatteryReport, INPUT, on_report, qos)
    print("listening", file=sys.stderr, flush=True)
    try:
        while len(received) < args.count:
            rclpy.spin_once(node, timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
