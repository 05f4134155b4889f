"""Generated logic captures (tests/srgen.py) decoded through sigrok-cli: what the public captures lack.

A driver-enable line (turn-on and turn-off times, late and early), an inverted
line, two wires with their roles, UART parity and framing errors, DE windows
across sigrok's blocks of samples, the live source's streaming mode (sigrok-cli
started as `live` starts it, on a file), and the MCAP keeping what a replay
needs to frame it again exactly.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from sigrok_tools import decode_source, need_sigrok_cli
from srgen import Trace

from helpers import fr
from sniffer.events import Chunk, Tick
from sniffer.line import LineSettings
from sniffer.events import CaptureError
from sniffer.sources.logic_options import LogicSpec
from sniffer.sources.sigrok_cli import SigrokSource, file_source

RATE, BAUD = 1_000_000, 9600
LINE = LineSettings(BAUD, "E", 1)
REQ = bytes.fromhex(fr("0103006b0003"))
RSP = bytes.fromhex(fr("010306022b00000064"))
ECHO = bytes.fromhex(fr("010600010003"))  # FC6: the answer is the request, byte for byte


@pytest.fixture(autouse=True)
def _sigrok():
    need_sigrok_cli()


def two_wire(path, *, lead=50, lag=30, polls=3, member_size=1 << 18):
    """RX: requests; TX: the slave's responses, DE `lead` samples before each and `lag` after it (negative lead: a
    driver enabled late, after the start bit; negative lag: disabled before the last stop bit ended).  Returns
    (path, [(first start, last start, rise, fall) per response])."""
    t = Trace(RATE, ["RX", "TX", "DE"], idle={"DE": 0})
    s, windows = 1000, []
    for _ in range(polls):
        end = t.uart("RX", s, REQ, BAUD, "E")
        r0 = end + 3000
        t.set("DE", r0 - lead, 1)
        e2 = t.uart("TX", r0, RSP, BAUD, "E")
        t.set("DE", e2 + lag, 0)
        last = e2 - round(11 * RATE / BAUD)
        windows.append((r0, last, r0 - lead, e2 + lag))
        s = e2 + 40_000
    return t.write(path, member_size=member_size), windows


def decode(path, logic: LogicSpec, line: LineSettings = LINE):
    return decode_source(file_source(str(path), logic), line)


def sniffer(*args, env=None):
    return subprocess.run([sys.executable, "-m", "sniffer", *map(str, args)], capture_output=True, text=True,
                          timeout=300, env=env)


def test_driver_enable_times_are_on_each_response(tmp_path):
    path, windows = two_wire(tmp_path / "de.sr")
    frames = decode(path, LogicSpec("RX", "TX", "DE", baud=BAUD, parity="E"))
    responses = [f for f in frames if f.role == "response"]
    assert len(responses) == 3 and all(f.crc_ok and f.pair is not None for f in responses)
    for f, (first, last, rise, fall) in zip(responses, windows):
        assert f.t_ns == first * 1000
        assert f.de_on_ns == (rise - first) * 1000 == -50_000  # enabled 50 us before the start bit
        assert f.de_off_ns == fall * 1000 - (last * 1000 + LINE.char_ns)  # after the last stop bit's end
        assert 29_000 < f.de_off_ns < 31_000
    assert all(f.de_on_ns is None and f.de_off_ns is None for f in frames if f.role == "request")


def test_a_late_enable_and_an_early_disable_read_as_such(tmp_path):
    """DE rising 200 us into the first character and falling 40 us before the last stop bit ends (TX is the
    UART's own pin, so the bytes are intact: what the bus got is what diagnose judges)."""
    path, windows = two_wire(tmp_path / "late.sr", lead=-200, lag=-40)
    responses = [f for f in decode(path, LogicSpec("RX", "TX", "DE", baud=BAUD, parity="E")) if f.role == "response"]
    assert [f.raw for f in responses] == [RSP] * 3
    for f in responses:
        assert f.de_on_ns == 200_000
        assert -41_000 < f.de_off_ns < -39_000


def test_windows_split_across_sigroks_sample_blocks_give_the_same_frames(tmp_path):
    """sigrok hands its decoders the file a member at a time: small members put DE edges and bytes of one
    response in different blocks."""
    whole, _ = two_wire(tmp_path / "whole.sr", polls=4)
    split, _ = two_wire(tmp_path / "split.sr", polls=4, member_size=3000)
    logic = LogicSpec("RX", "TX", "DE", baud=BAUD, parity="E")
    a, b = decode(whole, logic), decode(split, logic)
    key = [(f.t_ns, f.raw, f.role, f.de_on_ns, f.de_off_ns) for f in a]
    assert key == [(f.t_ns, f.raw, f.role, f.de_on_ns, f.de_off_ns) for f in b]
    assert all(f.de_on_ns is not None for f in b if f.role == "response")


def test_de_makes_the_slaves_bytes_responses_on_a_half_duplex_line(tmp_path):
    """The capture begins with an FC6 echo: on a bare line it passes for a request; sent under the slave's DE,
    it is the answer to a request before the capture."""
    t = Trace(RATE, ["BUS", "DE"], idle={"DE": 0})
    t.set("DE", 980, 1)
    end = t.uart("BUS", 1000, ECHO, BAUD, "E")
    t.set("DE", end + 20, 0)
    end = t.uart("BUS", end + 20_000, ECHO, BAUD, "E")
    t.set("DE", end + 4000 - 20, 1)
    end = t.uart("BUS", end + 4000, ECHO, BAUD, "E")
    t.set("DE", end + 20, 0)
    path = t.write(tmp_path / "hd.sr")
    bare = decode(path, LogicSpec("BUS", baud=BAUD, parity="E"))
    assert [f.role for f in bare] == ["request", "response", "request"]  # every pair one frame off
    frames = decode(path, LogicSpec("BUS", de="DE", baud=BAUD, parity="E"))
    assert [f.role for f in frames] == ["response", "request", "response"]
    assert [f.channel for f in frames] == ["BUS+DE", "BUS", "BUS+DE"]
    assert frames[2].pair == frames[1].index and frames[0].pair is None


def test_two_wires_give_the_roles_whatever_the_order(tmp_path):
    """An echo on TX first (its request came before the capture), then a request on RX and its echo on TX."""
    t = Trace(RATE, ["RX", "TX"])
    end = t.uart("TX", 1000, ECHO, BAUD, "E")
    end = t.uart("RX", end + 30_000, ECHO, BAUD, "E")
    t.uart("TX", end + 3000, ECHO, BAUD, "E")
    frames = decode(t.write(tmp_path / "tx.sr"), LogicSpec("RX", "TX", baud=BAUD, parity="E"))
    assert [(f.channel, f.role) for f in frames] == [("TX", "response"), ("RX", "request"), ("TX", "response")]


def test_an_inverted_line_decodes_with_invert(tmp_path):
    def capture(invert: bool):
        t = Trace(RATE, ["L"], idle={"L": 0 if invert else 1})
        end = t.uart("L", 1000, REQ, BAUD, "E", invert=invert)
        t.uart("L", end + 3000, RSP, BAUD, "E", invert=invert)
        return t.write(tmp_path / f"inv{invert}.sr")

    plain = decode(capture(False), LogicSpec("L", baud=BAUD, parity="E"))
    inverted = decode(capture(True), LogicSpec("L", invert=True, baud=BAUD, parity="E"))
    assert [(f.t_ns, f.raw, f.role) for f in inverted] == [(f.t_ns, f.raw, f.role) for f in plain]
    assert [f.raw for f in plain] == [REQ, RSP]
    garbled = decode(capture(True), LogicSpec("L", baud=BAUD, parity="E"))
    assert [f.raw for f in garbled] != [REQ, RSP]


def test_parity_and_framing_errors_are_flagged_on_their_bytes(tmp_path):
    t = Trace(RATE, ["L"])
    end = t.uart("L", 1000, REQ[:3], BAUD, "E", bad_parity=(1,))
    t.uart("L", end, REQ[3:], BAUD, "E", bad_stop=(2,), gap_bits=2)  # idle after each: the UART finds its feet
    [f] = decode(t.write(tmp_path / "err.sr"), LogicSpec("L", baud=BAUD, parity="E"))
    assert f.raw == REQ
    spans = {(a.code, a.start) for a in f.annotations if a.code.startswith("uart.")}
    assert spans == {("uart.parity_error", 1), ("uart.framing_error", 5)}


def test_byte_times_are_the_start_edges_when_the_decoder_centres_off_a_sample(tmp_path):
    """1.03 MHz at 20000 baud: 51.5 samples a bit; sigrok's start-bit annotation begins a sample after the edge."""
    rate, baud = 1_030_000, 20_000
    t = Trace(rate, ["L"])
    starts = [1000 + 700 * i for i in range(len(REQ))]
    for s, b in zip(starts, REQ):
        t.uart("L", s, bytes([b]), baud, "N")
    src = file_source(str(t.write(tmp_path / "odd.sr")), LogicSpec("L", baud=baud))
    src.open()
    times = [t for ev in src.events() if type(ev) is Chunk for t in ev.byte_t_ns]
    assert times == [(2 * s * 10**9 + rate) // (2 * rate) for s in starts]


def test_the_live_source_streams_what_the_file_source_reads(tmp_path):
    """`live sigrok:DRIVER` runs the same source with `-d DRIVER --continuous`: here `-i FILE` in its place.  It
    yields the same events (ticks included: sigrok's blocks become silence the framer can close frames on), and
    yields them while sigrok-cli is still decoding."""
    path, _ = two_wire(tmp_path / "live.sr", polls=40, member_size=20_000)
    logic = LogicSpec("RX", "TX", "DE", baud=BAUD, parity="E")
    a = file_source(str(path), logic)
    a.open()
    expected = list(a.events())
    live = SigrokSource(logic, "test-analyzer", ["-i", str(path)], RATE, ["RX", "TX", "DE"], live=True)
    live.open()
    events = live.events()
    first = next(events)
    running = live.proc.poll() is None
    got = [first, *events]
    assert got == expected
    assert running, "the first event came only after sigrok-cli had ended"
    assert sum(type(e) is Tick for e in got) > 5


def test_an_analyzer_that_stops_sending_ends_the_capture_with_a_reason(tmp_path):
    """A continuous acquisition ends only when asked to: if sigrok-cli ends by itself (an analyzer unplugged), the
    capture says so, after every byte it got (here sigrok-cli reads a file "continuously": it ends at its end)."""
    path, _ = two_wire(tmp_path / "gone.sr", polls=2)
    logic = LogicSpec("RX", "TX", "DE", baud=BAUD, parity="E")
    src = SigrokSource(logic, "sigrok:test", ["-i", str(path), "--continuous"], RATE, ["RX", "TX", "DE"], live=True)
    src.open()
    got = []
    with pytest.raises(CaptureError, match="the analyzer stopped sending"):
        for ev in src.events():
            got.append(ev)
    assert sum(len(c.data) for c in got if type(c) is Chunk) == 2 * (len(REQ) + len(RSP))


def test_export_to_mcap_replays_to_the_same_frames(tmp_path):
    path, _ = two_wire(tmp_path / "m.sr")
    flags = ["--rx", "RX", "--tx", "TX", "--de", "DE", "--baud", BAUD, "--parity", "E"]
    direct = sniffer("replay", path, *flags, "--format", "jsonl")
    assert direct.returncode == 0, direct.stderr
    out = tmp_path / "m.mcap"
    exp = sniffer("export", path, *flags, "--to", "mcap", "--out", out)
    assert exp.returncode == 0, exp.stderr
    again = sniffer("replay", out, "--format", "jsonl")
    assert again.returncode == 0, again.stderr
    records = [json.loads(x) for x in direct.stdout.splitlines()]
    assert [json.loads(x) for x in again.stdout.splitlines()] == records
    assert sum("de_on_ns" in r for r in records) == 3
    from sniffer.sources.files import FileSource

    info = FileSource(out).open()
    assert info.extra["samplerate"] == RATE and info.extra["channel_roles"]["TX+DE"] == "response"


def test_bad_input_is_one_line_and_exit_2(tmp_path):
    path, _ = two_wire(tmp_path / "b.sr", polls=1)
    cases = [
        (["replay", path, "--rx", "D7", "--baud", "9600"], "no logic channel 'D7' for --rx (channels: RX, TX, DE)"),
        (["replay", path, "--baud", "9600"], "say which channel carries the line"),
        (["replay", path, "--rx", "RX"], "--baud"),
        (["replay", path, "--tx", "TX", "--baud", "9600"], "--tx needs --rx"),
        (["live", "sigrok:no-such-driver", "--rx", "D0", "--baud", "9600", "--no-out"], "not found"),
        (["live", "sigrok:demo", "--rx", "D42", "--baud", "9600", "--no-out"], "no logic channel 'D42'"),
    ]
    for args, said in cases:
        p = sniffer(*args)
        assert p.returncode == 2, (args, p.stderr)
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and said in lines[0], (args, p.stderr)
    env = {**os.environ, "PATH": os.path.dirname(sys.executable)}  # python, but no sigrok-cli
    p = sniffer("replay", path, "--rx", "RX", "--baud", "9600", env=env)
    assert p.returncode == 2 and "sigrok-cli not found" in p.stderr and len(p.stderr.strip().splitlines()) == 1
