"""The battery monitor: known reports on /battery/report, and the charge-limit service.

Run: python -m battery.monitor [--count N]

With ``--count``, it waits for a subscriber, publishes N reports (printing each as a JSON line),
calls its own /battery/set_charge_limit service once (events introspected) and exits;
without, it publishes until stopped.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable

import rclpy
from my_robot_msgs.msg import BatteryReport, CellState
from my_robot_msgs.srv import SetChargeLimit
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.service_introspection import ServiceIntrospectionState
from rclpy.utilities import remove_ros_args

from battery.core import INPUT
from battery.plain import print_json

RATE_HZ = 20.0
SERVICE = "/battery/set_charge_limit"
RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


def report(i: int) -> BatteryReport:
    """Report ``i``: every field depends on it; floats exact in float32."""
    msg = BatteryReport()
    msg.header.stamp.sec = 1_700_000_000 + i
    msg.header.stamp.nanosec = 250_000 * i
    msg.header.frame_id = f"pack_{i % 3}"
    msg.state = BatteryReport.STATE_CHARGING if i % 2 else BatteryReport.STATE_DISCHARGING
    msg.voltage = 14.0 + i / 8
    msg.cell_voltages = [3.5 + i / 64 + k / 32 for k in range(4)]
    msg.cells = [CellState(voltage=3.25 + k / 16, temperature=20.5 + i + k) for k in range(i % 4)]
    msg.error_codes = [-i, i * 1000][: i % 3]
    msg.status = f"report {i}" + "!" * (i % 5)
    return msg


class Monitor(Node):
    def __init__(self) -> None:
        super().__init__("battery_monitor")
        self.publisher = self.create_publisher(BatteryReport, INPUT, RELIABLE)
        self.count = 0
        self.service = self.create_service(SetChargeLimit, SERVICE, self.on_set_charge_limit)
        self.client = self.create_client(SetChargeLimit, SERVICE)
        for endpoint in (self.service, self.client):
            endpoint.configure_introspection(
                self.get_clock(), RELIABLE, ServiceIntrospectionState.CONTENTS
            )

    def publish_next(self) -> BatteryReport:
        msg = report(self.count)
        self.count += 1
        self.publisher.publish(msg)
        return msg

    def on_set_charge_limit(
        self, request: SetChargeLimit.Request, response: SetChargeLimit.Response
    ) -> SetChargeLimit.Response:
        response.accepted = 0.0 < request.limit <= 1.0
        response.message = f"charging stops at {request.limit:.0%}"
        return response


def wait_until(node: Node, condition: Callable[[], bool], what: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            sys.exit(f"battery monitor: no {what} within {timeout_s} s")
        rclpy.spin_once(node, timeout_sec=0.01)


def publish_known(node: Monitor, count: int) -> None:
    """The --count run: subscribers first, then every report, then one service call."""
    events = f"{SERVICE}/_service_event"
    wait_until(node, lambda: node.publisher.get_subscription_count() > 0, "subscriber", 60)
    wait_until(node, lambda: node.count_subscribers(events) > 0, "event subscriber", 60)
    for _ in range(count):
        print_json(node.publish_next())
        time.sleep(1 / RATE_HZ)
    future = node.client.call_async(SetChargeLimit.Request(limit=0.8))
    rclpy.spin_until_future_complete(node, future, timeout_sec=30)
    if not future.done():
        sys.exit("battery monitor: no response from the charge-limit service within 30 s")
    # Every report delivered before the node goes away.
    if not node.publisher.wait_for_all_acked(Duration(seconds=30)):
        sys.exit("battery monitor: reports not acknowledged within 30 s")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--count", type=int, default=None)
    args = parser.parse_args(remove_ros_args(sys.argv)[1:])
    rclpy.init(args=sys.argv)
    node = Monitor()
    try:
        if args.count is None:
            node.create_timer(1 / RATE_HZ, node.publish_next)
            rclpy.spin(node)
        else:
            publish_known(node, args.count)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
