"""Where a word helps, the tool says it: a live line with no traffic, a trigger that never fired, a report
without --out (written beside its capture and named on stderr)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from sniffer.analysis.quietline import QUIET_S, QuietLine
from sniffer.cli import main
from sniffer.events import CaptureInfo, Chunk, Tick

ROOT = Path(__file__).resolve().parent.parent
S = 1_000_000_000


def _info(port="/dev/ttyUSB0", links=()):
    info = CaptureInfo(source="serial", port=port)
    info.links = list(links)
    return info


def _run(sink, events):
    said = []
    sink.say = said.append
    for ev in events:
        sink.raw(ev)
        sink.advance(ev.t_ns)
    return said


def test_a_line_silent_from_the_start_is_said_once_with_what_to_check():
    sink = QuietLine(print)
    sink.start(_info())
    said = _run(sink, [Tick(t * S // 100) for t in range(0, 30 * 100)])  # 30 s of idle ticks, 10 ms apart
    assert len(said) == 1
    assert said[0].startswith("warning: no traffic on /dev/ttyUSB0: nothing received in 5 s")
    assert "A and B" in said[0] and "sniffer detect /dev/ttyUSB0" in said[0]


def test_bytes_before_the_quiet_time_say_nothing_and_bytes_after_it_are_noted():
    early = QuietLine(print)
    early.start(_info())
    events = [Tick(t * S // 10) for t in range(0, 40)] + [Chunk(4 * S, b"\x01\x03")]
    events += [Tick(t * S // 10) for t in range(41, 200)]
    assert _run(early, events) == []
    late = QuietLine(print)
    late.start(_info())
    events = [Tick(t * S // 10) for t in range(0, 80)] + [Chunk(8 * S, b"\x01\x03")]
    said = _run(late, events)
    assert len(said) == 2 and said[0].startswith("warning: no traffic")
    assert said[1] == "note: /dev/ttyUSB0: traffic at last, 8 s after the start"


def test_only_the_silent_link_of_several_is_named():
    sink = QuietLine(print)
    sink.start(_info(links=[{"name": "pump", "ports": ["/dev/ttyUSB0"]}, {"name": "fan", "ports": ["/dev/ttyUSB1"]}]))
    events = []
    for t in range(0, 100):
        events.append(Tick(t * S // 10, "fan"))
        if t % 5 == 0:
            events.append(Chunk(t * S // 10, b"\x01\x03\x00", link="pump"))
    said = _run(sink, events)
    assert said == [said[0]] and "no traffic on /dev/ttyUSB1 (fan)" in said[0]
    assert QUIET_S == 5.0


def test_a_trigger_that_never_fired_says_0_windows(tmp_path, capsys):
    capture = tmp_path / "tds-v8.mcap"
    shutil.copy(ROOT / "captures" / "sim" / "tds-v8.mcap", capture)
    rc = main(["replay", str(capture), "--quiet", "--trigger", "unit == 77", "--windows", str(tmp_path / "w")])
    err = capsys.readouterr().err
    assert rc == 0
    assert "triggers: 0 fired, 0 windows (no frame matched 'unit == 77')" in err
    assert not list((tmp_path / "w").glob("*.mcap"))


def test_report_without_out_writes_beside_its_capture(tmp_path, capsys):
    capture = tmp_path / "cab3.mcap"
    shutil.copy(ROOT / "captures" / "sim" / "tds-v8.mcap", capture)
    assert main(["report", str(capture), "--jobs", "1"]) == 0
    page = tmp_path / "cab3.html"
    assert page.is_file() and "<html" in page.read_text()[:200].lower()
    assert f"wrote {page}" in capsys.readouterr().err


def test_live_on_a_port_with_no_traffic_says_so(tmp_path):
    """A real pty that carries nothing: the capture says so while it runs, and ends normally."""
    master, slave = os.openpty()
    port = os.ttyname(slave)
    try:
        p = subprocess.run([sys.executable, "-m", "sniffer", "live", port, "--no-out", "--headless",
                            "--duration", f"{QUIET_S + 3:g}"], capture_output=True, text=True, timeout=120,
                           cwd=tmp_path)
    finally:
        os.close(master)
        os.close(slave)
    assert p.returncode == 0, p.stderr
    line = next(x for x in p.stderr.splitlines() if "no traffic on" in x)
    assert line.startswith(f"sniffer: warning: no traffic on {port}:") and f"sniffer detect {port}" in line
    assert "Traceback" not in p.stderr


def test_a_trigger_on_a_mistyped_field_says_what_it_reads_as_it_starts(tmp_path, capsys):
    capture = tmp_path / "tds-v8.mcap"
    shutil.copy(ROOT / "captures" / "sim" / "tds-v8.mcap", capture)
    assert main(["replay", str(capture), "--quiet", "--trigger", "unti == 1", "--windows", str(tmp_path / "w")]) == 0
    err = capsys.readouterr().err.splitlines()
    note = next(i for i, x in enumerate(err) if "'unti' is read as a point's name; did you mean the field 'unit'?" in x)
    assert note < next(i for i, x in enumerate(err) if "0 windows" in x)  # before the capture's end
    assert main(["replay", str(capture), "--quiet", "--trigger", "unit == 77", "--windows", str(tmp_path / "w")]) == 0
    assert "did you mean" not in capsys.readouterr().err  # a field spelt right: no note


def test_check_rules_that_match_no_field_are_said_with_the_closest_name(tmp_path, capsys):
    from sniffer.analysis.goldenfields import FieldRules, matches

    assert matches("holding[8451]", "holding[8451]") and matches("Analog input 1", "Analog input*")
    assert not matches("holding[8451]", "holding[8452]")  # brackets are literal, not a glob's set
    assert FieldRules(("Outptu current", "crc", "Output*")).unmatched({"Output current", "Output frequency"}) == [
        "Outptu current"]
    capture = tmp_path / "tds-v8.mcap"
    shutil.copy(ROOT / "captures" / "sim" / "tds-v8.mcap", capture)
    golden = tmp_path / "g.txt"
    shutil.copy(ROOT / "captures" / "golden" / "sim-tds-v8.txt", golden)
    assert main(["check", str(capture), "--golden", str(golden), "--ignore", "Outptu current", "--jobs", "1"]) == 0
    err = capsys.readouterr().err
    assert "'Outptu current' matched no field of the capture; did you mean 'Output current'?" in err


def test_a_flag_the_tool_has_elsewhere_says_where(capsys):
    """`replay --filter` is no typo of --invert: the tool filters in the TUI and query, and triggers on a filter."""
    capture = str(ROOT / "captures" / "sim" / "tds-v8.mcap")
    assert main(["replay", capture, "--filter", "u == 1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "frames are filtered in the TUI" in err[0] and "--invert" not in err[0]
    assert main(["replay", capture, "--inverr"]) == 2
    assert "did you mean '--invert'?" in capsys.readouterr().err
