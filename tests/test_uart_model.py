"""The bit-level UART model (sniffer/simulator/uart.py) against bit patterns worked out by hand.

Times in the comments are in bits of the line; the receiver samples each bit in its middle.
"""

from __future__ import annotations

import random

import pytest

from sniffer.line import LineSettings
from sniffer.simulator.uart import Receiver, Wire, char_bits

L8N1, L8E1, L8O1, L8N2 = (LineSettings(9600, p, s) for p, s in (("N", 1), ("E", 1), ("O", 1), ("N", 2)))


def send(line: LineSettings, data: bytes, gap_bits: float = 0.0, t0: int = 1_000_000) -> Wire:
    """`data` at `line`, back to back (or `gap_bits` of idle after each character)."""
    wire = Wire(line)
    step = (line.bits_per_char + gap_bits) * 1e9 / line.baud
    wire.send(data, [t0 + round(i * step) for i in range(len(data))])
    return wire


def rx(wire: Wire, line: LineSettings, resync: str = "edge") -> list[tuple[int, str]]:
    chars = Receiver(line, resync=resync).receive(wire, wire.end_ns + 10**9)
    return [(c.value, c.error) for c in chars]


def test_char_bits_start_data_lsb_first_parity_stop():
    # 0x55 = 01010101: LSB first 1,0,1,0,1,0,1,0; four ones: even parity bit 0, odd 1
    assert char_bits(0x55, L8N1) == [0, 1, 0, 1, 0, 1, 0, 1, 0, 1]
    assert char_bits(0x55, L8E1) == [0, 1, 0, 1, 0, 1, 0, 1, 0, 0, 1]
    assert char_bits(0x55, L8O1) == [0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 1]
    assert char_bits(0x55, L8N2) == [0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 1]
    # 'A' = 0x41 = 1000001 in 7 bits: two ones, even parity 0
    assert char_bits(0x41, LineSettings(9600, "E", 1, 7)) == [0, 1, 0, 0, 0, 0, 0, 1, 0, 1]


@pytest.mark.parametrize("line", [L8N1, L8E1, L8O1, L8N2, LineSettings(115200, "E", 1, 7)], ids=lambda x: x.label())
def test_same_settings_receive_every_byte_unchanged(line):
    data = bytes(range(256)) if line.databits == 8 else bytes(range(128))
    assert rx(send(line, data), line) == [(b, "") for b in data]


def test_8n1_receiver_on_8e1_line_framing_error_where_the_parity_bit_is_0():
    # 0x03: two ones, even parity bit 0 at bit 9, where an 8N1 receiver wants its stop bit
    # 0x01: one one, parity bit 1: the 8N1 receiver sees a good stop bit
    assert rx(send(L8E1, b"\x03\x01\x03"), L8N1) == [(0x03, "framing"), (0x01, ""), (0x03, "framing")]


def test_8e1_receiver_on_8n1_line_parity_error_where_the_stop_bit_is_not_the_parity():
    # alone on the line (idle after): bit 9 is the stop bit (1), bit 10 idle (1).
    # 0x03 wants even parity 0 and gets 1: parity error; 0x01 wants 1 and gets 1
    assert rx(send(L8N1, b"\x03\x01", gap_bits=5), L8E1) == [(0x03, "parity"), (0x01, "")]


def test_opposite_parity_every_byte_a_parity_error():
    data = bytes(range(0, 256, 7))
    assert rx(send(L8E1, data), L8O1) == [(b, "parity") for b in data]


def test_a_uart_checks_the_first_stop_bit_only():
    data = bytes(random.Random(1).randrange(256) for _ in range(64))
    assert rx(send(L8N1, data), L8N2) == [(b, "") for b in data]  # back to back 8N1 read at 8N2
    assert rx(send(L8N2, data), L8N1) == [(b, "") for b in data]


def test_wrong_baud_resamples():
    # 0xFF at 9600 read at 19200: only the start bit is low (0..1 line bit = 0..2 receiver bits), so the
    # receiver's first data sample (1.5 of its bits) is still low: 11111110
    assert rx(send(L8N1, b"\xff", gap_bits=20), LineSettings(19200, "N", 1)) == [(0xFE, "")]
    # 0x00 at 19200 is low for 9 of its bits = 4.5 bits at 4800: start and data bit 0 low, the rest high
    assert rx(send(LineSettings(19200, "N", 1), b"\x00", gap_bits=40), LineSettings(4800, "N", 1)) == [(0xFE, "")]


def test_low_for_a_whole_character_is_a_break():
    # 0x00 at 9600 is low for 9 bits = 18 bits at 19200: start, data and stop sample all low
    assert rx(send(L8N1, b"\x00", gap_bits=20), LineSettings(19200, "N", 1)) == [(0x00, "break")]
    wire = Wire(L8N1)
    wire.hold_low(1_000_000, 1_000_000 + 50 * 104_167)  # 50 bits of break: one break, then nothing
    assert rx(wire, L8N1) == [(0x00, "break")]


def test_a_glitch_shorter_than_half_a_bit_is_no_start_bit():
    wire = Wire(L8N1)
    wire.hold_low(1_000_000, 1_000_000 + 40_000)  # 40 us low: under half a bit (52 us) at 9600
    assert rx(wire, L8N1) == []


def test_after_a_framing_error_edge_and_16550_resync_differ():
    # 8E1 0x03 0x01 back to back read at 8N1: 0x03's parity bit 0 is a framing error at bit 9.5.
    # edge: the receiver waits for the line to rise (bit 10, the stop bit) and fall (bit 11): 0x01 is read right.
    # 16550: the low bit 9 is taken for a start bit: data = bits 10..17 = 1 (stop), 0 (start of 0x01), 1, 0, 0, 0, 0, 0
    # = 0x05, its stop sample bit 18 (0x01's bit 6 = 0) a framing error again; then start = bit 18, data bits 19..26 =
    # 0 (bit 7), 1 (parity of 0x01), 1 (stop), then idle = 0xFE, stop sample idle.
    wire = send(L8E1, b"\x03\x01")
    assert rx(wire, L8N1, "edge") == [(0x03, "framing"), (0x01, "")]
    assert rx(wire, L8N1, "16550") == [(0x03, "framing"), (0x05, "framing"), (0xFE, "")]


def test_receive_waits_for_the_stop_sample_and_keeps_its_place():
    wire = send(L8N1, b"\x10\x20")
    r = Receiver(L8N1)
    char = round(10 * 1e9 / 9600)
    first = r.receive(wire, 1_000_000 + char)  # the first stop sample is at 9.5 bits: in
    assert [c.value for c in first] == [0x10]
    assert [c.value for c in r.receive(wire, wire.end_ns + char)] == [0x20]
    assert first[0].t_ns == 1_000_000 and first[0].t_end_ns == 1_000_000 + round(9.5 * 1e9 / 9600)
