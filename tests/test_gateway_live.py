"""`sniffer live socket://HOST:PORT` and `rfc2217://HOST:PORT`: a line behind a gateway (tests/gateway.py relays a
simulated line's pty over TCP, as a device server relays its UART).

Checks what arrived (frames with good CRCs, the "net" time source, the Gap of a server restart and frames
after it), and that not one data byte went to the gateway."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time

from gateway import Gateway
from helpers import SimulatedLine

from sniffer.formats.mcap.reader import open_mcap, read_frames
from sniffer.line import LineSettings

LINE = LineSettings(19200, "E", 1)
SNIFFER = [sys.executable, "-m", "sniffer"]


def _capture(url: str, out, seconds: float, during=None) -> subprocess.CompletedProcess:
    p = subprocess.Popen([*SNIFFER, "live", url, "--baud", "19200", "--parity", "E", "--headless", "--format",
                          "jsonl", "--duration", str(seconds), "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if during is not None:
        threading.Thread(target=during, daemon=True).start()
    stdout, stderr = p.communicate(timeout=120)
    return subprocess.CompletedProcess(p.args, p.returncode, stdout, stderr)


def _records(stdout: str) -> list[dict]:
    return [json.loads(x) for x in stdout.splitlines() if x.startswith("{")]


def test_a_socket_line_captures_and_nothing_is_sent(tmp_path):
    with SimulatedLine(tmp_path, "default", "19200 8E1") as line, Gateway(line.path, LINE) as gw:
        r = _capture(gw.url, tmp_path / "gw.mcap", 4)
        assert gw.from_clients == 0  # passive: not one byte to the gateway
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-2000:]
    recs = [x for x in _records(r.stdout) if x.get("type", "frame") == "frame" and "raw" in x]
    assert len(recs) > 20
    assert sum(x["crc_ok"] is True for x in recs) >= 0.9 * len(recs)
    assert {x["time_source"] for x in recs} == {"net"}
    assert any(x.get("latency_ms") is not None for x in recs)  # answers in a read of their own have one
    info, _ = open_mcap(str(tmp_path / "gw.mcap"))
    assert info.time_source == "net" and info.extra["gateway"]["scheme"] == "socket"
    assert read_frames(str(tmp_path / "gw.mcap"))


def test_the_server_goes_away_and_comes_back(tmp_path):
    with SimulatedLine(tmp_path, "default", "19200 8E1") as line, Gateway(line.path, LINE) as gw:
        def restart():
            deadline = time.monotonic() + 60
            while gw.to_clients < 500 and time.monotonic() < deadline:  # the capture is reading
                time.sleep(0.05)
            gw.restart(pause_s=1.5)

        r = _capture(gw.url, tmp_path / "gw.mcap", 8, during=restart)
        assert gw.connections >= 2 and gw.from_clients == 0, r.stderr
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-2000:]
    _, events = open_mcap(str(tmp_path / "gw.mcap"))
    gaps = [e for e in events if type(e).__name__ == "Gap"]
    assert len(gaps) == 1 and "reconnected" in gaps[0].reason, gaps
    frames = read_frames(str(tmp_path / "gw.mcap"))
    after = [f for f in frames if f["t_ns"] > gaps[0].t_end_ns] if frames and "t_ns" in frames[0] else frames
    assert len(after) > 10  # frames came again after the server was back


def test_rfc2217_negotiates_settings_but_sends_no_data(tmp_path):
    with SimulatedLine(tmp_path, "default", "19200 8E1") as line, Gateway(line.path, LINE, rfc2217=True) as gw:
        r = _capture(gw.url, tmp_path / "gw.mcap", 4)
        assert gw.from_clients == 0
        port = gw.port_settings
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert (port.baudrate, port.parity, port.stopbits, port.bytesize) == (19200, "E", 1, 8)
    assert port.rts is False and port.dtr is False  # a gateway switching its transmitter by RTS stays receiving
    recs = [x for x in _records(r.stdout) if "raw" in x]
    assert len(recs) > 20 and sum(x["crc_ok"] is True for x in recs) >= 0.9 * len(recs)


def test_no_server_is_one_line(tmp_path):
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there
    r = subprocess.run([*SNIFFER, "live", f"socket://127.0.0.1:{port}", "--headless", "--out",
                        str(tmp_path / "x.mcap")], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "Traceback" not in r.stderr
    assert r.stderr.count("\n") == 1 and f"socket://127.0.0.1:{port}" in r.stderr, r.stderr
    assert not (tmp_path / "x.mcap").exists()


def test_a_gateway_nobody_listens_on_says_what_to_check(tmp_path):
    """One line in words, not an errno: nothing listens at the port (a device server off, or in client mode)."""
    import socket
    import subprocess
    import sys

    with socket.socket() as s:  # a free port, closed again: nothing listens there
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    r = subprocess.run([sys.executable, "-m", "sniffer", "live", f"socket://127.0.0.1:{port}", "--headless",
                        "--no-out", "--duration", "3"], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert "connection refused (nothing listens there" in line and "Errno" not in line
