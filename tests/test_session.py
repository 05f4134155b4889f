"""sniffer.capture.session: one precedence rule, one loop, outputs renamed into place, one line for bad input."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import decoded, export

from sniffer.cli import main
from sniffer.events import CaptureInfo
from sniffer.line import SettingsError
from sniffer.formats.outputs import Output, OutputError
from sniffer.capture.session import DEFAULTS, CaptureSpec, LineChoice, Session, layered
from sniffer.sources.files import FileSource

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
A510 = CAPTURES / "sim" / "a510.mcap"
WIZ = CAPTURES / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv"


# ---------------------------------------------------------------- settings: one precedence rule
def test_flags_beat_bus_file_beat_capture_beat_defaults(tmp_path):
    bus = tmp_path / "line.toml"
    bus.write_text('[serial]\nbaud = 9600\nparity = "O"\n[units]\n1 = "tds-v8"\n2 = "spl"\n[timeouts_ms]\n1 = 250\n')
    spec = CaptureSpec.of(baud=19200, devices={2: "a510"}, bus_file=str(bus))
    info = CaptureInfo(baud=115200, parity="E", stopbits=2, devices={1: "generic", 3: "spl"}, protocol="modbus-rtu")
    r = spec.resolve(info)
    assert r.line.baud == 19200  # flag
    assert r.line.parity == "O"  # bus file over the capture's E
    assert r.line.stopbits == 2  # the capture's own, nothing above says it
    assert r.devices == {1: "tds-v8", 2: "a510", 3: "spl"}  # per unit: flag > bus > capture
    assert r.unit_timeouts == {1: 250.0} and r.timeout_ms == DEFAULTS.timeout_ms


def test_layered_is_first_that_says():
    a = LineChoice(parity="E")
    b = LineChoice(baud=9600, parity="O", devices={1: "x"})
    c = LineChoice(baud=1200, devices={1: "y", 2: "z"})
    got = layered(a, b, c)
    assert (got.baud, got.parity, dict(got.devices)) == (9600, "E", {1: "x", 2: "z"})


def test_resolve_refuses_what_cannot_work():
    with pytest.raises(SettingsError, match="does not say its baud rate"):
        CaptureSpec().resolve(CaptureInfo(source="byte-csv:x"))
    with pytest.raises(SettingsError, match="model pd-series speaks pd-rtu, pd-ascii, not modbus-rtu"):
        CaptureSpec.of(baud=9600, devices={2: "pd-series"}).resolve(None)
    with pytest.raises(SettingsError, match="not one of modbus-rtu"):
        CaptureSpec.of(baud=9600, protocol="can-bus").resolve(None)
    with pytest.raises(SettingsError, match="finite"):
        CaptureSpec.of(baud=9600, timeout_ms=float("nan")).resolve(None)
    assert CaptureSpec.of(baud=9600, protocol="pd-rtu", devices={2: "pd-series"}).resolve(None).devices


def test_the_capture_process_gets_the_same_spec(tmp_path):
    """serve and the TUI start their capture as a process of its own: the spec it decodes is the one sent."""
    from sniffer.processes.capture import capture_input

    bus = tmp_path / "b.toml"
    bus.write_text("[serial]\nbaud = 9600\n")
    spec = CaptureSpec.of(baud=19200, parity="E", devices={1: "a510", 7: "spl"}, timeout_ms=250.0,
                          bus_file=str(bus), model_files=("m.toml",), port="/dev/ttyUSB0", out="x.mcap",
                          duration_s=30.0, publish="/tmp/s.sock", publish_backlog=5, headless=True, stream=None)
    assert CaptureSpec.decode(capture_input(spec, "/tmp/s.sock")) == spec
    demo = CaptureSpec(scenario="errors", seed=3, out="d.mcap", duration_s=2.0, stream="jsonl")
    assert CaptureSpec.decode(capture_input(demo, "/tmp/d.sock")) == demo.with_(publish="/tmp/d.sock", headless=True,
                                                                                stream=None)


# ---------------------------------------------------------------- the loop
def test_session_frames_stream_and_settings_travel_with_the_capture():
    session = Session(CaptureSpec.of(devices={1: "generic"}), FileSource(str(A510)))
    first = next(iter(session))
    assert session.info.devices[1] == "generic" and session.info.baud == 19200  # what the decode used
    rest = sum(1 for _ in session)
    assert 1 + rest == session.frames_out == 502 and first.index == 0


def test_decode_capture_is_a_stream_not_a_list():
    from sniffer.capture.session import decode_capture

    session = decode_capture(A510)
    it = iter(session)
    assert next(it).index == 0 and session.frames_out < 502  # frames come while the file is read


# ---------------------------------------------------------------- outputs
def test_output_is_written_as_part_and_renamed(tmp_path):
    target = tmp_path / "x.csv"
    target.write_text("old")
    out = Output(target)
    assert out.part == str(target) + ".part"
    Path(out.part).write_text("new")
    assert target.read_text() == "old"  # untouched until the output is complete
    out.commit()
    assert target.read_text() == "new" and not os.path.exists(out.part)


def test_output_refuses_inputs_folders_and_missing_folders(tmp_path):
    src = tmp_path / "in.mcap"
    src.write_bytes(b"x")
    with pytest.raises(OutputError, match="also an input"):
        Output(src, inputs=[str(src)])
    with pytest.raises(OutputError, match="does not exist"):
        Output(tmp_path / "nope" / "x.csv")
    with pytest.raises(OutputError, match="is a folder"):
        Output(tmp_path)
    (tmp_path / "in.mcap.part").write_text("a killed run's capture")
    assert Output(src).part.endswith("in.mcap.2.part")  # never writes over a part file left behind


def test_export_over_its_input_is_refused_and_the_input_kept(tmp_path, capfd):
    b = tmp_path / "b.mcap"
    b.write_bytes(A510.read_bytes())
    assert export(b, "mcap", b) == 2
    assert b.read_bytes() == A510.read_bytes()
    assert capfd.readouterr().err.count("\n") == 1


def test_export_of_a_missing_input_keeps_the_old_output(tmp_path, capfd):
    keep = tmp_path / "keep.pcap"
    keep.write_text("precious")
    assert export(tmp_path / "nosuch.mcap", "pcap", keep) == 2
    assert keep.read_text() == "precious" and not list(tmp_path.glob("*.part"))
    assert "no such file" in capfd.readouterr().err


def test_export_replaces_the_old_output_only_when_complete(tmp_path):
    out = tmp_path / "a.csv"
    out.write_text("old\n")
    assert export(A510, "csv", out) == 0
    assert out.read_text().startswith('"index","t",') and not list(tmp_path.glob("*.part"))


def _with_file_size_limit(limit: int, *argv: str, cwd) -> subprocess.CompletedProcess:
    code = (f"import resource,sys; resource.setrlimit(resource.RLIMIT_FSIZE,({limit},{limit}));"
            "import signal; signal.signal(signal.SIGXFSZ, signal.SIG_IGN);"
            "from sniffer.cli import main; sys.exit(main(sys.argv[1:]))")
    return subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=120, cwd=cwd)


@pytest.mark.parametrize("fmt", ["csv", "pcap", "mcap", "parquet"])
def test_disk_full_at_start_one_line_exit_2_nothing_left(tmp_path, fmt):
    r = _with_file_size_limit(0, "export", str(A510), "--to", fmt, "--out", "x." + fmt, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr and "x." + fmt in r.stderr
    assert ".part" not in r.stderr and os.listdir(tmp_path) == []


def test_disk_full_during_an_export_keeps_the_old_file(tmp_path):
    (tmp_path / "x.mcap").write_text("the old export")
    r = _with_file_size_limit(30_000, "export", str(A510), "--to", "mcap", "--out", "x.mcap", cwd=tmp_path)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "nothing written" in r.stderr, r.stderr
    assert (tmp_path / "x.mcap").read_text() == "the old export" and os.listdir(tmp_path) == ["x.mcap"]


# ---------------------------------------------------------------- bad input: one line, exit 2
@pytest.mark.parametrize("argv, says", [
    (["replay", str(A510), "--timeout-ms", "nan"], "--timeout-ms 'nan'"),
    (["replay", str(A510), "--timeout-ms", "inf"], "--timeout-ms 'inf'"),
    (["replay", str(A510), "--timeout-ms", "1e308"], "--timeout-ms"),
    (["replay", str(A510), "--baud", "0"], "baud rate 0"),
    (["simulate", "--duration", "nan", "--out", "x.mcap"], "--duration 'nan'"),
    (["demo", "--duration", "-1"], "--duration '-1'"),
    (["live", "/dev/null", "--publish", "tcp:99999"], "99999"),
    (["replay", str(A510), "--tui"], "needs a terminal"),
    (["diff", str(A510), str(A510), "--device", "2=pd-series"], "pd-series"),
    (["decode", "zz"], "not hex"),
    (["replay", str(WIZ)], "baud rate"),
    (["simulate", "--out", "x.txt"], ".mcap or .csv"),
    (["export", str(A510), "--to", "csv", "--out", "/nonexistent-folder/x.csv"], "does not exist"),
])
def test_bad_flags_one_line_exit_2(tmp_path, monkeypatch, capfd, argv, says):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sniffer: error: ") and says in err, err
    assert not list(tmp_path.iterdir())  # nothing created


def test_live_on_a_missing_port_says_so_first_and_writes_nothing(tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)
    assert main(["live", "/dev/nonexistent", "--headless", "--out", "x.mcap"]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "capturing" not in err and "no such port" in err
    assert not list(tmp_path.iterdir())


def test_a_stalled_viewer_leaves_no_traceback(tmp_path, capfd):
    """A viewer that never reads is cut off at the end of the capture: quietly (no CancelledError traceback)."""
    import socket

    from sniffer.frame import Frame
    from sniffer.processes.publish_sink import PublishSink

    sock = str(tmp_path / "s.sock")
    pub = PublishSink(sock, viewer_queue=200, linger_s=0.2)
    pub.start(CaptureInfo(source="test"))
    viewer = socket.socket(socket.AF_UNIX)
    viewer.connect(sock)  # and never reads
    for i in range(100_000):
        pub.frame(Frame(i, i, i + 1, bytes(200), "modbus-rtu", 1, 3))
    pub.close()
    viewer.close()
    err = capfd.readouterr().err
    assert "Traceback" not in err and "CancelledError" not in err


def test_decoded_helper_matches_replay_text(tmp_path):
    info, frames = decoded(A510)
    assert len(frames) == 502 and info.protocol == "modbus-rtu"
