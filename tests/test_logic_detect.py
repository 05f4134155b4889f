"""`sniffer detect` on logic captures: baud, parity and stop bits from the bit widths, which a UART cannot tell.

The measurement (sniffer/detect/bitwidth.py) is checked on generated edges for
every format; the command end to end on generated .sr files (8E2 against 8E1)
and on the public captures, whose settings SOURCE.md gives.
"""

from __future__ import annotations

import random
import subprocess
import sys

import pytest
from refdata import SIGROK
from sigrok_tools import decode_source, need_sigrok_cli
from srgen import Trace, edges

from helpers import fr
from sniffer.detect.bitwidth import measure
from sniffer.line import LineSettings
from sniffer.sources.logic_options import LogicSpec
from sniffer.sources.sigrok_cli import file_source

RATE = 1_000_000


def modbus_trace(fmt: str, baud: int = 19200, inverted: bool = False, polls: int = 6, seed: int = 1) -> Trace:
    """Requests and responses of random registers on one line, back-to-back characters (7 data bits: each
    byte's low 7 bits)."""
    rnd = random.Random(seed)
    databits, parity, stop = int(fmt[0]), fmt[1], int(fmt[2])
    t = Trace(RATE, ["L"], idle={"L": 0 if inverted else 1})
    s = 1000
    for _ in range(polls):
        s = t.uart("L", s, bytes.fromhex(fr(f"0103{rnd.randrange(65536):04x}0002")), baud, parity, stop,
                   invert=inverted, databits=databits) + 4000
        s = t.uart("L", s, bytes.fromhex(fr(f"010304{rnd.randrange(2**32):08x}")), baud, parity, stop,
                   invert=inverted, databits=databits) + 30_000
    return t


@pytest.mark.parametrize("fmt", ["8N1", "8E1", "8O1", "8N2", "8E2", "8O2", "7E1", "7O1"])
@pytest.mark.parametrize("inverted", [False, True])
def test_the_format_is_measured_from_the_edges(fmt, inverted):
    baud = 19200 if fmt != "8O2" else 38400
    m = measure("L", edges(modbus_trace(fmt, baud, inverted), "L"), RATE)
    assert (m.baud, m.fmt, m.inverted) == (baud, fmt, inverted)
    assert m.settled and m.framing_errors == 0
    assert abs(m.measured_baud - baud) / baud < 0.01


def test_a_channel_without_uart_traffic_is_not_measured():
    t = Trace(RATE, ["L"])
    for k in range(10):
        t.set("L", 1000 + 5000 * k, k % 2)
    assert measure("L", edges(t, "L"), RATE) is None


def test_parity_is_not_guessed_when_bit_9_could_be_either():
    """Every character's data has an odd number of ones and bit 9 is always high: even parity, or a stop bit."""
    t = Trace(RATE, ["L"])
    s = 1000
    for _ in range(30):
        s = t.uart("L", s, bytes([0x01, 0x07, 0x0B]), 19200, "E", 1) + 3000
    m = measure("L", edges(t, "L"), RATE)
    assert m.parity is None and not m.settled


def test_a_uart_takes_8e2_for_8e1_the_samples_do_not(tmp_path):
    """sigrok's UART decoder reads an 8E2 line set to 8E1 without a single error; detect says 8E2."""
    need_sigrok_cli()
    path = modbus_trace("8E2").write(tmp_path / "8e2.sr")
    frames = decode_source(file_source(str(path), LogicSpec("L", baud=19200, parity="E", stopbits=1)),
                           LineSettings(19200, "E", 1))
    assert frames and all(f.crc_ok and not f.annotations for f in frames if f.role == "request")
    p = subprocess.run([sys.executable, "-m", "sniffer", "detect", path, "--write-bus", tmp_path / "bus.toml"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "line: 19200 8E2 on L" in p.stdout
    assert "--rx L --baud 19200 --parity E --stopbits 2" in p.stdout
    bus = (tmp_path / "bus.toml").read_text()
    assert 'parity = "E"' in bus and "stopbits = 2" in bus
    replay = subprocess.run([sys.executable, "-m", "sniffer", "replay", path, "--rx", "L", "--bus",
                             tmp_path / "bus.toml"], capture_output=True, text=True, timeout=300)
    assert replay.returncode == 0 and len(replay.stdout.splitlines()) == 12


@pytest.mark.parametrize("name, said", [
    ("brainchild-io-16do", "line: 19200 8E1, idle low (inverted) on 1 (requests) and 0 (responses)"),
    ("flowmeter_graph_tool", "line: 9600 8N2 on RXTX"),
])
def test_the_public_captures_are_measured_as_their_notes_say(name, said):
    """SOURCE.md: brainchild 8E1 on the RS-232 side (inverted), 11 bits a character; flowmeter 11 bits a
    character without parity (8N2, or 8N1 and an idle bit: the same on the wire)."""
    need_sigrok_cli()
    p = subprocess.run([sys.executable, "-m", "sniffer", "detect", SIGROK / f"{name}.sr"], capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert said in p.stdout


def test_no_uart_on_the_channel_exits_1(tmp_path):
    need_sigrok_cli()
    t = Trace(RATE, ["L", "M"])
    t.set("M", 5000, 0)
    t.set("M", 90_000, 1)
    p = subprocess.run([sys.executable, "-m", "sniffer", "detect", t.write(tmp_path / "quiet.sr")],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 1 and "no channel carries a UART line" in p.stderr


def test_a_modbus_ascii_line_is_7e1_and_its_bus_file_says_so(tmp_path):
    """7 data bits and parity: no flag says 7 data bits, so the bus file carries them (and the protocol)."""
    need_sigrok_cli()
    t = Trace(RATE, ["L"])
    s = 1000
    for _ in range(5):
        s = t.uart("L", s, b":010300000001FB\r\n", 9600, "E", 1, databits=7) + 5000
        s = t.uart("L", s, b":0103020000FA\r\n", 9600, "E", 1, databits=7) + 50_000
    path = t.write(tmp_path / "ascii.sr")
    bus = tmp_path / "ascii.toml"
    p = subprocess.run([sys.executable, "-m", "sniffer", "detect", path, "--write-bus", bus], capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "line: 9600 7E1 on L" in p.stdout and "10 of 10 frames with a good CRC/LRC" in p.stdout
    text = bus.read_text()
    assert "databits = 7" in text and 'protocol = "modbus-ascii"' in text
    replay = subprocess.run([sys.executable, "-m", "sniffer", "replay", path, "--rx", "L", "--bus", bus,
                             "--format", "jsonl"], capture_output=True, text=True, timeout=300)
    assert replay.returncode == 0 and replay.stdout.count('"crc_ok":true') == 10
