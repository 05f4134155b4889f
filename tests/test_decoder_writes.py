"""What the decoders record on a frame: `writes` (its register-shadow writes) and each point's `span`.

Frames go through the real pipeline (framer, pairer, registry); the
expected values are written out from the Modbus / PD-series layouts, not
taken from the decoder.
"""

from __future__ import annotations

import pytest
from helpers import bursts, fr, run_events
from tui_helpers import SIM_CAPTURES, registry_shadow, replay_frames

from sniffer.line import LineSettings
from sniffer.protocols import of_frame

LINE = LineSettings(19200)


def frames_of(*hexes, devices=None, protocol="modbus-rtu"):
    return run_events(bursts(list(hexes), LINE), LINE, devices, protocol=protocol)


def test_a_read_response_writes_its_values_and_nothing_from_a_bad_crc_or_an_exception():
    f = frames_of(fr("0103000a0002"), fr("010304000700ff"),
                  fr("0104000a0001"), "0104020009" + "0000",  # CRC-bad answer
                  fr("0103000a0001"), fr("018302"),  # exception
                  fr("01010003000a"), fr("0101020501"))
    assert [x.role for x in f] == ["request", "response"] * 4
    assert f[0].writes == [] and f[1].writes == [["holding", 10, [7, 255]]]
    assert f[3].crc_ok is False and f[3].points and f[3].writes == []
    assert f[5].exception and f[5].writes == []
    # coils 3..12 from status bytes 05 01 (LSB first): 1 0 1 0 0 0 0 0, 1 0
    assert f[7].writes == [["coil", 3, [1, 0, 1, 0, 0, 0, 0, 0, 1, 0]]]


def test_a_write_is_recorded_on_the_response_that_confirms_it_and_a_broadcast_at_once():
    f = frames_of(fr("011000100002040001fffe"), fr("011000100002"),
                  fr("010600200005"), fr("010600200005"),
                  fr("010f0002000a020d02"), fr("010f0002000a"),
                  fr("001000300001020009"),  # broadcast: nobody answers
                  fr("011000400001020001"), "011000400001" + "0000")  # the confirmation is mangled
    assert f[0].writes == [] and f[1].writes == [["holding", 16, [1, 0xFFFE]]]
    assert f[2].writes == [] and f[3].writes == [["holding", 32, [5]]]
    # coils 2..11 from 0D 02: 1 0 1 1 0 0 0 0, 0 1
    assert f[5].writes == [["coil", 2, [1, 0, 1, 1, 0, 0, 0, 0, 0, 1]]]
    assert f[6].unit == 0 and f[6].writes == [["holding", 48, [9]]]
    assert f[8].crc_ok is False and f[8].writes == []


def test_mask_write_and_read_write_multiple_record_their_results():
    f = frames_of(fr("0103000a0001"), fr("0103021234"),
                  fr("0116000a00f20025"), fr("0116000a00f20025"),
                  fr("0116000b00f20025"), fr("0116000b00f20025"),  # 11 never seen: no result to record
                  fr("01170003000200040002040011002202"), fr("0117040005000600"))
    assert f[3].writes == [["holding", 10, [(0x1234 & 0x00F2) | (0x0025 & ~0x00F2 & 0xFFFF)]]]
    assert f[5].writes == []
    # 0x17 writes first (4..5), then reads (3..4): both on the response, in that order
    assert f[6].writes == [] and f[7].writes == [["holding", 4, [0x11, 0x22]], ["holding", 3, [5, 6]]]


def test_pd_series_parameter_and_status_writes():
    pd = dict(protocol="pd-rtu", devices={1: "pd-series"})
    f = frames_of(fr("010201a5"), fr("010201a5"),  # a write of PD165 without value bytes (LEN=1)
                  fr("010103a50003"), fr("010103a50003"),  # read PD165 (the request's value is a placeholder)
                  fr("01040101"), fr("0104030109c4"),
                  fr("01040101"), "0104030109c4" + "0000", **pd)
    assert [x.protocol for x in f] == ["pd-rtu"] * 8
    assert f[1].writes == []  # LEN=1: a parameter number without a value
    assert f[2].writes == [] and f[3].writes == [["holding", 165, [3]]]
    assert f[5].writes == [["input", 1, [0x09C4]]] and f[5].points[0]["value"] == 25.0
    assert f[7].crc_ok is False and f[7].writes == []


@pytest.mark.parametrize("name", SIM_CAPTURES)
def test_the_frames_writes_replayed_are_the_decoders_shadow(name):
    _, frames, registry = replay_frames(name)
    shadow: dict = {}
    for f in frames:
        assert not f.writes or (f.crc_ok and not f.exception and f.role in ("request", "response"))
        for table, start, values in f.writes:
            shadow.update(((f.unit, table, start + i), v) for i, v in enumerate(values))
    assert shadow == registry_shadow(registry) and shadow


def _value_bytes(f, span) -> bytes:
    """A span's bytes as binary: wire bytes, or the hex characters of an ASCII frame decoded."""
    s, e = span
    if of_frame(f.protocol).text:
        assert s % 2 == 1 and (e - s) % 2 == 0, (f.raw, span)  # ':' then two characters a byte
        return bytes.fromhex(f.raw[s:e].decode())
    return f.raw[s:e]


@pytest.mark.parametrize("name", SIM_CAPTURES)
def test_every_point_span_holds_its_value(name):
    _, frames, _ = replay_frames(name)
    checked = set()
    for f in frames:
        table = of_frame(f.protocol).table_of(f.function) if not f.is_noise else None
        for i, p in enumerate(f.points):
            data = _value_bytes(f, p["span"])
            if table in ("coil", "discrete") and f.function in (0x01, 0x02, 0x0F):
                assert len(data) == 1 and (data[0] >> (i & 7)) & 1 == p["raw"], (f, p)
                checked.add("bit")
            elif f.function == 0x05 and table == "coil":
                assert data in (b"\xff\x00", b"\x00\x00") and (data == b"\xff\x00") == p["raw"], (f, p)
                checked.add("coil")
            else:
                assert int.from_bytes(data, "big") == p["raw"], (f, p, data)
                checked.add(len(data))
    assert checked


def test_spans_of_a_joined_32_bit_point_would_cover_both_words():
    """make_points' contract for a model that joins two registers: the point's span covers 4 bytes."""
    from decoders.base import UnitState
    from decoders.generic import GenericModbus
    from sniffer.frame import Frame

    class Joined(GenericModbus):
        def make_points(self, space, addr, values, state, offset):
            pts = super().make_points(space, addr, values, state, offset)
            hi, lo = pts[0], pts[1]
            return [dict(hi, raw=(hi["raw"] << 16) | lo["raw"], span=[hi["span"][0], lo["span"][1]])] + pts[2:]

    req, rsp = Frame(0, 0, 1, b"", "modbus-rtu", 1, 3, crc_ok=True), Frame(1, 2, 3, b"", "modbus-rtu", 1, 3,
                                                                          crc_ok=True)
    req.adu, req.role = bytes.fromhex("010325100002"), "request"
    rsp.adu, rsp.role = bytes.fromhex("01030400010002"), "response"
    rsp.raw = rsp.adu + b"\0\0"
    Joined().decode(rsp, req, UnitState(1))
    p = rsp.points[0]
    assert p["raw"] == 0x00010002 and int.from_bytes(rsp.raw[slice(*p["span"])], "big") == p["raw"]
    assert rsp.writes == [["holding", 0x2510, [1, 2]]]  # the shadow keeps words, whatever the points join


def test_a_write_multiple_response_for_other_registers_confirms_nothing():
    """Third outside review: a 10H response echoing other addresses (pair.mismatch) still committed the
    request's values to the register shadow."""
    from helpers import bursts, fr, run_events

    from sniffer.line import LineSettings

    line = LineSettings(19200, "E", 1)
    req = fr("0110000100020400050006")
    good, other = fr("011000010002"), fr("011000050002")
    out = run_events(bursts([req, other], line), line)
    assert "pair.mismatch" in [a.code for a in out[1].annotations] and out[1].writes == []
    out = run_events(bursts([req, good], line), line)
    assert out[1].writes == [["holding", 1, [5, 6]]]
