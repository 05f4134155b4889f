"""The pytest plugin (entry point pytest11 'sniffer'): sniffer_check fixture, marker, --update-golden."""

from __future__ import annotations

from pathlib import Path

pytest_plugins = ["pytester"]

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
A510 = CAPTURES / "sim" / "a510.mcap"
WIZ = CAPTURES / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv"


def _run(pytester, *args):
    # in-process run: keep plugins that own session-wide temp state (textual snapshots) out of it
    return pytester.runpytest("-p", "no:textual-snapshot", *args)


def _tests(pytester):
    pytester.makepyfile(test_user=f'''
import pytest

def test_fixture(sniffer_check):
    sniffer_check(r"{A510}", "golden/a510.txt")

@pytest.mark.sniffer_golden(r"{WIZ}", "golden/wiz.txt", baud=9600, time_tol_ms=0.5)
def test_marker():
    pass
''')


def test_plugin_is_registered_by_entry_point(pytester):
    result = _run(pytester, "--help")
    result.stdout.fnmatch_lines(["*--update-golden*", "*--sniffer-time-tol-ms*"])


def test_missing_golden_fails_then_update_then_pass(pytester):
    _tests(pytester)
    result = _run(pytester)
    result.assert_outcomes(failed=2)
    result.stdout.fnmatch_lines(["*no such golden file*--update-golden*"])

    _run(pytester, "--update-golden").assert_outcomes(passed=2)
    golden = pytester.path / "golden" / "a510.txt"
    assert golden.read_text().startswith("# sniffer golden v2")
    assert (pytester.path / "golden" / "wiz.txt").exists()
    _run(pytester).assert_outcomes(passed=2)

    golden.write_text(golden.read_text().replace("pair=-1 wrote 2501H", "pair=-1 wrote 2501h", 1))
    result = _run(pytester)
    result.assert_outcomes(failed=1, passed=1)
    result.stdout.fnmatch_lines([
        "E * AssertionError: decode of * differs from golden/a510.txt*",
        "E *frames: 1 of 502 frames differ (1 changed, 0 added, 0 missing)",
        "E *first: frame 1 at *, u1 fc10 response: summary wrote 2501h* -> wrote 2501H*",
        "E *u1 * summary * 1",
        "E *pytest --sniffer-diff shows the unified diff",
    ])
    assert "+0." not in result.stdout.str()  # no unified diff unless asked
    result = _run(pytester, "--sniffer-diff")
    result.stdout.fnmatch_lines(["E *frames: 1 of 502 frames differ*", "E *-* wrote 2501h*", "E *+* wrote 2501H*"])


def test_tolerance_option(pytester):
    _tests(pytester)
    _run(pytester, "--update-golden").assert_outcomes(passed=2)
    golden = pytester.path / "golden" / "a510.txt"
    lines = golden.read_text().splitlines()
    head, _, content = lines[3].partition(" | ")
    t, lat = head.split(" ")
    lines[3] = f"{float(t) + 0.003:.6f} {lat} | {content}"  # 3 ms later
    golden.write_text("\n".join(lines) + "\n")
    _run(pytester, "-k", "fixture").assert_outcomes(failed=1, deselected=1)
    _run(pytester, "-k", "fixture", "--sniffer-time-tol-ms", "5").assert_outcomes(passed=1, deselected=1)


def test_marker_without_arguments_fails_clearly(pytester):
    pytester.makepyfile(test_bad='''
import pytest

@pytest.mark.sniffer_golden("only-one-argument")
def test_bad():
    pass
''')
    result = _run(pytester)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*sniffer_golden needs (capture, golden*"])
