"""Health reports as JUnit XML (``bagkit check --junit FILE``): what CI systems show as tests.

One ``testsuite`` per bag, one ``testcase`` per assertion (``classname`` the bag, ``name``
``TOPIC: ASSERTION``); a broken assertion has a ``failure`` saying where it broke (seconds
from the bag's start) and the commands that replay or cut it; a bag that could not be read is
one ``testcase`` with an ``error``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

from bagkit.health.verdicts import HealthReport


def junit_xml(reports: Sequence[HealthReport]) -> str:
    """The XML document for ``reports``."""
    root = ET.Element("testsuites", name="bagkit check")
    for report in reports:
        suite = ET.SubElement(root, "testsuite", name=report.bag)
        failures = errors = 0
        if report.error is not None:
            case = ET.SubElement(suite, "testcase", classname=report.bag, name="read")
            ET.SubElement(case, "error", message=report.error)
            errors += 1
        for assertion in report.assertions:
            case = ET.SubElement(
                suite, "testcase", classname=report.bag, name=f"{assertion.topic}: {assertion.what}"
            )
            if assertion.passed:
                continue
            failures += 1
            lines = [assertion.summary(report.start_ns)]
            lines += assertion.commands(report.bag, report.start_ns)
            failure = ET.SubElement(case, "failure", message=lines[0])
            failure.text = "\n".join(lines)
        cases = len(report.assertions) + (report.error is not None)
        suite.set("tests", str(cases))
        suite.set("failures", str(failures))
        suite.set("errors", str(errors))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def write_junit(reports: Sequence[HealthReport], path: Path) -> None:
    """Write :func:`junit_xml` of ``reports`` to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(junit_xml(reports))
