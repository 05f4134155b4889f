"""Which byte broke a CRC (crc.damaged_byte, the framer's modbus.crc.one_byte): the first byte or a CRC byte."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from sniffer.framing.crc import crc_bytes, damaged_byte
from sniffer.events import Chunk
from sniffer.framing.rtu import RtuFramer
from sniffer.line import LineSettings


@given(st.binary(min_size=2, max_size=250), st.sampled_from(("first", "crc_low", "crc_high")), st.integers(1, 255))
def test_one_damaged_byte_at_a_line_fault_position_is_named_or_left_open(data, where, flip):
    frame = bytearray(data + crc_bytes(data))
    at = {"first": 0, "crc_low": len(frame) - 2, "crc_high": len(frame) - 1}[where]
    was = frame[at]
    frame[at] ^= flip
    # the right byte and its value, or nothing where two positions explain the syndrome: never a wrong one
    assert damaged_byte(bytes(frame)) in ((at, was), None)


def test_a_good_frame_has_no_damaged_byte_and_a_cut_address_is_found():
    good = bytes.fromhex("02030400010002")
    assert damaged_byte(good + crc_bytes(good)) is None
    raw = bytes((0x81,)) + (good + crc_bytes(good))[1:]
    assert damaged_byte(raw) == (0, 0x02)


def test_the_framer_keeps_the_damaged_byte_on_the_frame():
    line = LineSettings(19200, "E", 1)
    good = bytes.fromhex("02030400010002")
    raw = bytes((0x81,)) + (good + crc_bytes(good))[1:]
    fr = RtuFramer(line)
    frames = fr.feed(Chunk(0, raw, tuple(i * line.char_ns for i in range(len(raw)))))
    frames += fr.flush()
    (f,) = frames
    (hit,) = [a for a in f.annotations if a.code == "modbus.crc.one_byte"]
    assert (hit.start, hit.end) == (0, 1) and "0x02" in hit.detail
