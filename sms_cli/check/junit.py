"""JUnit XML for CI systems: one test suite for requirements, one for the baseline.

Schema: the de-facto Jenkins/GitLab/GitHub one — ``<testsuites><testsuite name tests failures
errors><testcase classname name><failure message type>text</failure></testcase>…``.
Written atomically. Text that XML 1.0 cannot hold (control characters of a requirement name or a
message) is written as ``\\xNN``, so the file always parses. ``error_junit_xml`` is the report of a
check that could not run (damaged results, an unreadable baseline, an invalid mission): one failing
test case carrying the error, so CI shows why.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

from sms_cli.check.baseline import Drift
from sms_cli.check.requirements import Verdict
from sms_cli.results import write_bytes_atomic


#: characters XML 1.0 does not allow (C0 controls but tab/newline/return, lone surrogates, U+FFFE/F)
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _xml_safe(text: str) -> str:
    return _NOT_XML.sub(lambda m: f"\\x{ord(m.group()):02x}", text)


def _serialize(root: ET.Element) -> bytes:
    for el in root.iter():
        el.attrib = {k: _xml_safe(v) for k, v in el.attrib.items()}
        if el.text:
            el.text = _xml_safe(el.text)
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def _suite(root: ET.Element, name: str) -> ET.Element:
    return ET.SubElement(root, "testsuite", name=name)


def _finish(suite: ET.Element, tests: int, failures: int, errors: int) -> None:
    suite.set("tests", str(tests))
    suite.set("failures", str(failures))
    suite.set("errors", str(errors))


def junit_xml(mission: str, verdicts: list[Verdict] | None, drifts: list[Drift] | None) -> bytes:
    """The XML document (UTF-8 bytes)."""
    root = ET.Element("testsuites", name=f"sms check {mission}")
    total = fails = errs = 0
    if verdicts is not None:
        s = _suite(root, f"{mission}.requirements")
        f = e = 0
        for v in verdicts:
            tc = ET.SubElement(s, "testcase", classname=f"{mission}.requirements.{v.stage or 'results'}", name=v.name)
            value = "missing" if v.value is None else str(v.value)
            ET.SubElement(tc, "system-out").text = f"{v.metric} = {value} {v.unit}; required {v.bound} {v.unit}".strip()
            if v.status == "error":
                e += 1
                ET.SubElement(tc, "error", message=v.message, type="requirement").text = v.message
            elif not v.passed:
                f += 1
                ET.SubElement(tc, "failure", message=v.message, type=v.status).text = v.message
        _finish(s, len(verdicts), f, e)
        total, fails, errs = total + len(verdicts), fails + f, errs + e
    if drifts is not None:
        s = _suite(root, f"{mission}.baseline")
        f = 0
        for d in drifts:
            tc = ET.SubElement(s, "testcase", classname=f"{mission}.baseline.{d.metric.split('.')[0]}", name=d.metric)
            if not d.passed:
                f += 1
                ET.SubElement(tc, "failure", message=d.message, type=d.status).text = d.message
        _finish(s, len(drifts), f, 0)
        total, fails = total + len(drifts), fails + f
    _finish(root, total, fails, errs)
    return _serialize(root)


def error_junit_xml(suite: str, kind: str, message: str) -> bytes:
    """The report of a check that could not run: one test case failing with ``message``."""
    root = ET.Element("testsuites", name=f"sms check {suite}")
    s = _suite(root, f"{suite}.check")
    tc = ET.SubElement(s, "testcase", classname=f"{suite}.check", name="the check runs")
    ET.SubElement(tc, "failure", message=message.splitlines()[0] if message else kind, type=kind).text = message
    _finish(s, 1, 1, 0)
    _finish(root, 1, 1, 0)
    return _serialize(root)


def write_junit(path: Path, mission: str, verdicts: list[Verdict] | None, drifts: list[Drift] | None) -> Path:
    return write_bytes_atomic(path, junit_xml(mission, verdicts, drifts))


def write_error_junit(path: Path, suite: str, kind: str, message: str) -> Path:
    return write_bytes_atomic(path, error_junit_xml(suite, kind, message))
