"""A std_srvs/SetBool service ``/svc/toggle`` with introspection on, and a client calling it.

Run as a process by the service tests: ``python service_node.py [--calls N] [--negate]
[--no-server] [--client-introspection]``. The server answers ``success = data`` (``--negate``:
the opposite, a changed handler) and ``message = "set <data>"``; the client makes ``--calls``
calls, one every ``--period`` seconds, alternating ``data``, then the node keeps serving until
SIGINT. It prints ``ready`` once the service is up, ``called N`` after the calls.
"""

from __future__ import annotations

import argparse
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.service_introspection import ServiceIntrospectionState
from std_srvs.srv import SetBool

SERVICE = "/svc/toggle"
# Deep enough that no event of a call overwrites another before delivery (docs/record.md).
EVENT_QOS = QoSProfile(depth=100)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--calls", type=int, default=0)
    parser.add_argument("--period", type=float, default=0.1)
    parser.add_argument("--negate", action="store_true")
    parser.add_argument("--no-server", action="store_true")
    parser.add_argument("--client-introspection", action="store_true")
    parser.add_argument("--wait-subscriber", action="store_true")
    parser.add_argument("--delay", type=float, default=0.0)
    parser.add_argument("--metadata", action="store_true", help="METADATA introspection")
    args = parser.parse_args()
    rclpy.init()
    node = Node("service_node")

    def handle(request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        response.success = request.data != args.negate
        response.message = f"set {request.data}"
        return response

    if not args.no_server:
        service = node.create_service(SetBool, SERVICE, handle)
        state = ServiceIntrospectionState.METADATA if args.metadata else None
        service.configure_introspection(
            node.get_clock(), EVENT_QOS, state or ServiceIntrospectionState.CONTENTS
        )
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    print("ready", flush=True)
    try:
        if args.calls:
            _call(node, executor, args)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def _call(node: Node, executor: SingleThreadedExecutor, args: argparse.Namespace) -> None:
    client = node.create_client(SetBool, SERVICE)
    if args.client_introspection:
        client.configure_introspection(
            node.get_clock(), EVENT_QOS, ServiceIntrospectionState.CONTENTS
        )
    if not client.wait_for_service(timeout_sec=10.0):
        sys.exit("no service")
    if args.wait_subscriber:  # the recorder has subscribed to the events
        topic = f"{SERVICE}/_service_event"
        while node.count_subscribers(topic) == 0:
            executor.spin_once(timeout_sec=0.05)
        time.sleep(0.5)
    time.sleep(args.delay)
    for i in range(args.calls):
        future = client.call_async(SetBool.Request(data=i % 2 == 0))
        executor.spin_until_future_complete(future, timeout_sec=5.0)
        executor.spin_once(timeout_sec=args.period)
        time.sleep(args.period)
    print(f"called {args.calls}", flush=True)


if __name__ == "__main__":
    main()
