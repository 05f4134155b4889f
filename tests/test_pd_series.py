"""PD-series protocol: framers (pd-rtu, pd-ascii), decoder, the manual's example frames.

The PD-series manual (pd-series-protocol.txt, the team's manuals folder) contradicts itself about
LEN; decoders/pd_series/NOTES.md has our reading.  Wrong bytes in the manual
stay wrong in examples.toml and the sniffer must flag them.  The lines the
tests hold the tables against are kept in tests/data/pd-series-manual-lines.json,
so the tests read nothing outside the repository; `scripts/check-manual-excerpt.py MANUAL`
holds the copy against the manual by hand.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from decoders.base import UnitState
from decoders.pd_series import PdSeriesDecoder
from decoders.pd_series import schema
from decoders.pd_series.schema import CNST_BITS, CNTR_BITS, PARAMS, STATUS
from decoders.registry import default_registry
from helpers import bursts, run_events
from sniffer.framing.crc import crc_bytes, lrc
from sniffer.events import CaptureInfo, Chunk, Tick
from sniffer.frame import CAN_REQ, CAN_RSP, REQUEST, RESPONSE, UNKNOWN, Frame
from sniffer.line import LineSettings
from sniffer.framing import pd as pd_framer
from sniffer.framing.pd import QUIET_NS, PdAsciiFramer, PdRtuFramer
from sniffer.capture.pipeline import Pipeline
from sniffer.formats.records import frame_record

LINE = LineSettings(9600, "N", 1)
PKG = Path(__file__).resolve().parent.parent / "decoders" / "pd_series"
EXCERPT = json.loads((Path(__file__).resolve().parent / "data" / "pd-series-manual-lines.json").read_text("utf-8"))
EXAMPLES = tomllib.loads((PKG / "examples.toml").read_text())["examples"]
BY_LINE = {ex["line"]: ex for ex in EXAMPLES}
CODEBOOK = default_registry().codebook
DEV = {u: "pd-series" for u in range(256)}


def rtu(h: str) -> str:
    """A frame's hex with its CRC appended."""
    b = bytes.fromhex(h)
    return (b + crc_bytes(b)).hex()


def asc(h: str) -> str:
    """ADDR..DATA hex -> the hex of its ASCII frame ':' .. LRC CR LF."""
    b = bytes.fromhex(h)
    return (b":" + (b.hex() + f"{lrc(b):02x}").upper().encode() + b"\r\n").hex()


def run(hexes, protocol="pd-rtu", gap_chars=5.0, devices=DEV):
    return run_events(bursts(hexes, LINE, gap_chars), LINE, devices=devices, protocol=protocol)


def codes_of(f):
    return [a.code for a in f.annotations]


def errors_of(f):
    return [(a.code, a.detail) for a in f.annotations if a.severity == "error"]


def check_invariants(frames, data: bytes):
    assert b"".join(f.raw for f in frames) == data
    for f in frames:
        assert f.raw
        for a in f.annotations:
            assert 0 <= a.start < a.end <= len(f.raw), (a, f)
            assert a.code in CODEBOOK, a.code
            assert not a.detail.startswith("decoder "), a.detail  # the registry caught an exception
        frame_record(f, 0)


def manual_lines() -> list[str]:
    """The manual's lines (text[n - 1] is line n): the kept excerpt, "" for lines it does not hold."""
    text = [""] * EXCERPT["source_lines"]
    for n, line in EXCERPT["lines"].items():
        text[int(n) - 1] = line
    return text


# ---------------------------------------------------------------- manual examples
def test_examples_cover_the_manual():
    assert len(EXAMPLES) == 7
    assert sorted(BY_LINE) == [173, 175, 192, 193, 199, 228, 230]
    text = manual_lines()
    for ex in EXAMPLES:
        printed = text[ex["line"] - 1]
        assert printed.strip(), ex["line"]
        if ex["protocol"] == "pd-rtu":  # the printed bytes are on that line, in that order
            words = [w.rstrip("H") for w in printed.replace("\t", " ").split()]
            joined = "".join(w for w in words if len(w) == 2 and all(c in "0123456789ABCDEFabcdef" for c in w))
            assert ex["hex"].lower() in joined.lower(), (ex["line"], joined)


@pytest.mark.parametrize("ex", EXAMPLES, ids=lambda ex: f"l{ex['line']}")
def test_example_check_values_computed(ex):
    data = bytes.fromhex(ex["hex"])
    if ex["protocol"] == "pd-rtu":
        if ex.get("crc_printed", True):
            assert (crc_bytes(data[:-2]) == data[-2:]) == ex["crc_ok"]
            adu = data[:-2]
        else:
            assert ex["crc_ok"] is False
            assert crc_bytes(data).hex().upper() == ex["expected_crc"]
            adu = data
    else:
        body = bytes.fromhex(data[1:-2].decode())
        adu = body[:-1]
        assert (lrc(adu) == body[-1]) == ex["crc_ok"]
    assert (adu[2] == len(adu) - 3) == ex["len_ok"]


@pytest.mark.parametrize("ex", EXAMPLES, ids=lambda ex: f"l{ex['line']}")
def test_manual_example_verdict(ex):
    proto = ex["protocol"]
    before = [rtu(BY_LINE[ex["answers"]]["hex"])] if "answers" in ex else []
    frames = run([ex["hex"]], proto)
    check_invariants(frames, bytes.fromhex(ex["hex"]))
    verdict = ex["verdict"]
    if verdict == "noise":
        assert all(f.is_noise for f in frames)
        return
    if verdict == "len":
        # as printed (no CRC): never a CRC-good frame
        assert not any(f.crc_ok for f in frames)
        # as a device would send it: the printed bytes + their CRC
        frames = run(before + [rtu(ex["hex"])], proto)
        f = frames[-1]
        assert len(frames) == len(before) + 1 and f.crc_ok and not f.is_noise
        assert "pd.len.mismatch" in codes_of(f)
        assert f.role == ex["role"]
        if "answers" in ex:
            assert f.pair == frames[0].index
    else:
        assert len(frames) == 1
        f = frames[0]
        assert f.crc_ok and f.role == ex["role"] and f.model == "pd-series"
        assert "pd.len.mismatch" not in codes_of(f)
        assert not errors_of(f)
    assert f.summary
    if "raw_value" in ex:
        assert f.points and f.points[0]["raw"] == ex["raw_value"]


def test_printed_ok_frames_decode_to_the_manual_meaning():
    f = run([BY_LINE[228]["hex"]])[0]
    assert (f.unit, f.function, f.points[0]["address"], f.points[0]["raw"]) == (1, 2, 0, 3000)
    assert "pd.param.unknown" in codes_of(f)  # PD000 (prose says PD003): see NOTES.md
    a = run([BY_LINE[193]["hex"]], "pd-ascii")[0]
    assert a.adu == f.adu and a.crc_ok and a.protocol == "pd-ascii"


def test_status_example_pair_reads_cfg_from_the_request():
    req, rsp = run([rtu("01040300"), rtu("0104031388")])
    assert req.summary.startswith("read status CFG 0")
    assert rsp.points[0]["name"] == "Set F" and rsp.points[0]["value"] == 50.0 and rsp.points[0]["unit"] == "Hz"
    for f in (req, rsp):
        lm = [a for a in f.annotations if a.code == "pd.len.mismatch"]
        assert lm and (lm[0].start, lm[0].end) == (2, 3)  # the LEN byte


def test_wrong_crc_is_flagged_with_the_expected_value():
    good = bytes.fromhex(BY_LINE[228]["hex"])
    bad = good[:-1] + b"\x0d"
    f = run([bad.hex()])[0]
    assert f.crc_ok is False and f.crc_expected == 0x0C7F
    assert "modbus.crc.mismatch" in codes_of(f)
    a = run([asc("010203000bb8").replace("3337", "3338")], "pd-ascii")[0]
    assert a.crc_ok is False and a.crc_expected == 0x37


# ---------------------------------------------------------------- pairing
TRAFFIC = [  # (hex without CRC, role, function key)
    ("010103a50000", REQUEST, 0x01),  # read PD165
    ("010103a50003", RESPONSE, 0x01),  # PD165 = 3 (8N1 RTU)
    ("010203a50004", REQUEST, 0x02),  # write PD165 = 4
    ("010203a50004", RESPONSE, 0x02),
    ("0101014a", REQUEST, 0x01),  # read PD074 (LEN=1, parameter byte only)
    ("0181014a", RESPONSE, 0x81),  # 81H to a read
    ("010202ae05", REQUEST, 0x02),  # write PD174 (read-only)
    ("018101ae", RESPONSE, 0x82),  # 81H to a write: pairing key 82H
    ("01030103", REQUEST, 0x03),  # run + for
    ("01030109", RESPONSE, 0x03),  # run + running
    ("01030106", REQUEST, 0x03),  # for + rev
    ("01830109", RESPONSE, 0x83),
    ("010403010000", REQUEST, 0x04),  # status Out F
    ("010403010bb8", RESPONSE, 0x04),  # CFG 1 + 3000 = 30.00 Hz
    ("01050209c4", REQUEST, 0x05),  # 25.00 Hz
    ("01050209c4", RESPONSE, 0x05),
    ("0108021234", REQUEST, 0x08),
    ("0108021234", RESPONSE, 0x08),
]


@pytest.mark.parametrize("protocol", ["pd-rtu", "pd-ascii"])
def test_request_response_pairing(protocol):
    enc = rtu if protocol == "pd-rtu" else asc
    frames = run([enc(h) for h, _, _ in TRAFFIC], protocol)
    assert [(f.role, f.function) for f in frames] == [(r, fc) for _, r, fc in TRAFFIC]
    for i in range(0, len(frames), 2):
        assert frames[i].pair == frames[i + 1].index and frames[i + 1].pair == frames[i].index
    for f in frames:
        assert f.crc_ok and f.model == "pd-series" and f.summary
        assert "pair.mismatch" not in codes_of(f) and "pair.orphan_response" not in codes_of(f)
    f = {i: fr for i, fr in enumerate(frames)}
    assert f[1].points[0]["text"] == "8N1 for RTU"
    assert f[5].exception == {"code": 0x81, "name": "parameter not available or setting rejected"}
    assert "read parameter" in f[5].summary
    assert "pd.write.read_only" in codes_of(f[6]) and "write parameter" in f[7].summary
    assert "pd.error.write" in codes_of(f[7]) and f[7].adu[1] == 0x81
    assert f[8].points[0]["text"] == "run for" and f[9].points[0]["text"] == "run running"
    assert f[11].exception["code"] == 0x83
    assert (f[13].points[0]["name"], f[13].points[0]["value"]) == ("Out F", 30.0)
    assert f[14].points[0]["value"] == 25.0 and f[16].summary.endswith("12 34")


def test_broadcast():
    frames = run([rtu("00030108"), rtu("000203a50003"), rtu("00040100"), rtu("01030101"), rtu("01030101")])
    bc = frames[:3]
    assert all(f.role == REQUEST and f.pair is None and "pair.broadcast" in codes_of(f) for f in bc)
    assert "(broadcast)" in bc[0].summary and bc[0].points[0]["text"] == "stop"
    assert "pd.broadcast.read" in codes_of(bc[2]) and "pd.broadcast.read" not in codes_of(bc[0])
    assert frames[3].role == REQUEST and frames[4].role == RESPONSE and frames[4].pair == 3


def test_pd_checks_replace_the_modbus_pair_rule():
    ok = run([rtu("010103a50000"), rtu("010103a50003")])[1]
    assert "pair.mismatch" not in codes_of(ok)  # Modbus byte-count rules do not apply to PD
    wrong = run([rtu("010103a50000"), rtu("010103a60003")])[1]
    pm = [a for a in wrong.annotations if a.code == "pair.mismatch"]
    assert pm and "PD165" in pm[0].detail and "PD166" in pm[0].detail
    cfg = run([rtu("010403010000"), rtu("010403020bb8")])[1]
    assert "pair.mismatch" in codes_of(cfg)
    loop = run([rtu("0108021234"), rtu("0108021235")])[1]
    assert "pd.loop.echo" in codes_of(loop)


def test_write_while_running_and_range():
    frames = run([rtu("01030101"), rtu("01030109"), rtu("010203a50009"), rtu("010203a50009"), rtu("010203ac0001")])
    assert "pd.write.running" in codes_of(frames[2]) and "pd.value.range" in codes_of(frames[2])
    assert frames[4].role == REQUEST and frames[4].points[0]["text"] == "fault clear"
    assert "pd.write.running" not in codes_of(frames[4])  # PD172 is ** (l.283, l.335)


# ---------------------------------------------------------------- framing
def test_glued_frames_in_one_usb_read_are_cut():
    parts = [rtu("010403010000"), rtu("010403010bb8"), rtu("01040300"), rtu("0104031388"),
             rtu("01030101"), rtu("01030109")]
    data = b"".join(bytes.fromhex(h) for h in parts)
    frames = run_events([Chunk(200_000_000, data)], LINE, devices=DEV, protocol="pd-rtu")
    assert [f.raw.hex() for f in frames] == parts
    assert all(f.time_source == "read" and f.crc_ok for f in frames)
    assert [f.role for f in frames] == [REQUEST, RESPONSE] * 3
    assert [f.pair for f in frames] == [1, 0, 3, 2, 5, 4]


def test_noise_glued_before_a_lenient_frame_in_one_read():
    parts = ["ff00", rtu("0104031388"), rtu("0104031388"), rtu("010403000000")]
    data = b"".join(bytes.fromhex(h) for h in parts)
    frames = _frames(data)
    assert [x.raw.hex() for x in frames] == parts
    assert frames[0].is_noise and [("pd.len.mismatch" in codes_of(x)) for x in frames[1:]] == [True, True, False]


def _frames(data: bytes):
    f = PdRtuFramer(LINE)
    return f.feed(Chunk(10**9, data)) + f.flush()


def test_frame_then_zeros_is_not_swallowed():
    """A CRC register at 0 stays 0 through 00 bytes: structure must cut (NOTES.md, "CRC high byte 00")."""
    good = bytes.fromhex(rtu("010403010bb8"))
    assert [x.raw for x in _frames(good + b"\0\0\0")] == [good, b"\0\0\0"]
    far = bytes.fromhex(rtu("0104001388"))  # LEN 0 on 2 data bytes: B1, shortest CRC-good run
    frames = _frames(far + b"\0\0\0")
    assert [x.raw for x in frames] == [far, b"\0\0\0"] and frames[1].is_noise
    assert "pd.len.mismatch" in codes_of(frames[0])


def test_len_one_too_long_then_broadcast():
    """The LEN length would swallow the next broadcast's address 00: the shorter reading wins."""
    first = bytes.fromhex(rtu("0104031388"))  # the manual's l.175 shape
    bc = bytes.fromhex(rtu("00030108"))
    assert [x.raw for x in _frames(first + bc)] == [first, bc]


def _timed(parts, gap_ns):
    """Per-byte times: bytes back to back, gap_ns of silence between parts."""
    chunks, t = [], 0
    for data in parts:
        times = tuple(t + i * LINE.char_ns for i in range(len(data)))
        chunks.append(Chunk(times[0], data, times))
        t = times[-1] + LINE.char_ns + gap_ns
    return chunks


def test_quiet_of_50ms_is_the_frame_boundary():
    frame = bytes.fromhex(rtu("010403010bb8"))
    pieces = [frame[:3], frame[3:]]
    short = run_events(_timed(pieces, 20_000_000), LINE, devices=DEV, protocol="pd-rtu")
    assert [f.raw for f in short] == [frame] and short[0].crc_ok  # 20 ms: SOFT, rejoined by LEN + CRC
    assert "modbus.timing.t15" not in codes_of(short[0])
    long = run_events(_timed(pieces, 60_000_000), LINE, devices=DEV, protocol="pd-rtu")
    assert frame not in [f.raw for f in long]  # > 50 ms: never one frame
    fr = PdRtuFramer(LINE)
    assert fr.hard_ns == QUIET_NS
    assert fr.feed(_timed([frame[:3]], 0)[0]) == []
    assert fr.tick(3 * LINE.char_ns + 40_000_000) == [] and fr.tick(3 * LINE.char_ns + 60_000_000)


def test_quiet_annotation():
    frames = run_events(_timed([bytes.fromhex(rtu("01030101"))] * 2, 10_000_000), LINE, devices=DEV,
                        protocol="pd-rtu")
    assert "pd.timing.quiet" in codes_of(frames[1])
    frames = run_events(_timed([bytes.fromhex(rtu("01030101"))] * 2, 60_000_000), LINE, devices=DEV,
                        protocol="pd-rtu")
    assert "pd.timing.quiet" not in codes_of(frames[1])


def test_outside_vectors():
    """Frames printed in third-party Huanyang code (Grbl_ESP32 HuanyangSpindle.cpp), CRCs as printed."""
    texts = []
    for h in ["010301013188", "01030108f18e", "010301113044", "01050209c4bf0f"]:
        (f,) = run([h])
        assert f.crc_ok and f.role == REQUEST and not errors_of(f) and "pd.len.mismatch" not in codes_of(f)
        texts.append(f.points[0].get("text", f.points[0]["value"]))
    assert texts == ["run", "stop", "run r/f", 25.0]


def test_ascii_framing_details():
    data = bytes.fromhex(asc("01030101")) + b"zz" + bytes.fromhex(asc("0104031388"))[:-2] + b":0G\r\n"
    f = PdAsciiFramer(LINE)
    frames = f.feed(Chunk(10**9, data)) + f.flush()
    assert b"".join(x.raw for x in frames) == data
    assert frames[0].adu.hex() == "01030101" and frames[1].is_noise
    assert "pd.ascii.no_crlf" in codes_of(frames[2]) and "pd.len.mismatch" in codes_of(frames[2])
    lm = next(a for a in frames[2].annotations if a.code == "pd.len.mismatch")
    assert frames[2].raw[lm.start:lm.end] == b"03"  # the LEN characters
    assert frames[3].is_noise and "pd.ascii.bad_hex" in codes_of(frames[3])


def test_decoder_spans_map_onto_ascii_characters():
    f = run([asc("010203ae0005")], "pd-ascii")[0]
    ro = next(a for a in f.annotations if a.code == "pd.write.read_only")
    assert f.raw[ro.start:ro.end] == b"0005"


# ---------------------------------------------------------------- schema
def test_schema_rows_cite_the_manual():
    text = manual_lines()
    for p in PARAMS.values():
        if p.number != 3:
            assert p.id in text[p.line - 1] or p.id in " ".join(text[p.line - 3 : p.line + 1]), p
    assert "PD003" in text[188]
    assert [b.label for b in sorted(CNTR_BITS, key=lambda b: -b.bit)] == text[139].split("\t")
    assert sorted(STATUS) == list(range(8))
    assert set(schema.FUNCTIONS) == pd_framer.FUNCTIONS and set(schema.ERRORS) == pd_framer.ERRORS
    assert {b.bit for b in CNST_BITS} == set(range(8))


# ---------------------------------------------------------------- fuzz
_pd_frame = st.builds(
    lambda unit, fc, body: bytes([unit, fc, len(body)]) + body + crc_bytes(bytes([unit, fc, len(body)]) + body),
    st.sampled_from([0, 1, 2, 250, 255]), st.sampled_from([1, 2, 3, 4, 5, 8, 0x81, 0x83, 6, 0x41]),
    st.binary(max_size=6),
)
_runs = st.lists(st.tuples(st.sampled_from([0.0, 1.0, 2.0, 30.0, 60.0]),
                           st.one_of(st.binary(min_size=1, max_size=30), _pd_frame)), min_size=1, max_size=15)


def _per_byte(runs):
    data, times, t = bytearray(), [], 0
    for gap_ms, chunk in runs:
        t += int(gap_ms * 1e6)
        for b in chunk:
            times.append(t)
            data.append(b)
            t += LINE.char_ns
    return bytes(data), times


def _pipe(chunks, protocol):
    p = Pipeline(CaptureInfo(), LINE, default_registry(DEV), protocol=protocol)
    out = []
    for c in chunks:
        out += p.feed(c)
    return out + p.finish()


def _sig(frames):
    return [(f.raw, f.t_ns, f.role, f.pair, f.crc_ok, tuple(codes_of(f)), f.summary) for f in frames]


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_runs, st.integers(1, 20))
def test_fuzz_rtu_per_byte(runs, cut):
    data, times = _per_byte(runs)
    whole = _pipe([Chunk(times[0], data, tuple(times))], "pd-rtu")
    check_invariants(whole, data)
    pieces = [Chunk(times[i], data[i : i + cut], tuple(times[i : i + cut])) for i in range(0, len(data), cut)]
    assert _sig(_pipe(pieces, "pd-rtu")) == _sig(whole)  # chunking invariance


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.one_of(st.binary(min_size=1, max_size=40), _pd_frame), min_size=1, max_size=10),
       st.integers(1, 64))
def test_fuzz_rtu_per_read(parts, cut):
    data = b"".join(parts)
    chunks, t = [], 1_000_000
    for k, i in enumerate(range(0, len(data), cut)):
        t += cut * LINE.char_ns + (k % 3) * 40_000_000
        chunks.append(Chunk(t, data[i : i + cut]))
    frames = _pipe(chunks + [Tick(t + 10**9)], "pd-rtu")
    check_invariants(frames, data)


_ascii_piece = st.one_of(
    st.binary(max_size=20),
    _pd_frame.map(lambda b: bytes.fromhex(asc(b[:-2].hex()))),
    st.text("0123456789ABCDEF:\r\nxG", max_size=30).map(str.encode),
)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_ascii_piece, min_size=1, max_size=10), st.integers(1, 40))
def test_fuzz_ascii(parts, cut):
    data = b"".join(parts)
    if not data:
        return
    chunks = [Chunk(10**6 * (i + 1), data[i : i + cut]) for i in range(0, len(data), cut)]
    frames = _pipe(chunks, "pd-ascii")
    check_invariants(frames, data)


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=2, max_size=40), st.sampled_from([REQUEST, RESPONSE, UNKNOWN]),
       st.one_of(st.none(), st.binary(min_size=2, max_size=12)), st.booleans(), st.sampled_from(["pd-rtu", "pd-ascii"]))
def test_fuzz_decoder_direct(adu, role, req_adu, crc, protocol):
    """The decoder never raises, whatever the ADU, role or request."""
    f = Frame(0, 0, 1, adu + b"\0\0", protocol, unit=adu[0], function=adu[1], role_fits=CAN_REQ | CAN_RSP, crc_ok=crc)
    f.adu, f.role = adu, role
    req = None
    if req_adu is not None:
        req = Frame(1, 0, 1, req_adu + b"\0\0", protocol, unit=req_adu[0], function=req_adu[1], crc_ok=True)
        req.adu = req_adu
    PdSeriesDecoder().decode(f, req, UnitState(adu[0]))
    for a in f.annotations:
        assert 0 <= a.start < a.end <= len(adu), a
        assert a.code in CODEBOOK
    frame_record(f, 0)
