"""A failing `sniffer check` says what changed first: the summary, its JSON, JUnit XML, findings as sets.

The changed-parameter case is built the way a user meets it: the shipped TDS-V8 capture's scenario
recorded again with one drive parameter changed (unit 1's rated current), checked against the shipped
golden.  The expected counts come from the two decodes' frames, not from the summary's own text.
"""

from __future__ import annotations

from pathlib import Path

import orjson
import pytest

from sniffer import cli
from sniffer.analysis.check import EXIT_DIFFERENT, EXIT_SAME
from sniffer.capture.session import decode_capture
from sniffer.commands.check import check

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
TDS = CAPTURES / "sim" / "tds-v8.mcap"
TDS_GOLDEN = CAPTURES / "golden" / "sim-tds-v8.txt"
XSD = Path(__file__).resolve().parent / "data" / "junit-10.xsd"


@pytest.fixture(scope="module")
def changed(tmp_path_factory) -> Path:
    """captures/sim/tds-v8.mcap's recording (captures/regenerate.sh) with unit 1's rated current 12 -> 15 A."""
    out = tmp_path_factory.mktemp("changed") / "tds-v8-rated15.mcap"
    assert cli.main(["simulate", "--scenario", "tds-v8", "--duration", "10", "--seed", "11",
                     "--param", "unit1.rated_current_a=15.0", "--out", str(out)]) == 0
    return out


def _current(f):
    return next((p["value"] for p in f.points if p["name"] == "Output current"), None)


def _expected(changed: Path) -> tuple[int, int, int]:
    """(frames, frames whose Output current differs, the first such frame's index) from the frames."""
    a, b = list(decode_capture(TDS, None)), list(decode_capture(changed, None))
    assert len(a) == len(b)
    diff = [fb.index for fa, fb in zip(a, b) if _current(fa) != _current(fb)]
    assert diff and all(b[i].unit == 1 for i in diff)
    return len(a), len(diff), diff[0]


def test_changed_rated_current_fits_a_screen_and_names_unit_field_values(changed, capsys):
    frames, n, first = _expected(changed)
    assert cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN)]) == EXIT_DIFFERENT
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert len(lines) <= 15, out
    assert f"{n} of {frames} frames differ ({n} changed, 0 added, 0 missing)" in lines[1]
    assert lines[2].startswith(f"  first: frame {first} at ") and "u1 fc03 response: Output current " in lines[2]
    old, new = lines[2].split("Output current ", 1)[1].split(" -> ")
    assert old.endswith(" A") and new.endswith(" A") and float(new[:-2]) > float(old[:-2])  # 12 A -> 15 A rated
    rows = [x.split() for x in lines if x.startswith("    u")]
    assert rows == [["u1", "Output", "current", str(n)]]
    assert not any(x.startswith(("-", "+")) for x in lines)  # no unified diff unless asked


def test_diff_flag_adds_the_unified_diff(changed, capsys):
    assert cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN), "--diff"]) == EXIT_DIFFERENT
    out = capsys.readouterr().out
    head, _, unified = out.partition("\n--- ")
    body = unified.splitlines()[2:]
    assert "frames differ" in head and unified.split("\n")[1].startswith("+++ ")
    assert sum(x.startswith("+") for x in body) == sum(x.startswith("-") for x in body) > 0


def test_json_summary_has_the_same_figures(changed, capsys):
    frames, n, first = _expected(changed)
    assert cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN), "--format", "json"]) == EXIT_DIFFERENT
    d = orjson.loads(capsys.readouterr().out)
    assert d["same"] is False
    assert d["frames"] == {"golden": frames, "capture": frames, "differ": n, "changed": n, "added": 0, "missing": 0}
    assert d["first"]["frame"] == first and d["first"]["unit"] == "1" and d["first"]["function"] == "03"
    assert d["first"]["fields"][0]["field"] == "Output current"
    assert d["by_unit_and_field"] == [{"unit": "u1", "field": "Output current", "frames": n}]


def test_passing_check_says_ok_on_stderr(capsys):
    assert cli.main(["check", str(TDS), "--golden", str(TDS_GOLDEN)]) == EXIT_SAME
    cap = capsys.readouterr()
    frames = sum(1 for x in TDS_GOLDEN.read_text().splitlines() if not x.startswith("#"))
    assert cap.out == "" and cap.err == f"ok: {frames} frames, 0 findings match\n"


def test_junit_validates_and_reads_back(changed, tmp_path, capsys):
    xmlschema = pytest.importorskip("xmlschema")
    junitparser = pytest.importorskip("junitparser")
    schema = xmlschema.XMLSchema(str(XSD))
    failed, passed = tmp_path / "failed.xml", tmp_path / "passed.xml"
    assert cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN), "--junit", str(failed)]) == EXIT_DIFFERENT
    summary = capsys.readouterr().out
    assert cli.main(["check", str(TDS), "--golden", str(TDS_GOLDEN), "--junit", str(passed)]) == EXIT_SAME
    for f in (failed, passed):
        schema.validate(str(f))
    suite = next(iter(junitparser.JUnitXml.fromfile(str(failed))))
    assert (suite.tests, suite.failures) == (1, 1)
    case = next(iter(suite))
    assert case.name == str(changed)
    fail = case.result[0]
    assert isinstance(fail, junitparser.Failure) and "frames differ" in fail.message
    assert fail.text == summary
    ok = next(iter(next(iter(junitparser.JUnitXml.fromfile(str(passed))))))
    assert ok.is_passed


def test_junit_for_an_error_validates(tmp_path, capsys):
    xmlschema = pytest.importorskip("xmlschema")
    x = tmp_path / "err.xml"
    assert cli.main(["check", str(TDS), "--golden", str(tmp_path / "none.txt"), "--junit", str(x)]) == 2
    assert "no such golden file" in capsys.readouterr().err
    xmlschema.XMLSchema(str(XSD)).validate(str(x))
    assert "no such golden file" in x.read_text()


def test_findings_compare_as_sets(tmp_path):
    errors = CAPTURES / "sim" / "errors.mcap"
    golden = CAPTURES / "golden" / "sim-errors.txt"
    lines = golden.read_text().splitlines()
    findings = [x for x in lines if x.startswith("finding ")]
    assert len(findings) >= 2
    frames = [x for x in lines if not x.startswith("finding ")]
    g = tmp_path / "reordered.txt"
    g.write_text("\n".join(frames + findings[::-1]) + "\n")
    rc, text = check(errors, g)
    assert rc == EXIT_SAME and text.endswith(f", {len(findings)} findings match\n")
    g.write_text("\n".join(frames + findings[1:] + ["finding warning eeprom_wear link=- unit=7"]) + "\n")
    rc, text = check(errors, g)
    assert rc == EXIT_DIFFERENT
    assert "0 of" in text and "findings: 1 added (" in text and "1 gone (warning eeprom_wear u7)" in text
