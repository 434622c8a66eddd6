"""The pack check without rclpy: each report in, the same report judged out.

It sums the cells into the pack voltage, flags the weakest cell below ``LOW_CELL_V`` and keeps
the header, so that lockstep and live runs can be compared field by field.
"""

from __future__ import annotations

from typing import Any

from my_robot_msgs.msg import BatteryReport

INPUT = "/battery/report"
OUTPUT = "/battery/checked"
LOW_CELL_V = 3.3


class PackCheck:
    input_topics = (INPUT,)
    output_topics = (OUTPUT,)
    timer_period_ns = None

    def on_message(self, topic: str, msg: Any, now_ns: int) -> list[tuple[str, Any]]:
        checked = BatteryReport(
            header=msg.header,
            state=msg.state,
            voltage=float(sum(cell.voltage for cell in msg.cells)),
            cell_voltages=msg.cell_voltages,
            cells=msg.cells,
            error_codes=list(msg.error_codes),
        )
        weakest = min(range(len(msg.cells)), key=lambda i: msg.cells[i].voltage, default=None)
        if weakest is not None and msg.cells[weakest].voltage < LOW_CELL_V:
            checked.error_codes = [*checked.error_codes, 100 + weakest]
            checked.status = f"cell {weakest} low"
        else:
            checked.status = "ok"
        return [(OUTPUT, checked)]

    def on_timer(self, now_ns: int) -> list[tuple[str, Any]]:
        return []


def make_processors() -> list[PackCheck]:
    return [PackCheck()]
