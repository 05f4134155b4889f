"""The framers rule by rule: one small, hand-built byte-level case per rule of each docstring.

RtuFramer (sniffer/framing/rtu.py) and PdRtuFramer (sniffer/framing/pd.py): rules A,
B1..B5, the boundary classes (HARD / SOFT / none) from per-byte times and
per-read chunks, t1.5 / t3.5 / quiet annotations, UART flags.  The ASCII
framers (sniffer/framing/hexline.py): ':' ... CR LF, no CR LF, bad hex, LRC
mismatch, noise in ASCII words.  Each case asserts exact frame boundaries,
roles (`can`), CRC verdicts and annotation codes.
"""

from __future__ import annotations

from sniffer.framing.ascii import AsciiFramer
from sniffer.framing.crc import crc_bytes, lrc
from sniffer.events import FLAG_FRAMING, Chunk
from sniffer.frame import CAN_REQ, CAN_RSP
from sniffer.framing.rtu import RtuFramer
from sniffer.framing.hexline import MAX_LINE
from sniffer.line import LineSettings
from sniffer.framing.pd import QUIET_NS, PdAsciiFramer, PdRtuFramer

LINE = LineSettings(19200, "E", 1)
CHAR = LINE.char_ns
BOTH = CAN_REQ | CAN_RSP
QUIET = QUIET_NS / CHAR + 10  # characters of silence past the PD quiet time


def crc(hex_body: str) -> bytes:
    """Bytes with their CRC-16 appended (Modbus RTU and PD RTU share it)."""
    b = bytes.fromhex(hex_body)
    return b + crc_bytes(b)


def asc(hex_body: str, lrc_byte: int | None = None) -> bytes:
    """':' + hex pairs + LRC + CR LF."""
    b = bytes.fromhex(hex_body)
    return b":" + (b + bytes([lrc(b) if lrc_byte is None else lrc_byte])).hex().upper().encode() + b"\r\n"


def wire(*items, t0: int = 0) -> list[Chunk]:
    """Per-byte times: each bytes item back to back, a number between them = characters of silence."""
    chunks, t = [], t0
    for it in items:
        if isinstance(it, (int, float)):
            t += int(it * CHAR)
            continue
        times = tuple(t + i * CHAR for i in range(len(it)))
        chunks.append(Chunk(t, it, times))
        t = times[-1] + CHAR
    return chunks


def frames(cls, chunks, flush: bool = True):
    f = cls(LINE)
    out = []
    for c in chunks:
        out += f.feed(c)
    return out + (f.flush() if flush else [])


def codes(f) -> list[str]:
    return [a.code for a in f.annotations]


def shape(fs) -> list[tuple]:
    """(raw, protocol, can, crc_ok) of each frame."""
    return [(f.raw, f.protocol, f.role_fits, f.crc_ok) for f in fs]


REQ = crc("0103000a0001")  # read 1 holding register: 8 bytes, a request only
RSP = crc("01030200ff")  # its response: byte count 2, 7 bytes
BAD = REQ[:-1] + bytes([REQ[-1] ^ 0xFF])  # REQ with its CRC high byte damaged


# ------------------------------------------------------------------ Modbus RTU rules
def test_rule_a_glued_frames_cut_by_structural_length():
    got = frames(RtuFramer, wire(REQ + RSP + REQ))  # back to back: no silence tells where they end
    assert shape(got) == [(REQ, "modbus-rtu", CAN_REQ, True), (RSP, "modbus-rtu", CAN_RSP, True),
                          (REQ, "modbus-rtu", CAN_REQ, True)]
    assert [(f.unit, f.function, f.adu) for f in got] == [(1, 3, REQ[:-2]), (1, 3, RSP[:-2]), (1, 3, REQ[:-2])]


def test_rule_a_frame_followed_by_zeros_not_swallowed():
    got = frames(RtuFramer, wire(REQ + b"\0\0\0"))  # the CRC register stays 0 through 00 bytes
    assert [f.raw for f in got] == [REQ, b"\0\0\0"] and got[1].is_noise


def test_rule_a_fast_path_per_read_same_as_rule_path():
    """Per-read bytes go through `_fast`; it cuts and rejoins as rule A does for per-byte bytes."""
    reads = [Chunk(10_000_000, REQ + RSP[:3]), Chunk(12_000_000, RSP[3:] + REQ)]  # glued and split
    assert shape(frames(RtuFramer, reads)) == shape(frames(RtuFramer, wire(REQ + RSP + REQ)))


def test_rule_b1_crc_run_of_the_wrong_length():
    run = crc("01030000000100")  # 9 bytes, CRC good, but function 03 is 8 or byte count + 5 long
    unknown, user = crc("015a0102"), crc("01410102")
    got = frames(RtuFramer, wire(run, 5, unknown, 5, user))
    assert shape(got) == [(run, "modbus-rtu", BOTH, True), (unknown, "modbus-rtu", BOTH, True),
                          (user, "modbus-rtu", BOTH, True)]
    assert [codes(f) for f in got] == [["modbus.length.mismatch"], ["modbus.function.unknown"],
                                       ["modbus.function.user_defined"]]
    assert got[0].annotations[0].detail == "9 bytes do not fit function 0x03"


def test_rule_b2_noise_glued_before_a_frame():
    got = frames(RtuFramer, wire(b"\xff\x13\xa5" + REQ))  # one burst: no silence before the frame
    assert shape(got) == [(b"\xff\x13\xa5", "noise", 0, None), (REQ, "modbus-rtu", CAN_REQ, True)]
    assert got[0].noise_reason == "3 byte(s): too short for a frame" and codes(got[0]) == ["noise.bytes"]


def test_rule_b3b_a_frame_with_junk_on_both_sides():
    """A good frame inside a burst with a stray byte on each side: B2's scan finds no plausible end
    after it, B3 no damaged frame; B3b takes the frame and leaves the junk as noise (issue 10)."""
    got = frames(RtuFramer, wire(b"\xff" + REQ + b"\x77"))
    assert shape(got) == [(b"\xff", "noise", 0, None), (REQ, "modbus-rtu", CAN_REQ, True),
                          (b"\x77", "noise", 0, None)]


def test_rule_b3_before_b3b_a_damaged_frame_is_not_searched_for_a_chance_crc():
    """A write-multiple whose 8 data bytes happen to be a CRC-valid frame, its own CRC bad: the
    structural length ends at the boundary, so it is one damaged frame (B3), not noise around a frame."""
    inner = crc("020600010005")
    body = bytes.fromhex("01100000000408") + inner
    outer = body + bytes([crc(body.hex())[-2] ^ 0xFF, 0x00])
    (f,) = frames(RtuFramer, wire(outer))
    assert shape([f]) == [(outer, "modbus-rtu", CAN_REQ, False)]


def test_rule_b3_damaged_frame_ends_at_the_boundary():
    (f,) = frames(RtuFramer, wire(BAD))
    assert shape([f]) == [(BAD, "modbus-rtu", CAN_REQ, False)]  # the 8-byte length fits a request only
    assert codes(f) == ["modbus.crc.mismatch"] and f.crc_expected == REQ[-2] | REQ[-1] << 8
    a = f.annotations[0]
    assert (a.start, a.end, a.detail) == (6, 8, "CRC is 0xF7A4, expected 0x08A4 (bytes a4 08)")


def test_rule_b3_damaged_frame_split_across_reads_is_rejoined():
    got = frames(RtuFramer, [Chunk(10_000_000, BAD[:3]), Chunk(12_000_000, BAD[3:])])  # a SOFT read boundary
    assert shape(got) == [(BAD, "modbus-rtu", CAN_REQ, False)]


def test_rule_b4_malformed_burst_between_two_t35_silences():
    burst = bytes.fromhex("01060001000311223344")  # function 06 is 8 bytes long; 10 here, bad CRC
    (f,) = frames(RtuFramer, wire(burst))
    assert shape([f]) == [(burst, "modbus-rtu", BOTH, False)]
    assert codes(f) == ["modbus.crc.mismatch", "modbus.length.mismatch"]
    # the same bytes 2 characters after a frame: no t3.5 silence before them, so no frame
    got = frames(RtuFramer, wire(REQ, 2, burst))
    assert shape(got) == [(REQ, "modbus-rtu", CAN_REQ, True), (burst, "noise", 0, None)]


def test_rule_b5_noise_up_to_the_boundary():
    got = frames(RtuFramer, wire(b"\xff\xff", 5, bytes.fromhex("015a112233"), 5, bytes.fromhex("f9030000")))
    assert [(f.raw.hex(), f.protocol) for f in got] == [("ffff", "noise"), ("015a112233", "noise"),
                                                        ("f9030000", "noise")]
    assert [f.noise_reason for f in got] == [
        "2 byte(s): too short for a frame",
        "no frame: unknown function 0x5A and no valid CRC",
        "no frame: unit 249 is reserved and no valid CRC",
    ]
    assert all(codes(f) == ["noise.bytes"] and f.annotations[0].end == len(f.raw) for f in got)


# ------------------------------------------------------------------ boundaries
def test_boundary_none_and_soft_inside_a_frame_per_byte():
    """Under 1.5 characters of silence: no boundary; 1.5 to 3.5: SOFT, which a frame may span."""
    (f,) = frames(RtuFramer, wire(REQ[:4], 0.4, REQ[4:]))
    assert f.raw == REQ and f.crc_ok and codes(f) == []
    (f,) = frames(RtuFramer, wire(REQ[:4], 2, REQ[4:]))
    assert f.raw == REQ and f.crc_ok and codes(f) == ["modbus.timing.t15"]
    a = f.annotations[0]
    assert (a.start, a.end) == (4, 5) and a.detail == f"{2 * CHAR / 1e6:.2f} ms silence before byte 4"


def test_boundary_hard_per_byte_is_never_spanned():
    got = frames(RtuFramer, wire(REQ[:3], 4, REQ[3:]))  # 4 characters >= t3.5
    assert [(f.raw, f.protocol) for f in got] == [(REQ[:3], "noise"), (REQ[3:], "noise")]


def test_boundary_per_read_soft_within_t35_plus_slack_hard_beyond():
    soft = [Chunk(10_000_000, REQ[:3]), Chunk(40_000_000, REQ[3:])]  # 30 ms: an adapter's latency
    assert shape(frames(RtuFramer, soft)) == [(REQ, "modbus-rtu", CAN_REQ, True)]
    hard = [Chunk(10_000_000, REQ[:3]), Chunk(100_000_000, REQ[3:])]  # past t3.5 + 50 ms read slack
    assert [f.raw for f in frames(RtuFramer, hard)] == [REQ[:3], REQ[3:]]


def test_boundary_per_read_counts_silence_only_from_the_readers_last_empty_look():
    # the reader stalled 90 ms, its last look at the port 89 ms before the read: the rest of the frame may
    # have waited in the tty all along, so the gap is no proven silence
    stalled = [Chunk(10_000_000, REQ[:3], unseen_ns=2_000_000), Chunk(100_000_000, REQ[3:], unseen_ns=89_000_000)]
    assert shape(frames(RtuFramer, stalled)) == [(REQ, "modbus-rtu", CAN_REQ, True)]
    # it looked 3 ms before the read and found nothing: 87 ms of silence, the bytes are two runs
    looked = [Chunk(10_000_000, REQ[:3], unseen_ns=2_000_000), Chunk(100_000_000, REQ[3:], unseen_ns=3_000_000)]
    assert [f.raw for f in frames(RtuFramer, looked)] == [REQ[:3], REQ[3:]]


def test_boundary_hard_on_a_channel_change():
    reads = [Chunk(10_000_000, REQ[:3], channel="RX"), Chunk(11_000_000, REQ[3:], channel="TX")]
    assert [f.raw for f in frames(RtuFramer, reads)] == [REQ[:3], REQ[3:]]


def test_boundary_hard_after_a_tick_that_proved_silence():
    f = RtuFramer(LINE)
    assert f.feed(Chunk(10_000_000, REQ[:3])) == []  # waiting for the rest of the frame
    assert f.tick(10_000_000 + LINE.t35_ns) == []  # not silence enough yet (read slack)
    (noise,) = f.tick(10_000_000 + LINE.t35_ns + 60_000_000)
    assert noise.raw == REQ[:3] and noise.is_noise
    assert [x.raw for x in f.feed(Chunk(70_100_000, REQ[3:])) + f.flush()] == [REQ[3:]]


def test_t35_annotation_when_a_frame_starts_too_soon():
    got = frames(RtuFramer, wire(REQ, 2, RSP, 5, REQ))
    assert [codes(f) for f in got] == [[], ["modbus.timing.t35"], []]
    assert got[1].annotations[0].detail == "2.00 characters of silence before the frame"


def test_uart_flags_annotate_their_byte():
    times = tuple(i * CHAR for i in range(len(REQ)))
    (f,) = frames(RtuFramer, [Chunk(0, REQ, times, ((2, "parity"), (5, FLAG_FRAMING)))])
    # still one frame of these bytes, but a CRC over bytes the UART flagged proves nothing
    assert f.raw == REQ and f.crc_ok is False and f.unit == 1 and f.function == 3
    assert [(a.code, a.start, a.end) for a in f.annotations] == [("uart.parity_error", 2, 3),
                                                                ("uart.framing_error", 5, 6),
                                                                ("modbus.crc.unproven", 6, 8)]
    (g,) = frames(RtuFramer, [Chunk(10_000_000, REQ, None, ((2, "parity"),))])  # per read: not the fast path
    assert g.raw == REQ and codes(g) == ["uart.parity_error", "modbus.crc.unproven"] and not g.crc_ok


# ------------------------------------------------------------------ PD-series RTU rules
PD_REQ = crc("01030101")  # ADDR FUNC LEN=1 DATA CRC: 6 bytes
PD_RSP = crc("010403010bb8")  # LEN=3: 8 bytes


def test_pd_rule_a_glued_frames_cut_by_len():
    got = frames(PdRtuFramer, wire(PD_REQ + PD_RSP + PD_REQ))
    assert shape(got) == [(PD_REQ, "pd-rtu", BOTH, True), (PD_RSP, "pd-rtu", BOTH, True),
                          (PD_REQ, "pd-rtu", BOTH, True)]
    assert [codes(f) for f in got] == [[], ["pd.timing.quiet"], ["pd.timing.quiet"]]


def test_pd_rule_a_needs_no_plausible_end():
    """LEN + 5 with a good CRC is a frame whatever follows it (B1's CRC runs need a plausible end)."""
    got = frames(PdRtuFramer, wire(PD_REQ + b"\x77\x66"))
    assert shape(got) == [(PD_REQ, "pd-rtu", BOTH, True), (b"\x77\x66", "noise", 0, None)]


def test_pd_rule_a_roles_from_the_header():
    err, bc = crc("018101ff"), crc("00030108")  # an error reply; a broadcast (unit 0)
    got = frames(PdRtuFramer, wire(err, QUIET, bc))
    assert shape(got) == [(err, "pd-rtu", CAN_RSP, True), (bc, "pd-rtu", CAN_REQ, True)]


def test_pd_rule_b1_lenient_len_where_the_crc_fits():
    run = crc("0104031388")  # LEN=03 but 2 data bytes: the manual's own l.175 shape
    (f,) = frames(PdRtuFramer, wire(run))
    assert shape([f]) == [(run, "pd-rtu", BOTH, True)] and codes(f) == ["pd.len.mismatch"]
    assert f.annotations[0].detail == "LEN=03H but 2 data byte(s) follow (taken where the CRC fits)"


def test_pd_rule_b2_noise_glued_before_a_frame():
    got = frames(PdRtuFramer, wire(b"\xff\x00" + PD_RSP))
    assert shape(got) == [(b"\xff\x00", "noise", 0, None), (PD_RSP, "pd-rtu", BOTH, True)]
    assert got[0].noise_reason == "2 byte(s): too short for a PD frame"


def test_pd_rule_b3_damaged_frame_ends_at_the_boundary():
    bad = PD_RSP[:-1] + bytes([PD_RSP[-1] ^ 0xFF])
    got = frames(PdRtuFramer, wire(PD_REQ, 30, bad))  # 30 characters: SOFT, so not a whole burst (B4)
    assert shape(got) == [(PD_REQ, "pd-rtu", BOTH, True), (bad, "pd-rtu", BOTH, False)]
    assert codes(got[1]) == ["modbus.crc.mismatch", "pd.timing.quiet"]
    assert got[1].crc_expected == PD_RSP[-2] | PD_RSP[-1] << 8


def test_pd_rule_b4_malformed_burst_between_two_quiets():
    burst = bytes.fromhex("01030501021122")  # LEN=05 says 10 bytes; 7 here, bad CRC
    (f,) = frames(PdRtuFramer, wire(burst))
    assert shape([f]) == [(burst, "pd-rtu", BOTH, False)]
    assert codes(f) == ["pd.len.mismatch", "modbus.crc.mismatch", "modbus.length.truncated"]  # 3 bytes missing
    got = frames(PdRtuFramer, wire(PD_REQ, 20, burst))  # 20 characters: less than the quiet, no burst
    assert shape(got) == [(PD_REQ, "pd-rtu", BOTH, True), (burst, "noise", 0, None)]


def test_pd_rule_b5_noise_up_to_the_boundary():
    got = frames(PdRtuFramer, wire(b"\xff", QUIET, bytes.fromhex("010900112233")))
    assert [(f.raw.hex(), f.noise_reason) for f in got] == [
        ("ff", "1 byte(s): too short for a PD frame"),
        ("010900112233", "no frame: unknown function 09H and no valid CRC"),
    ]


def test_pd_quiet_time_is_the_hard_boundary_and_no_t15():
    (f,) = frames(PdRtuFramer, wire(PD_RSP[:3], 30, PD_RSP[3:]))  # 17 ms: SOFT, rejoined by LEN + CRC
    assert f.raw == PD_RSP and f.crc_ok and codes(f) == []  # the manual has no inter-character rule
    assert [x.raw for x in frames(PdRtuFramer, wire(PD_RSP[:3], QUIET, PD_RSP[3:]))] == [PD_RSP[:3], PD_RSP[3:]]
    got = frames(PdRtuFramer, wire(PD_REQ, 30, PD_REQ))
    assert [codes(x) for x in got] == [[], ["pd.timing.quiet"]]


# ------------------------------------------------------------------ ASCII
MB = asc("010300000001")  # b":010300000001FB\r\n"


def test_ascii_colon_to_crlf_is_a_frame():
    (f,) = frames(AsciiFramer, wire(MB))
    assert shape([f]) == [(MB, "modbus-ascii", CAN_REQ, True)] and codes(f) == []
    assert (f.unit, f.function, f.adu) == (1, 3, bytes.fromhex("010300000001"))


def test_ascii_without_crlf_ends_before_the_next_colon():
    rsp = asc("01030200ff")
    got = frames(AsciiFramer, wire(MB[:-2] + rsp))
    assert shape(got) == [(MB[:-2], "modbus-ascii", CAN_REQ, True), (rsp, "modbus-ascii", CAN_RSP, True)]
    assert codes(got[0]) == ["modbus.ascii.no_crlf"] and codes(got[1]) == []


def test_ascii_lrc_mismatch_points_at_the_lrc_characters():
    bad = asc("010300000001", 0xFA)
    got = frames(AsciiFramer, wire(bad, bad[:-2]))
    assert shape(got) == [(bad, "modbus-ascii", CAN_REQ, False), (bad[:-2], "modbus-ascii", CAN_REQ, False)]
    assert [codes(f) for f in got] == [["modbus.crc.mismatch"], ["modbus.crc.mismatch", "modbus.ascii.no_crlf"]]
    for f in got:
        a = f.annotations[0]
        assert f.raw[a.start : a.end] == b"FA" and a.detail == "LRC is 0xFA, expected 0xFB" and f.crc_expected == 0xFB


def test_ascii_bad_hex_is_noise_in_ascii_words():
    got = frames(AsciiFramer, wire(b":8Yfdfd\r\n", b":0103000\r\n", b":01FF\r\n"))
    assert [(f.protocol, f.unit, f.function) for f in got] == [("noise", None, None)] * 3
    assert [f.noise_reason for f in got] == [
        "':' frame whose characters are not hex pairs ('Y' at character 2 is not a hex digit)",
        "':' frame whose characters are not hex pairs (an odd number (7) of hex digits)",
        "2 byte(s) after ':': too short for unit, function and LRC",
    ]
    assert [codes(f) for f in got] == [["noise.bytes", "modbus.ascii.bad_hex"]] * 2 + [["noise.bytes"]]
    bh = got[0].annotations[1]
    assert got[0].raw[bh.start : bh.end] == b"Y"


def test_ascii_noise_outside_colon_crlf():
    got = frames(AsciiFramer, wire(b"hello there!" + MB))
    assert [(f.raw, f.protocol) for f in got] == [(b"hello there!", "noise"), (MB, "modbus-ascii")]
    assert got[0].noise_reason == "12 character(s) outside ':' ... CR LF"


def test_ascii_waits_for_crlf_and_cuts_a_runaway_line():
    f = AsciiFramer(LINE)
    assert f.feed(wire(MB[:-1])[0]) == [] and [x.raw for x in f.feed(wire(b"\n", t0=10**9)[0])] == [MB]
    runaway = b":" + b"0" * 600 + b"\r\n"
    whole = frames(AsciiFramer, wire(runaway))  # no line is longer than MAX_LINE characters
    assert [(len(x.raw), x.protocol) for x in whole] == [(MAX_LINE, "modbus-ascii"), (88, "noise")]
    assert codes(whole[0]) == ["modbus.function.unknown", "modbus.ascii.no_crlf"]  # 256 zero bytes, LRC 00: cut
    by_byte = frames(AsciiFramer, [Chunk(i * CHAR, runaway[i : i + 1], (i * CHAR,)) for i in range(len(runaway))])
    assert shape(by_byte) == shape(whole)


def test_pd_ascii_frame_noise_and_bad_hex():
    good, short_len = asc("01030101"), asc("0104031388")
    got = frames(PdAsciiFramer, wire(good, b"zz", short_len[:-2], b":0G\r\n", b":01FF\r\n"))
    assert [(f.raw, f.protocol, f.role_fits, f.crc_ok) for f in got] == [
        (good, "pd-ascii", BOTH, True), (b"zz", "noise", 0, None), (short_len[:-2], "pd-ascii", BOTH, True),
        (b":0G\r\n", "noise", 0, None), (b":01FF\r\n", "noise", 0, None)]
    assert [codes(f) for f in got] == [[], ["noise.bytes"], ["pd.len.mismatch", "pd.ascii.no_crlf"],
                                       ["noise.bytes", "pd.ascii.bad_hex"], ["noise.bytes"]]
    lm = got[2].annotations[0]
    assert got[2].raw[lm.start : lm.end] == b"03"  # the LEN characters
    assert [f.noise_reason for f in got if f.is_noise] == [
        "2 character(s) outside ':' ... CR LF",
        "':' frame whose characters are not hex pairs ('G' at character 2 is not a hex digit)",
        "2 byte(s) after ':': too short for ADDR FUNC + LRC",
    ]


def test_pd_ascii_lrc_mismatch():
    bad = asc("01030101", 0x00)
    (f,) = frames(PdAsciiFramer, wire(bad))
    assert shape([f]) == [(bad, "pd-ascii", BOTH, False)] and codes(f) == ["modbus.crc.mismatch"]
    a = f.annotations[0]
    assert f.raw[a.start : a.end] == b"00" and f.crc_expected == lrc(bytes.fromhex("01030101"))
