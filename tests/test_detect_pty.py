"""`sniffer detect` as a user runs it, in a subprocess, on a pseudo-terminal line (simulator/uartpty.py) that
delivers what a UART at the settings detect sets receives; the line counts what came back (nothing, ever).

Asserts what was found, not how long it took (benchmarks/bench_detect.py measures that)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest
from helpers import SimulatedLine, run_sniffer

from sniffer.capture.busfile import load_bus_file
from sniffer.events import Chunk
from sniffer.frame import CAN_RSP
from sniffer.framing.rtu import RtuFramer
from sniffer.line import LineSettings


def detect(tmp_path, path, *flags):
    bus = tmp_path / "line.toml"
    r = run_sniffer("detect", path, "--write-bus", str(bus), "--units-time", "0.5", *flags)
    return r, bus


@pytest.mark.parametrize("scenario, line, want, how", [
    ("default", None, "19200 8E1 modbus-rtu", "certain:"),
    ("default", "9600 8O1", "9600 8O1 modbus-rtu", "certain:"),
    ("tds-v8", None, "9600 8N2 modbus-rtu", "certain:"),  # 8N2: the characters' spacing tells it from 8N1
    ("default", "38400 8N1", "38400 8N1 modbus-rtu", "certain:"),  # 8N1: 8N2 would be too slow for it
    ("fast", None, "115200 8N1 modbus-rtu", ""),  # frames too short to time: 1 or 2 stop bits left open
    ("a510-ascii", None, "9600 7E1 modbus-ascii", "certain:"),
    ("pd-series", None, "9600 8N1 pd-rtu", "certain:"),
])
def test_detect_finds_the_line_and_sends_nothing(tmp_path, scenario, line, want, how):
    with SimulatedLine(tmp_path, scenario, line) as sim:
        r, bus = detect(tmp_path, sim.path)
        back = sim.pty.bytes_received_from_sniffer
    assert r.returncode == 0, r.stderr
    assert back == 0  # not one byte reached the line
    out = r.stdout
    table = out.split("\n\n")[0].splitlines()
    if how and want.split()[1].endswith("1") and "stop bits not told apart" in out:
        # a loaded machine's pty delivers reads late: the characters' spacing unmeasured or blurred (11.6 bits
        # a character is neither 8O1's 11 nor 8O2's 12), and 1 and 2 stop bits receive alike, so detect is
        # certain of neither; the same settings, 1 stop bit (test_detect_search holds the certain verdicts)
        how = ""
    assert f"line: {want} ({how}" in out
    if how:
        assert table[1].split()[:3] == want.split()  # ranked first
    else:
        assert "stop bits not told apart" in out
    assert "units seen:" in out
    b = load_bus_file(str(bus))
    baud, fmt, protocol = want.split()
    assert (b.baud, b.parity, b.stopbits, b.databits or 8, b.protocol) == (int(baud), fmt[1], int(fmt[2]), int(fmt[0]),
                                                                          protocol)
    assert f"wrote {bus}" in r.stderr


def test_silent_line_is_no_traffic_in_one_line(tmp_path):
    master, slave = os.openpty()  # a pty nobody writes to
    try:
        r, bus = detect(tmp_path, os.ttyname(slave), "--quiet-time", "1", "-q")
    finally:
        os.close(master)
        os.close(slave)
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("sniffer: error: no traffic on ")
    assert not bus.exists()


def test_no_candidate_fits_says_so_and_writes_nothing(tmp_path):
    with SimulatedLine(tmp_path, "default", "250000 8E1") as sim:  # a rate detect is not told to try
        r, bus = detect(tmp_path, sim.path, "--max-time", "8", "-q")
        back = sim.pty.bytes_received_from_sniffer
    assert r.returncode == 1 and back == 0
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("sniffer: error:")]
    assert len(errors) == 1 and "no candidate fits" in errors[0]
    assert not bus.exists()


@pytest.mark.parametrize("args, message", [
    (["/nonexistent/ttyUSB9"], "no such port"),
    (["PORT", "--bauds", "fast"], "--bauds: 'fast' is not a whole number"),
    (["PORT", "--write-bus", "/nonexistent/x.toml"], "does not exist"),
    (["PORT", "--max-time", "0"], "--max-time"),
    ([], "the following arguments are required: port"),
])
def test_bad_flags_are_one_line(tmp_path, args, message):
    master, slave = os.openpty()
    try:
        r = run_sniffer("detect", *[os.ttyname(slave) if a == "PORT" else a for a in args])
    finally:
        os.close(master)
        os.close(slave)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and message in r.stderr and "Traceback" not in r.stderr


def test_simulate_pty_serves_detect_and_live_until_stopped(tmp_path):
    link = tmp_path / "line0"
    sim = subprocess.Popen([sys.executable, "-m", "sniffer", "simulate", "--pty", str(link), "--scenario", "tds-v8"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        r, bus = detect(tmp_path, str(link), "-q")
        assert r.returncode == 0, r.stderr
        assert "line: 9600 8N2 modbus-rtu" in r.stdout
        live = run_sniffer("live", str(link), "--bus", str(bus), "--no-out", "--headless", "--duration", "2",
                           "--format", "jsonl")
        assert live.returncode == 0, live.stderr
        recs = [json.loads(x) for x in live.stdout.splitlines()]
        # what arrived, not when: every byte, in order. The bytes framed again without their times are
        # CRC-valid frames, but for those caught in part when the capture started and when it stopped.
        # (The live framing itself depends on when bytes came: a simulated line or a reader stalled
        # past t3.5 + the 50 ms read slack by a loaded machine cuts a frame, as a real line would.)
        stream = bytes.fromhex("".join(r["raw"] for r in recs))
        again = RtuFramer(LineSettings(9600, "N", 2)).feed(Chunk(0, stream))
        # (the last frame, cut by the stop, stays pending: it is never flushed)
        first = next(i for i, f in enumerate(again) if f.crc_ok)
        assert first <= 2  # the frame the start cut in two: noise, or a damaged frame and noise
        inner = again[first:]
        assert len(inner) >= 8 and all(f.crc_ok and not f.is_noise for f in inner), [f.raw.hex() for f in inner]
        assert sum(f.role_fits == CAN_RSP for f in inner) >= 3
        mid = [r for r in recs if 0.5 < r["t"] < 1.5]  # and live, the frames decode (see test_links_cli)
        assert sum(r["role"] == "response" and r["crc_ok"] for r in mid) >= 2
    finally:
        sim.send_signal(signal.SIGTERM)
        _, err = sim.communicate(timeout=30)
    assert sim.returncode == 0, err
    assert "0 bytes came from the other end" in err
    assert not os.path.lexists(link)  # the link went with the line


def test_help_says_what_it_tries_and_the_exit_status():
    r = run_sniffer("detect", "--help")
    assert r.returncode == 0
    for words in ("read-only", "921600", "8N2", "7E1", "PD-series", "exit status", "--write-bus", "--bauds",
                  "--units-time", "sniffer live /dev/ttyUSB0 --bus line.toml"):
        assert words in r.stdout


class SimulatedPorts:
    """`sniffer simulate --pty` lines, a process each (a line plays its UART bit by bit: several in one process
    would share its interpreter and fall behind), linked in a folder; `said` holds what each said at its end."""

    def __init__(self, folder, lines: list[tuple[str, list[str], str]]):
        self.paths = [str(folder / name) for _, _, name in lines]
        self.procs = [subprocess.Popen([sys.executable, "-m", "sniffer", "simulate", "--pty", path, "--scenario", sc,
                                        *flags], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                      for (sc, flags, _), path in zip(lines, self.paths)]
        self.said: list[str] = []

    def __enter__(self) -> "SimulatedPorts":
        deadline = time.monotonic() + 30
        while not all(os.path.lexists(p) for p in self.paths) and time.monotonic() < deadline:
            time.sleep(0.05)
        return self

    def __exit__(self, *exc) -> None:
        for p in self.procs:
            p.send_signal(signal.SIGTERM)
        self.said = [p.communicate(timeout=30)[1] for p in self.procs]


def test_several_ports_are_settled_at_once_into_one_bus_file_that_live_captures(tmp_path):
    """Three lines at different settings: one bus file, a [[links]] table each (named after the port, the units
    identified named, the others as comments); `live --bus` on it captures every link with good frames; nothing
    reaches any line."""
    lines = [("tds-v8", [], "line0"), ("default", ["--baud", "9600", "--parity", "O"], "line1"),
             ("a510-ascii", [], "line2")]
    want = {"line0": (9600, "N", 2, 8, "modbus-rtu"), "line1": (9600, "O", 1, 8, "modbus-rtu"),
            "line2": (9600, "E", 1, 7, "modbus-ascii")}
    bus = tmp_path / "plant.toml"
    with SimulatedPorts(tmp_path, lines) as sims:
        r = run_sniffer("detect", *sims.paths, "--write-bus", str(bus), "--units-time", "0.5")
        assert r.returncode == 0, r.stderr
        b = load_bus_file(str(bus))
        got = {x.name: (x.baud, x.parity, x.stopbits, x.databits or 8, x.protocol) for x in b.links}
        # the stop bits are told by the characters' spacing, which a loaded machine's simulator (the writer of
        # these ptys) stretches and its reads blur; test_detect_search holds them exactly on a virtual clock
        assert {k: v[:2] + v[3:] for k, v in got.items()} == {k: v[:2] + v[3:] for k, v in want.items()}
        assert all(got[k][2] in (1, 2) for k in got)
        assert [x.ports for x in b.links] == [(p,) for p in sims.paths]
        # the drives identified while listening are named; the generic ones are left as comments
        assert {x.name: x.devices for x in b.links} == {"line0": {1: "tds-v8", 2: "tds-v8"}, "line1": {},
                                                         "line2": {1: "a510", 2: "a510"}}
        text = bus.read_text()
        assert text.count("[[links]]") == 3 and text.count("# units = { 1 = ") == 1
        assert f"wrote {bus}" in r.stderr
        assert all(f"{p} (" in r.stdout for p in sims.paths) and r.stdout.count("  line: ") == 3
        live = run_sniffer("live", "--bus", str(bus), "--no-out", "--headless", "--duration", "3", "--format",
                           "jsonl")
        assert live.returncode == 0, live.stderr
        recs = [json.loads(x) for x in live.stdout.splitlines()]
        for name in want:  # every link captured, its frames good
            assert sum(rec["link"] == name and rec.get("crc_ok") is True for rec in recs) >= 3, name
        assert "probably wrong" not in live.stderr
    assert all("0 bytes came from the other end" in err for err in sims.said), sims.said


def test_several_ports_one_silent_writes_the_settled_and_says_the_other(tmp_path):
    master, slave = os.openpty()  # a pty nobody writes to
    silent = os.ttyname(slave)
    bus = tmp_path / "plant.toml"
    try:
        with SimulatedLine(tmp_path, "default") as sim:
            r = run_sniffer("detect", sim.path, silent, "--write-bus", str(bus), "--quiet-time", "2", "-q")
    finally:
        os.close(master)
        os.close(slave)
    assert r.returncode == 1
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("sniffer: error:")]
    assert len(errors) == 1 and f"no traffic on {silent}" in errors[0]
    b = load_bus_file(str(bus))
    assert [x.name for x in b.links] == ["line0"] and b.links[0].baud == 19200
    assert f"{silent}: not settled, not in this file" in bus.read_text()


@pytest.mark.parametrize("args, message", [
    (["PORT", "/nonexistent/ttyUSB9", "--write-bus", "BUS"], "no such port"),
    (["PORT", "PORT"], "given twice"),
    (["PORT", "SR"], "a logic capture is detected alone"),
])
def test_several_ports_bad_input_is_one_line_and_no_file(tmp_path, args, message):
    master, slave = os.openpty()
    sr = tmp_path / "x.sr"
    import zipfile

    with zipfile.ZipFile(sr, "w") as z:
        z.writestr("metadata", "[device 1]\nsamplerate=1 MHz\ntotal probes=1\nprobe1=rx\n")
        z.writestr("version", "2")
    bus = tmp_path / "plant.toml"
    try:
        r = run_sniffer("detect", *[{"PORT": os.ttyname(slave), "SR": str(sr), "BUS": str(bus)}.get(a, a)
                                    for a in args])
    finally:
        os.close(master)
        os.close(slave)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().count("\n") == 0 and message in r.stderr and "Traceback" not in r.stderr
    assert not bus.exists()

