"""Framing and roles at the edges of the address space and of the bytes (issue 10, section 1).

Each case is a frame outside test suites' usual traffic: reserved units, unit 0 answering,
junk on both sides of a frame, diagnostic 08 frames of odd length glued to others, the bytes
that decide a frame's role, and broadcasts named by the bus's model.  Per-read chunks (a USB
adapter's reads, no per-byte times) and per-byte wire times are both used: a rule must not
depend on how the bytes arrived.
"""

from __future__ import annotations

import pytest
from helpers import fr, run_events, run_sniffer

from sniffer.framing.ascii import AsciiFramer
from sniffer.framing.crc import crc_ok, lrc
from sniffer.events import Chunk
from sniffer.frame import CAN_REQ, CAN_RSP, REQUEST, RESPONSE
from sniffer.framing.rtu import RtuFramer
from sniffer.line import LineSettings

LINE = LineSettings(19200, "E", 1)
CHAR = LINE.char_ns
BOTH = CAN_REQ | CAN_RSP


def h(x: str) -> bytes:
    return bytes.fromhex(fr(x))


def one_read(*parts: bytes, t: int = 50_000_000) -> list[Chunk]:
    """All parts in one USB read (no per-byte times)."""
    return [Chunk(t, b"".join(parts))]


def on_wire(*parts: bytes) -> list[Chunk]:
    """All parts back to back with per-byte times (one burst, no silence inside)."""
    data = b"".join(parts)
    return [Chunk(0, data, tuple(i * CHAR for i in range(len(data))))]


def at(t_chars: float, raw: bytes) -> list[Chunk]:
    """`raw` on the wire from t_chars characters on, per-byte times."""
    t = int(t_chars * CHAR)
    return [Chunk(t, raw, tuple(t + i * CHAR for i in range(len(raw))))]


def framed(chunks, cls=RtuFramer):
    f = cls(LINE)
    out = []
    for c in chunks:
        out += f.feed(c)
    return out + f.flush()


def shape(frames):
    return [(f.raw.hex(), f.protocol, f.role_fits, f.crc_ok) for f in frames]


def codes(f):
    return [a.code for a in f.annotations]


CHUNKINGS = (one_read, on_wire)


# ---------------------------------------------------------------- reserved units
@pytest.mark.parametrize("unit", [248, 254, 255])
def test_a_crc_valid_frame_to_a_reserved_unit_is_a_frame_annotated(unit):
    raw = h(f"{unit:02x}03007c0002")
    (f,) = framed(one_read(raw))
    assert shape([f]) == [(raw.hex(), "modbus-rtu", CAN_REQ, True)]
    assert codes(f) == ["modbus.unit.reserved"]
    got = run_sniffer("decode", raw.hex())
    assert got.returncode == 0 and f"u{unit}" in got.stdout and "read holding 124..125 (2)" in got.stdout
    assert "NOISE" not in got.stdout


def test_the_issue_example_to_unit_255_decodes():
    got = run_sniffer("decode", "ff03007c0002100d")
    assert "->REQ u255" in got.stdout and "modbus.unit.reserved" in got.stdout and "NOISE" not in got.stdout


def test_a_reserved_unit_with_a_bad_crc_is_judged_like_any_unit():
    """The structural length ends at the boundary: a damaged frame (as for unit 1); bytes that fit no
    length stay noise, and the noise reason names the reserved unit."""
    bad = bytes.fromhex("ff03007c0002100e")
    (f,) = framed(one_read(bad))
    assert (f.protocol, f.crc_ok, f.unit) == ("modbus-rtu", False, 255)
    # its last byte is the one damage (10 0E for 10 0D): said so, as for any unit
    assert codes(f) == ["modbus.unit.reserved", "modbus.crc.mismatch", "modbus.crc.one_byte"]
    (n,) = framed(one_read(bytes.fromhex("ff03017c00")))  # lengths 6 (response) and 8 (request)
    assert n.protocol == "noise" and n.noise_reason == "no frame: unit 255 is reserved and no valid CRC"


def test_reserved_unit_in_ascii_is_annotated_on_its_characters():
    adu = bytes.fromhex("f803007c0002")
    line = b":" + (adu + bytes([lrc(adu)])).hex().upper().encode() + b"\r\n"
    (f,) = framed([Chunk(0, line)], AsciiFramer)
    assert f.unit == 248 and f.crc_ok and codes(f) == ["modbus.unit.reserved"]
    a = f.annotations[0]
    assert line[a.start : a.end] == b"F8"


# ---------------------------------------------------------------- unit 0
def test_an_exception_from_unit_0_is_a_response():
    """`sniffer decode 0083029131`: 83H can only be a response, whatever the unit."""
    (f,) = framed(one_read(bytes.fromhex("0083029131")))
    assert shape([f]) == [("0083029131", "modbus-rtu", CAN_RSP, True)]
    assert "modbus.length.mismatch" not in codes(f)
    got = run_sniffer("decode", "0083029131")
    assert "<-RSP u0" in got.stdout and "modbus.length.mismatch" not in got.stdout
    assert "ILLEGAL DATA ADDRESS" in got.stdout


def test_an_exception_in_ascii_is_never_a_request():
    adu = bytes.fromhex("008302")
    line = b":" + (adu + bytes([lrc(adu)])).hex().upper().encode() + b"\r\n"
    (f,) = framed([Chunk(0, line)], AsciiFramer)
    assert f.role_fits == CAN_RSP


@pytest.mark.parametrize("chunking", CHUNKINGS)
@pytest.mark.parametrize("unit", [0, 1])
def test_a_read_at_the_start_of_a_burst_splits_alike_for_unit_0_and_1(unit, chunking):
    """A unit-0 read glued to the frames after it used to swallow them (one long bad-CRC frame)."""
    parts = [h(f"{unit:02x}0300000002"), h(f"{unit:02x}0304000a0014"), h("0106000100ff")]
    got = framed(chunking(*parts))
    assert [f.raw for f in got] == parts
    assert all(f.crc_ok for f in got)


def test_a_unit_0_read_is_flagged_as_a_function_a_broadcast_cannot_carry():
    out = run_events(on_wire(h("0003000a0002")), LINE)
    (f,) = out
    assert f.role == REQUEST and "pair.broadcast" in codes(f) and "pair.broadcast.function" in codes(f)


@pytest.mark.parametrize("chunking", CHUNKINGS)
def test_a_bad_crc_unit_0_exception_before_a_good_one_stays_apart(chunking):
    good = h("008302")
    bad = good[:3] + bytes([good[3] ^ 0x55, good[4]])
    got = framed(chunking(bad, good))
    assert shape(got) == [(bad.hex(), "modbus-rtu", CAN_RSP, False), (good.hex(), "modbus-rtu", CAN_RSP, True)]


# ---------------------------------------------------------------- junk on both sides
@pytest.mark.parametrize("chunking", CHUNKINGS)
def test_a_valid_frame_with_junk_on_both_sides_is_found(chunking):
    """`sniffer decode 7b01030000000585c97d`: 7b, a good read request, 7d."""
    data = bytes.fromhex("7b01030000000585c97d")
    got = framed(chunking(data))
    assert shape(got) == [("7b", "noise", 0, None), ("01030000000585c9", "modbus-rtu", CAN_REQ, True),
                          ("7d", "noise", 0, None)]


def test_longer_junk_on_both_sides():
    frame = h("0110000a000204000100ff")
    got = framed(one_read(b"\x00\xff\x42", frame, b"\x13\x37\x00\x11\x22"))
    assert [f.raw for f in got if f.protocol != "noise"] == [frame]
    assert b"".join(f.raw for f in got) == b"\x00\xff\x42" + frame + b"\x13\x37\x00\x11\x22"


def test_the_issue_example_through_the_cli():
    got = run_sniffer("decode", "7b01030000000585c97d")
    assert "read holding 0..4 (5)" in got.stdout and "CRC!" not in got.stdout


# ---------------------------------------------------------------- 08 of odd lengths
@pytest.mark.parametrize("chunking", CHUNKINGS)
@pytest.mark.parametrize("odd", ["01080001", "01080004"], ids=["sub-function-no-data", "listen-only-no-data"])
def test_a_diagnostic_without_data_glued_to_other_frames_is_a_frame(odd, chunking):
    """6-byte 08 frames decode alone; glued to others their CRC still marks them as frames."""
    diag, nxt, after = h(odd), h("010300000002"), h("0103040001000a")
    got = framed(chunking(diag, nxt, after))
    assert [f.raw for f in got] == [diag, nxt, after]
    assert got[0].crc_ok and "modbus.length.mismatch" in codes(got[0])
    assert got[0].annotations[0].detail == "6 bytes do not fit function 0x08"


def test_an_unknown_length_run_between_two_good_frames_is_a_frame():
    first, odd, last = h("010300000001"), h("0103020001ffee"), h("01030002000a")  # 03 with a count that lies
    got = framed(one_read(first, odd, last))
    assert [f.raw for f in got] == [first, odd, last]
    assert got[1].crc_ok and "modbus.length.mismatch" in codes(got[1])


# ---------------------------------------------------------------- role evidence
def test_fc20_request_byte_count_is_seven_per_sub_request():
    req = h("011407060004000100 02".replace(" ", ""))
    (f,) = framed(one_read(req))
    assert f.role_fits == CAN_REQ and f.crc_ok


def test_fc20_response_walks_its_sub_responses():
    rsp = h("0114 0c 05 06 0dfe 0020 05 06 33cd 0040".replace(" ", ""))
    (f,) = framed(one_read(rsp))
    assert f.role_fits == CAN_RSP and f.crc_ok


def test_fc20_neither_shape_is_annotated():
    odd = h("0114 05 07 0001 0002".replace(" ", ""))
    (f,) = framed(one_read(odd))
    assert f.role_fits == BOTH and "modbus.structure.mismatch" in codes(f)


def test_fc21_groups_that_do_not_add_up_are_annotated():
    good = h("0115 0d 06 0004 0007 0003 06af 04be 100d".replace(" ", ""))
    bad = h("0115 0d 06 0004 0007 0009 06af 04be 100d".replace(" ", ""))
    (g,) = framed(one_read(good))
    (b,) = framed(one_read(bad))
    assert "modbus.structure.mismatch" not in codes(g)
    assert "modbus.structure.mismatch" in codes(b)


def test_an_odd_register_byte_count_is_no_response():
    """03 in 8 bytes with byte count 3 fits the length of both roles; a response needs an even count."""
    raw = h("010303000001")
    (f,) = framed(one_read(raw))
    assert f.role_fits == CAN_REQ
    (g,) = framed(on_wire(raw))
    assert g.role_fits == CAN_REQ


def test_a_coil_read_of_quantity_0_is_no_request():
    raw = h("010103000000")  # as a request: 0 coils (invalid); as a response: 3 status bytes
    (f,) = framed(one_read(raw))
    assert f.role_fits == CAN_RSP


def test_coil_bits_set_beyond_the_requested_quantity_are_flagged():
    req, ok, padded = h("010100000003"), h("01010105"), h("0101010d")
    out = run_events(on_wire(req) + at(60, ok), LINE)
    assert out[1].role == RESPONSE and "modbus.bits.padding" not in codes(out[1])
    out = run_events(on_wire(req) + at(60, padded), LINE)
    assert out[1].role == RESPONSE and "modbus.bits.padding" in codes(out[1])
    assert [p["value"] for p in out[1].points] == [1, 0, 1]


def test_a_frame_of_both_shapes_says_so_when_context_does_not_fit():
    """Pending: read of 8 coils (byte count 1 expected).  Next: an 8-byte 01 frame whose byte count
    is 3: as a response its count does not fit, as a request it leaves the read unanswered."""
    req = h("010100000008")
    both = h("010103000010")  # as a request: 16 coils from 0300H; as a response: 3 bytes of status
    out = run_events(on_wire(req) + at(60, both), LINE)
    assert out[1].role == RESPONSE
    assert "pair.role.ambiguous" in codes(out[1])
    note = next(a for a in out[1].annotations if a.code == "pair.role.ambiguous")
    assert "#0" in note.detail and "byte count 3" in note.detail


def test_an_echo_needs_no_ambiguity_note():
    req = h("010600010003")
    out = run_events(on_wire(req) + at(60, req), LINE)
    assert out[1].role == RESPONSE and "pair.role.ambiguous" not in codes(out[1])


# ---------------------------------------------------------------- broadcast by the bus's model
def _broadcasts():
    return [fr("000600070001"), fr("000600000001")]


def test_broadcast_without_a_model_stays_generic():
    got = run_sniffer("decode", *_broadcasts())
    assert "write holding[7]=1" in got.stdout and "model.broadcast.register" not in got.stdout


def test_broadcast_takes_the_model_all_units_share():
    got = run_sniffer("decode", "--device", "1=tds-v8", "--device", "3=tds-v8", *_broadcasts())
    lines = got.stdout.splitlines()
    assert "tds-v8" in lines[0] and "model.broadcast.register" in lines[0] and "holding[7]" not in lines[0]
    assert "Command word" in lines[1] and "model.broadcast.register" not in lines[1]


def test_broadcast_with_units_of_two_models_stays_generic_unless_told():
    args = ["--device", "1=tds-v8", "--device", "2=a510"]
    got = run_sniffer("decode", *args, *_broadcasts())
    assert "write holding[7]=1" in got.stdout
    got = run_sniffer("decode", *args, "--device", "0=tds-v8", *_broadcasts())
    assert "model.broadcast.register" in got.stdout


def test_bus_file_broadcast_key(tmp_path):
    bus = tmp_path / "line.toml"
    bus.write_text('broadcast = "a510"\n[serial]\nbaud = 19200\n[units]\n1 = "a510"\n2 = "tds-v8"\n')
    got = run_sniffer("decode", "--bus", str(bus), fr("000625010bb8"))
    assert got.returncode == 0, got.stderr
    assert "a510" in got.stdout and "Operation signal" in got.stdout
    bus.write_text('broadcast = "a510"\n[units]\n0 = "tds-v8"\n')
    got = run_sniffer("decode", "--bus", str(bus), fr("000625010bb8"))
    assert got.returncode == 2 and "broadcast" in got.stderr and "Traceback" not in got.stderr
    bus.write_text('broadcast = 3\n')
    got = run_sniffer("decode", "--bus", str(bus), fr("000625010bb8"))
    assert got.returncode == 2 and "model id" in got.stderr


# ---------------------------------------------------------------- two lengths, both CRC-valid
RSP9 = bytes.fromhex("01030444ea370a5900")  # a meter's float32 answer; its first 8 bytes pass as a request


def test_the_chance_request_inside_a_response_is_not_split():
    assert crc_ok(RSP9) and crc_ok(RSP9[:8])  # the case: both lengths of this header hold a CRC
    req = h("010300000002")
    for chunks in (on_wire(req) + at(60, RSP9), [Chunk(10 * CHAR, req), Chunk(70 * CHAR, RSP9)],
                   [Chunk(70 * CHAR, req + RSP9)]):
        got = framed(chunks)
        assert [f.raw for f in got] == [req, RSP9], chunks
        out = run_events(chunks, LINE)
        assert [f.role for f in out] == [REQUEST, RESPONSE] and out[1].pair == 0


def test_the_shorter_wins_where_it_ends_at_a_boundary():
    """The 8 bytes end at silence: a request, and the byte after it starts something else."""
    got = framed(on_wire(RSP9[:8]) + at(60, RSP9[8:]))
    assert [(f.raw, f.protocol) for f in got] == [(RSP9[:8], "modbus-rtu"), (RSP9[8:], "noise")]


# ---------------------------------------------------------------- found by an outside review
@pytest.mark.parametrize("chunking", CHUNKINGS)
@pytest.mark.parametrize("fc", [0x41, 0x48, 0x64, 0x6E, 0x5A])
def test_an_unknown_or_user_function_glued_to_other_frames_is_a_frame(fc, chunking):
    odd, req, rsp = h(f"01{fc:02x}aabbcc"), h("010300000002"), h("01030400640065")
    got = framed(chunking(odd, req, rsp))
    assert [f.raw for f in got] == [odd, req, rsp] and all(f.crc_ok for f in got)
    want = "modbus.function.user_defined" if fc != 0x5A else "modbus.function.unknown"
    assert codes(got[0]) == [want]
    got = framed(chunking(req, odd, rsp))
    assert [f.raw for f in got] == [req, odd, rsp]


@pytest.mark.parametrize("chunking", CHUNKINGS)
def test_two_frames_of_an_unknown_function_glued_are_two_frames(chunking):
    odd = h("0141aabbcc")
    got = framed(chunking(odd, odd))
    assert [f.raw for f in got] == [odd, odd] and all(f.crc_ok for f in got)


def test_ascii_frames_of_the_wrong_length_are_annotated():
    def line(hexbody: str) -> bytes:
        adu = bytes.fromhex(hexbody)
        return b":" + (adu + bytes([lrc(adu)])).hex().upper().encode() + b"\r\n"

    for body, code in (("01030000000102", "modbus.length.mismatch"), ("0108000a", "modbus.length.mismatch"),
                       ("01410102", "modbus.function.user_defined"), ("015a0102", "modbus.function.unknown")):
        (f,) = framed([Chunk(0, line(body))], AsciiFramer)
        assert code in codes(f), body
        a = next(x for x in f.annotations if x.code == code)
        assert 0 <= a.start < a.end <= len(f.raw)
    (ok,) = framed([Chunk(0, line("010300000001"))], AsciiFramer)
    assert codes(ok) == []


def test_decode_ascii_hex_of_several_frames_and_junk():
    two = b":010300000001FB\r\n:010300000001FB\r\n"
    got = run_sniffer("decode", "--protocol", "modbus-ascii", two.hex())
    assert got.returncode == 0 and got.stdout.count("read holding 0..0 (1)") == 2 and "CRC!" not in got.stdout
    got = run_sniffer("decode", "--protocol", "modbus-ascii", (b"x" + two[:17]).hex())
    assert "read holding 0..0 (1)" in got.stdout and "NOISE" in got.stdout and "u120" not in got.stdout


def test_a_write_to_another_register_is_a_new_request_not_an_echo():
    w1, w2 = h("010600010005"), h("010600020007")
    out = run_events(on_wire(w1) + at(3000, w2) + at(3060, w2), LINE)
    assert [f.role for f in out] == [REQUEST, REQUEST, RESPONSE]
    assert "pair.no_response" in codes(out[0]) and out[2].pair == 1
    assert "pair.role.ambiguous" in codes(out[1]) and "pair.mismatch" not in codes(out[1])


def test_a_repeated_broadcast_is_no_answer():
    b = h("000600000001")
    out = run_events(on_wire(b) + at(500, b), LINE)
    assert [f.role for f in out] == [REQUEST, REQUEST]
    assert all("pair.broadcast_response" not in codes(f) for f in out)
    answer = h("010600000001")  # a unit answering it is still flagged
    out = run_events(on_wire(b) + at(60, answer), LINE)
    assert "pair.broadcast_response" in codes(out[1])


def test_an_odd_register_byte_count_is_flagged():
    req, rsp = h("010300000002"), h("0103050064006500")
    out = run_events(on_wire(req) + at(60, rsp), LINE)
    assert "modbus.byte_count.odd" in codes(out[1]) and [p["value"] for p in out[1].points] == [100, 101]


def test_a_frame_of_both_shapes_with_nothing_pending_says_so():
    out = run_events(on_wire(h("010103010200")), LINE)
    (f,) = out
    assert f.role == REQUEST and "pair.role.ambiguous" in codes(f)
    assert "nothing pending" in next(a.detail for a in f.annotations if a.code == "pair.role.ambiguous")


@pytest.mark.parametrize("chunking", CHUNKINGS)
def test_several_glued_frames_no_length_rule_cuts_are_each_a_frame(chunking):
    """Third outside review: three fc41 frames, or two 6-byte 08s before a read, merged into one noise."""
    a, b, c = h("0141123456"), h("0141aabbccdd"), h("0141ee")
    got = framed(chunking(a, b, c))
    assert [f.raw for f in got] == [a, b, c] and all(f.crc_ok for f in got)
    d, req = h("01080004"), h("010300000001")
    got = framed(chunking(d, d, req))
    assert [f.raw for f in got] == [d, d, req] and all(f.crc_ok for f in got)
    junk = bytes.fromhex("00ff13")
    got = framed(chunking(junk, a, b, c))  # junk before them stays noise, the frames stay frames
    assert [f.raw for f in got if f.protocol != "noise"] == [a, b, c]
