"""``--golden-summary FILE``: the golden items' outcomes as a markdown verdict (a headline, then
one table row per fixture and mode), for a CI job summary. Written by the xdist controller from
the reports' user_properties, which cross the worker boundary."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from bagkit.pytest_plugin import (
    FIXTURE_PROPERTY,
    MODE_PROPERTY,
    REPORT_PROPERTY,
    SPEC_FILE,
    VERDICT_PROPERTY,
)


@dataclass(frozen=True, slots=True)
class SummaryRow:
    """One fixture in one mode, as the markdown verdict shows it."""

    fixture: str
    mode: str
    result: str
    verdict: str
    report: str


class GoldenSummary:
    """Collects the golden items' outcomes and writes the markdown verdict at session end."""

    def __init__(self, path: Path, rootpath: Path) -> None:
        self.path = path
        self.rootpath = rootpath
        self.rows: list[SummaryRow] = []

    def pytest_collectreport(self, report: pytest.CollectReport) -> None:
        # A spec that does not load is a fixture that did not run: a row, not a silence.
        if report.failed and Path(report.nodeid).name == SPEC_FILE:
            fixture = Path(report.nodeid).parent.name
            self.rows.append(SummaryRow(fixture, "-", "error", _first_line(report), ""))

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        props = dict(report.user_properties)
        if FIXTURE_PROPERTY not in props or (report.when != "call" and report.passed):
            return
        self.rows.append(
            SummaryRow(
                fixture=str(props[FIXTURE_PROPERTY]),
                mode=str(props[MODE_PROPERTY]),
                result=_result(report, compared=REPORT_PROPERTY in props),
                verdict=str(props.get(VERDICT_PROPERTY) or _first_line(report)),
                report=str(props.get(REPORT_PROPERTY, "")),
            )
        )

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session: pytest.Session, exitstatus: int) -> None:
        text = self.markdown(interrupted=exitstatus == pytest.ExitCode.INTERRUPTED)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.write_text(text)
        except OSError as exc:
            reporter = session.config.pluginmanager.get_plugin("terminalreporter")
            if reporter is not None:
                reporter.ensure_newline()
                reporter.write_line(f"error: --golden-summary {self.path}: {exc.strerror}")
            session.exitstatus = pytest.ExitCode.USAGE_ERROR

    def markdown(self, *, interrupted: bool = False) -> str:
        """The verdict: a headline, then one table row per fixture and mode."""
        # pytest stops before running anything on a collection error (or at Ctrl-C)
        note = ["", "pytest was interrupted: not every fixture ran."] if interrupted else []
        if not self.rows:
            return "\n".join(["## Golden fixtures: none ran", *note]) + "\n"
        bad = [r for r in self.rows if r.result in {"failed", "error"}]
        head = f"FAIL ({len(bad)} of {len(self.rows)})" if bad else f"pass ({len(self.rows)})"
        lines = [
            f"## Golden fixtures: {head}",
            *note,
            "",
            "| fixture | mode | result | verdict | report |",
            "|---|---|---|---|---|",
        ]
        for row in self.rows:
            report = f"`{self._relative(row.report)}`" if row.report else ""
            cells = [row.fixture, row.mode, row.result, row.verdict]
            lines.append("| " + " | ".join([*map(_cell, cells), report]) + " |")
        return "\n".join(lines) + "\n"

    def _relative(self, report: str) -> str:
        path = Path(report)
        return (
            str(path.relative_to(self.rootpath)) if path.is_relative_to(self.rootpath) else report
        )


def _result(report: pytest.TestReport, *, compared: bool) -> str:
    """passed, skipped, failed (the outputs differ) or error (the fixture did not get compared)."""
    if report.passed or report.skipped:
        return report.outcome
    return "failed" if compared and report.when == "call" else "error"


def _first_line(report: pytest.CollectReport | pytest.TestReport) -> str:
    if report.skipped and isinstance(report.longrepr, tuple):
        return report.longrepr[2].removeprefix("Skipped: ")
    text = report.longreprtext.strip()
    return text.splitlines()[0] if text else report.outcome


def _cell(text: str) -> str:
    """Markdown table cell text: a pipe would end the cell."""
    return text.replace("|", "\\|")
