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


# --ignore and --tolerance, kept in the golden's header


def _max_current_step(changed: Path) -> float:
    a, b = list(decode_capture(TDS, None)), list(decode_capture(changed, None))
    return max(abs(_current(fa) - _current(fb)) for fa, fb in zip(a, b) if _current(fa) is not None)


@pytest.mark.parametrize("margin, rc", [(0.05, EXIT_SAME), (-0.05, EXIT_DIFFERENT)])
def test_absolute_tolerance_around_the_largest_change(changed, margin, rc, capsys):
    amount = round(_max_current_step(changed) + margin, 2)
    assert cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN), "--tolerance",
                     f"Output current={amount}A"]) == rc
    if rc == EXIT_DIFFERENT:
        assert "u1    Output current" in capsys.readouterr().out


def test_tolerance_in_another_unit_tolerates_nothing(changed, capsys):
    assert cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN), "--tolerance", "Output current=100V"]) == 1
    frames, n, _ = _expected(changed)
    assert f"{n} of {frames} frames differ" in capsys.readouterr().out


def test_relative_tolerance(changed, capsys):
    """Rated 12 -> 15 A scales the current by 25 %: 30 % tolerates every nonzero value, 10 % none."""
    assert cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN), "--tolerance", "Output current=10%"]) == 1
    _, n, _ = _expected(changed)
    assert f"{n} of" in capsys.readouterr().out
    cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN), "--tolerance", "Output current=30%"])
    out = capsys.readouterr().out
    a, b = list(decode_capture(TDS, None)), list(decode_capture(changed, None))
    from_zero = sum(1 for fa, fb in zip(a, b) if _current(fa) == 0 and _current(fb) not in (0, None))
    assert (f"{from_zero} of" in out) if from_zero else out == ""


@pytest.mark.parametrize("field", ["Output current", "Output cur*"])
def test_ignore_a_field(changed, field, capsys):
    assert cli.main(["check", str(changed), "--golden", str(TDS_GOLDEN), "--ignore", field]) == EXIT_SAME
    assert capsys.readouterr().err.startswith("ok: ")


def test_ignore_does_not_hide_another_field(tmp_path, capsys):
    lines = TDS_GOLDEN.read_text().splitlines()
    k = next(i for i, x in enumerate(lines) if "Output voltage=" in x)
    g = tmp_path / "g.txt"
    g.write_text("\n".join(lines[:k] + [lines[k].replace("Output voltage=", "Output voltage=1", 1)] + lines[k + 1:])
                 + "\n")
    assert cli.main(["check", str(TDS), "--golden", str(g), "--ignore", "Output current"]) == EXIT_DIFFERENT
    assert "Output voltage 1" in capsys.readouterr().out


@pytest.mark.parametrize("jobs", ["1", pytest.param("2", marks=pytest.mark.slow)])  # 2: worker processes
def test_rules_are_kept_in_the_golden_header(changed, tmp_path, jobs, capsys):
    g = tmp_path / "g.txt"
    assert cli.main(["check", str(TDS), "--golden", str(g), "--update-golden", "--jobs", jobs,
                     "--tolerance", "Output current=4A", "--ignore", "Analog*", "--time-tol-ms", "2"]) == 0
    head = g.read_text().splitlines()[:2]
    assert head[1].startswith("# sniffer check options: ")
    assert orjson.loads(head[1].split(": ", 1)[1]) == {
        "time_tol_ms": 2.0, "ignore": ["Analog*"], "tolerance": {"Output current": "4A"}}
    capsys.readouterr()
    assert cli.main(["check", str(changed), "--golden", str(g), "--jobs", jobs]) == EXIT_SAME  # the header's rules
    # the command line's tolerance for the same field wins over the header's
    assert cli.main(["check", str(changed), "--golden", str(g), "--tolerance", "Output current=0.1A"]) == 1
    # rewriting the golden without flags keeps its rules
    assert cli.main(["check", str(TDS), "--golden", str(g), "--update-golden"]) == 0
    assert g.read_text().splitlines()[1] == head[1]


def test_bad_tolerance_is_one_line(capsys):
    assert cli.main(["check", str(TDS), "--golden", str(TDS_GOLDEN), "--tolerance", "Output current"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "FIELD=AMOUNT" in err[0]


@pytest.mark.parametrize("inserted", [1, 20, 300])  # within the first window, the second, the last
def test_a_block_of_inserted_frames_is_one_hunk_whatever_its_size(inserted):
    from sniffer.analysis.check import compare_text

    old = [f"{i / 10:.6f} - | request u1 generic fc03 crc=ok pair=+1 read holding {i}" for i in range(600)]
    added = [f"9.{k:06d} - | request u9 generic fc03 crc=ok pair=- read x" for k in range(inserted)]
    new = old[:100] + added + old[100:]
    d = compare_text("\n".join(old), "\n".join(new)).splitlines()
    assert sum(x.startswith("@@") for x in d) == 1
    assert sum(x.startswith("+") and not x.startswith("+++") for x in d) == inserted
    assert not any(x.startswith("-") and not x.startswith("---") for x in d)
