"""JUnit XML for CI systems: one test case a checked capture, the check's summary as the failure message.

The shape the Jenkins/surefire schema (`junit-10.xsd`, the one pytest's --junitxml is checked against)
accepts: <testsuites><testsuite name tests failures errors time><testcase classname name time>
[<failure type message>summary</failure>]</testcase>...  An error (exit 2: unreadable capture, missing
golden) is a failure of type `sniffer.check.error`: that schema has no <error> element in a test case.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

SUITE = "sniffer check"
FAILED, ERROR = "sniffer.check.differs", "sniffer.check.error"


def junit_xml(cases: list[tuple[str, int, object, str]], seconds: float = 0.0) -> bytes:
    """cases: (capture, exit code, summary or None, message) each."""
    failures = sum(1 for _, rc, _, _ in cases if rc != 0)
    root = ET.Element("testsuites", name=SUITE, tests=str(len(cases)), failures=str(failures), errors="0",
                      time=f"{seconds:.3f}")
    suite = ET.SubElement(root, "testsuite", name=SUITE, tests=str(len(cases)), failures=str(failures),
                          errors="0", skipped="0", time=f"{seconds:.3f}")
    for capture, rc, summary, message in cases:
        # one capture a run: its case took the run's time (several would need each one's own)
        case = ET.SubElement(suite, "testcase", classname="sniffer.check", name=capture,
                             time=f"{seconds / len(cases):.3f}")
        if rc == 1 and summary is not None:
            fail = ET.SubElement(case, "failure", type=FAILED, message=summary.headline())
            fail.text = summary.text()
        elif rc != 0:
            fail = ET.SubElement(case, "failure", type=ERROR, message=message.strip())
            fail.text = message
        elif message:
            ET.SubElement(case, "system-err").text = message
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def write_junit(path: str, cases, *, inputs=(), seconds: float = 0.0) -> None:
    """The XML to `path`, written whole under a temporary name (sniffer.formats.outputs)."""
    from sniffer.formats.outputs import Output

    out = Output(path, inputs=[str(i) for i in inputs], what="--junit")
    try:
        with open(out.claim(), "wb") as fh:
            fh.write(junit_xml(cases, seconds))
    except BaseException:
        out.discard()
        raise
    out.commit()
