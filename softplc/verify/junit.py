"""`softplc verify --junit report.xml`: the verdicts as a JUnit XML report for CI.

One test case per requirement (classname: the program): PROVEN passes, VIOLATED is a
failure carrying its counterexample table, UNKNOWN a failure saying why (skipped when
`--bounded` accepts it: no violation within the depth)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path


@dataclass
class Case:
    name: str
    status: str  # PROVEN | VIOLATED | UNKNOWN
    seconds: float
    message: str = ""  # the verdict's line
    detail: str = ""  # the counterexample table, the UNKNOWN's reasons
    accepted: bool = False  # an UNKNOWN `--bounded` accepts


def write(path: Path, program: str, cases: list[Case]) -> None:
    failures = sum(c.status != "PROVEN" and not c.accepted for c in cases)
    skipped = sum(c.accepted for c in cases)
    suite = ET.Element("testsuite", name=f"softplc verify {program}", tests=str(len(cases)),
                       failures=str(failures), errors="0", skipped=str(skipped),
                       time=f"{sum(c.seconds for c in cases):.3f}")
    for c in cases:
        case = ET.SubElement(suite, "testcase", classname=program, name=c.name,
                             time=f"{c.seconds:.3f}")
        if c.status == "PROVEN":
            continue
        tag = "skipped" if c.accepted else "failure"
        el = ET.SubElement(case, tag, message=c.message, type=c.status)
        el.text = c.detail
    ET.indent(suite)
    Path(path).write_text(ET.tostring(suite, encoding="unicode", xml_declaration=True) + "\n")
