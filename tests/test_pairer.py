"""The pairer rule by rule (sniffer/capture/pairer.py's docstring), on Frames built directly, and fuzzed.

Each rule test isolates one rule with frames whose `can` bits, units and
times are set by hand.  Two hypothesis tests: arbitrary Frames straight into
the Pairer (it never raises, every frame comes out once, in order), and
arbitrary bytes through every protocol's framer + pairer + decoders (no
exception, every byte in exactly one frame, any chunking the same frames).
"""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from decoders.registry import default_registry
from sniffer import protocols
from sniffer.codes import Annotation
from sniffer.framing.crc import crc_bytes, lrc
from sniffer.events import CaptureInfo, Chunk, Tick
from sniffer.frame import CAN_REQ, CAN_RSP, NOISE_ROLE, REQUEST, RESPONSE, UNKNOWN, Frame
from sniffer.line import LineSettings
from sniffer.capture.pairer import Pairer, response_mismatch
from sniffer.capture.pipeline import Pipeline
from sniffer.formats.records import frame_record

BOTH = CAN_REQ | CAN_RSP
MS = 1_000_000


def frame(index: int, t_ms: float, adu_hex: str, can: int, protocol: str = "modbus-rtu", crc_ok: bool = True,
          time_source: str = "byte") -> Frame:
    """A framed ADU (CRC appended) at t_ms, 1 ms long."""
    adu = bytes.fromhex(adu_hex)
    f = Frame(index, int(t_ms * MS), int((t_ms + 1) * MS), adu + crc_bytes(adu), protocol, unit=adu[0],
              function=adu[1], role_fits=can, crc_ok=crc_ok, time_source=time_source)
    f.adu = adu
    return f


def noise(index: int, t_ms: float, raw: bytes = b"\xff\xff") -> Frame:
    return Frame(index, int(t_ms * MS), int((t_ms + 1) * MS), raw, "noise", noise_reason="test")


def run(frames, pairer: Pairer | None = None) -> list[Frame]:
    p = pairer or Pairer()
    out = []
    for f in frames:
        out += p.push(f)
    return out + p.flush()


def notes(f) -> list[tuple[str, str]]:
    return [(a.code, a.detail) for a in f.annotations]


READ = "0103000a0002"  # read 2 holding registers at 10, unit 1: 8 bytes, a request shape only
READ_RSP = "010304000100ff"  # its answer: byte count 4


# ------------------------------------------------------------------ the rules
def test_pass_through_noise_and_unreadable_frames():
    """Noise, a frame without unit or function (or can = 0) is never paired and keeps its place."""
    bad_ascii = Frame(1, 2 * MS, 3 * MS, b":8Yfdfd\r\n", "modbus-ascii")  # unit, function None, can 0
    no_roles = frame(2, 4, "0141", 0)  # readable, but fits no role
    req, rsp = frame(0, 0, READ, CAN_REQ), frame(4, 8, READ_RSP, CAN_RSP)
    p = Pairer()
    assert p.push(req) == [] and p.push(bad_ascii) == [] and p.push(no_roles) == []
    assert p.push(noise(3, 6)) == []  # held behind the pending request
    out = p.push(rsp)
    assert [f.index for f in out] == [0, 1, 2, 3, 4]  # capture order
    assert (req.pair, rsp.pair) == (4, 0) and bad_ascii.pair is None and no_roles.pair is None
    assert (bad_ascii.role, no_roles.role, out[3].role) == (UNKNOWN, UNKNOWN, NOISE_ROLE)
    assert bad_ascii.annotations == [] and no_roles.annotations == []
    assert p.push(noise(5, 10)) != []  # nothing pending: settled at once


def test_unreadable_frame_then_exception_response_does_not_raise():
    """`sniffer decode ':8Yfdfd' ':0183027A' --protocol modbus-ascii` raised TypeError here."""
    bad = Frame(0, 0, MS, b":8Yfdfd\r\n", "modbus-ascii")
    exc = frame(1, 50, "018302", CAN_RSP, "modbus-ascii")
    out = run([bad, exc])
    assert out == [bad, exc] and exc.role == RESPONSE
    assert notes(exc) == [("pair.orphan_response", "nothing pending")]


def test_response_only_shapes_are_responses():
    req, exc = frame(0, 0, READ, CAN_REQ), frame(1, 5, "018302", CAN_RSP)
    out = run([req, exc])
    assert [(f.role, f.pair) for f in out] == [(REQUEST, 1), (RESPONSE, 0)]
    assert exc.latency_ms == 4.0 and notes(req) == [] and notes(exc) == []


def test_shape_fits_both_context_decides():
    write = "010600010055"  # 06 echoes its request: the same bytes both ways
    a, b = frame(0, 0, write, BOTH), frame(1, 5, write, BOTH)
    assert [(f.role, f.pair) for f in run([a, b])] == [(REQUEST, 1), (RESPONSE, 0)]
    # another unit's echo, or the same bytes past the timeout: a new request, not the answer
    c, d = frame(0, 0, write, BOTH), frame(1, 5, "020600010055", BOTH)
    assert [(f.role, f.pair) for f in run([c, d])] == [(REQUEST, None), (REQUEST, None)]
    e, g = frame(0, 0, write, BOTH), frame(1, 1500, write, BOTH)
    assert [(f.role, f.pair) for f in run([e, g])] == [(REQUEST, None), (REQUEST, None)]


def test_new_request_while_one_pending_is_no_response():
    a, b = frame(0, 0, READ, CAN_REQ), frame(1, 13.3, "0203000a0002", CAN_REQ)
    run([a, b])
    assert notes(a) == [("pair.no_response", "no response: next request after 12.3 ms")]
    a, b = frame(0, 0, READ, CAN_REQ), frame(1, 13.3, "0203000a0002", CAN_REQ)
    run([a, b], Pairer(unit_timeouts={1: 5}))  # past unit 1's timeout: pair.timeout follows
    assert notes(a) == [("pair.no_response", "no response: next request after 12.3 ms"),
                        ("pair.timeout", "unit 1: no response within 5 ms")]


def test_retry_detection():
    a, b, c = frame(0, 0, READ, CAN_REQ), frame(1, 60, READ, CAN_REQ), frame(2, 120, "0103000b0002", CAN_REQ)
    run([a, b, c])
    assert notes(b) == [("pair.retry", "repeats frame #0"),
                        ("pair.no_response", "no response: next request after 59.0 ms")]
    assert "pair.retry" not in [code for code, _ in notes(c)]  # other bytes: not a retry


def test_timeout_tick_settles_the_pending_request():
    p = Pairer()
    req, n = frame(0, 0, READ, CAN_REQ), noise(1, 3)
    assert p.push(req) == [] and p.push(n) == []
    assert not p.would_time_out(900 * MS) and p.tick(900 * MS) == []
    assert p.would_time_out(1501 * MS) and p.tick(1501 * MS) == [req, n]
    assert notes(req) == [("pair.no_response", "no response: timeout tick after 1500.0 ms"),
                          ("pair.timeout", "unit 1: no response within 1000 ms")]
    rsp = frame(2, 1600, READ_RSP, CAN_RSP)
    assert p.push(rsp) == [rsp] and req.pair is None  # the tick settled its request: it stays unanswered ...
    assert rsp.pair == 0 and rsp.latency_ms == 1599.0  # ... and this is its late answer, not an orphan
    assert [c for c, _ in notes(rsp)] == ["pair.late_response"]
    assert p.push(lone := frame(3, 1700, READ_RSP, CAN_RSP)) == [lone]  # answered once: another is an orphan
    assert [c for c, _ in notes(lone)] == ["pair.orphan_response"]


def test_end_of_capture_while_waiting():
    req = frame(0, 0, READ, CAN_REQ)
    out = run([req, noise(1, 2000)])
    assert [f.index for f in out] == [0, 1]
    assert notes(req) == [("pair.end_of_capture", "no response: end of capture")]  # not no_response


def test_broadcast_expects_no_answer():
    bc = frame(0, 0, "000600010055", BOTH)
    p = Pairer()
    assert p.push(bc) == [bc] and p.pending is None  # settled at once, not held
    assert bc.role == REQUEST and notes(bc) == [("pair.broadcast", "no response expected")]
    assert p.flush() == [] and [c for c, _ in notes(bc)] == ["pair.broadcast"]


def test_answer_to_a_broadcast_is_flagged():
    bc, echo = frame(0, 0, "000600010055", BOTH), frame(1, 5, "030600010055", BOTH)
    run([bc, echo])
    assert echo.role == RESPONSE and echo.pair is None
    assert notes(echo) == [("pair.broadcast_response", "unit 3 answered broadcast frame #0")]
    bc, exc = frame(0, 0, "001000010001020007", CAN_REQ), frame(1, 5, "039002", CAN_RSP)
    run([bc, exc])
    assert [c for c, _ in notes(exc)] == ["pair.broadcast_response"]


def test_orphan_response():
    lone = frame(0, 0, READ_RSP, CAN_RSP)
    run([lone])
    assert notes(lone) == [("pair.orphan_response", "nothing pending")]
    req, other, rsp = frame(0, 0, READ, CAN_REQ), frame(1, 3, "0203020007", CAN_RSP), frame(2, 6, READ_RSP, CAN_RSP)
    out = run([req, other, rsp])
    assert notes(other) == [("pair.orphan_response", "pending request #0 is for unit 1 function 0x03")]
    assert [f.index for f in out] == [0, 1, 2] and (req.pair, rsp.pair) == (2, 0)  # still waiting for unit 1


def test_late_response_is_paired_and_flagged():
    req, rsp = frame(0, 0, READ, CAN_REQ), frame(1, 1501, READ_RSP, CAN_RSP)  # no tick came between
    run([req, rsp])
    assert rsp.pair == 0 and rsp.latency_ms == 1500.0
    assert notes(rsp) == [("pair.late_response", "1500.0 ms after the request")]


def test_late_answer_after_the_next_request_pairs_with_the_request_it_answers():
    """The master gave up and sent its next request (another unit); the answer then comes alone: it is the
    late answer of the request it answers (unit, function, shape), not an orphan of the pending one."""
    a, b = frame(0, 0, READ, CAN_REQ), frame(1, 60, "0203000a0002", CAN_REQ)
    late, b_rsp = frame(2, 70, READ_RSP, CAN_RSP), frame(3, 75, "020304000100ff", CAN_RSP)
    out = run([a, b, late, b_rsp])
    assert [f.index for f in out] == [0, 1, 2, 3]
    assert late.pair == 0 and late.latency_ms == 69.0 and late.role == RESPONSE
    assert [c for c, _ in notes(late)] == ["pair.late_response"] and "#0" in notes(late)[0][1]
    assert (b.pair, b_rsp.pair) == (3, 1)  # the pending request still gets its own answer
    # too long after it (more than LATE_WINDOW timeouts): an orphan
    a, b, lone = frame(0, 0, READ, CAN_REQ), frame(1, 60, "0203000a0002", CAN_REQ), frame(2, 3500, READ_RSP, CAN_RSP)
    run([a, b, lone])
    assert lone.pair is None and [c for c, _ in notes(lone)] == ["pair.orphan_response"]


def test_an_answer_whose_shape_fits_an_earlier_request_is_that_ones_late_answer():
    """A second master's request (same unit and function, another quantity) came between a request and
    its answer: the byte count says which request the answer belongs to."""
    a = frame(0, 0, "010300000008", CAN_REQ)  # 8 registers
    c = frame(1, 3, READ, CAN_REQ)  # 2 registers, the other master
    ra = frame(2, 8, "010310" + "00" * 16, CAN_RSP)  # 16 bytes: answers a
    rc = frame(3, 14, READ_RSP, CAN_RSP)
    run([a, c, ra, rc])
    assert (ra.pair, rc.pair, c.pair) == (0, 1, 3)
    assert [code for code, _ in notes(ra)] == ["pair.late_response"] and "pair.mismatch" not in str(notes(rc))


def test_answer_with_its_address_cut_pairs_with_the_pending_request():
    """A transmitter that turns on late damages the first byte of its answers: a CRC-bad frame whose CRC
    holds with the pending request's unit in byte 0 is that request's (damaged) answer, not unit 129's."""
    req = frame(0, 0, "020300000002", CAN_REQ)
    good = bytes.fromhex("02030400010002")
    raw = bytes((0x81,)) + (good + crc_bytes(good))[1:]
    rsp = Frame(1, 5 * MS, 6 * MS, raw, "modbus-rtu", unit=0x81, function=3, role_fits=CAN_RSP, crc_ok=False)
    rsp.adu = raw[:-2]
    run([req, rsp])
    assert (req.pair, rsp.pair, rsp.role) == (1, 0, RESPONSE)
    assert "pair.orphan_response" not in [c for c, _ in notes(rsp)] and notes(req) == []


def test_a_crc_bad_burst_that_fits_no_length_is_never_a_request():
    """Two transmitters at once make a burst no length of its header explains: it is not a request of the
    unit its first byte names (the pending request keeps waiting for its answer)."""
    req = frame(0, 0, READ, CAN_REQ)
    burst = Frame(1, 3 * MS, 9 * MS, bytes.fromhex("0203ff00aa5512345678"), "modbus-rtu", unit=2, function=3,
                  role_fits=BOTH, crc_ok=False)
    burst.annotations.append(Annotation("modbus.length.mismatch", "error", "10 bytes do not fit function 0x03", 0, 10))
    rsp = frame(2, 12, READ_RSP, CAN_RSP)
    run([req, burst, rsp])
    assert burst.role == UNKNOWN and burst.pair is None
    assert (req.pair, rsp.pair) == (2, 0)
    # of the pending request's unit and function, it answers it only if it starts as its answer would: a damaged
    # repeat of the request (the master's retry, a stray byte glued on) does not
    req = frame(0, 0, READ, CAN_REQ)
    retry = Frame(1, 60 * MS, 65 * MS, bytes.fromhex(READ) + b"\x12\x34\x00", "modbus-rtu", unit=1, function=3,
                  role_fits=BOTH, crc_ok=False)
    retry.annotations.append(Annotation("modbus.length.mismatch", "error", "9 bytes do not fit function 0x03", 0, 9))
    answer = Frame(2, 70 * MS, 75 * MS, bytes.fromhex("01030400010002") + b"\x00\x00\x00", "modbus-rtu", unit=1,
                   function=3, role_fits=BOTH, crc_ok=False)
    answer.annotations.append(Annotation("modbus.length.mismatch", "error", "10 bytes do not fit", 0, 10))
    run([req, retry, answer])
    assert retry.role == UNKNOWN and (answer.role, answer.pair, req.pair) == (RESPONSE, 0, 2)


def test_a_copy_of_an_echo_request_is_the_masters_retry_when_its_timing_says_so():
    """_a_retry: a byte-for-byte copy of a pending 06 write, far later than the line's answers come, is the master's
    retry (the write unanswered), not the unit's echo; an echo as soon as the unit answers stays the echo, and so
    does a slow one (a write stored to EEPROM) well before the master's timer would run out."""
    write = "020620010007"
    frames, t = [], 0.0
    for _ in range(4):  # unit 1 answers its reads within 3 ms
        frames += [frame(len(frames), t, READ, CAN_REQ), frame(len(frames) + 1, t + 4, READ_RSP, CAN_RSP)]
        t += 50
    w0 = frame(len(frames), t, write, BOTH)
    w1 = frame(len(frames) + 1, t + 101, write, BOTH)  # unit 2 silent: the master's retry 100 ms later
    w2 = frame(len(frames) + 2, t + 202, write, BOTH)
    run(frames + [w0, w1, w2])
    assert w1.role == REQUEST and w1.pair is None and "pair.retry" in [c for c, _ in notes(w1)]
    assert "pair.no_response" in [c for c, _ in notes(w0)]
    assert any(c == "pair.role.ambiguous" and "master's retry of #" in d for c, d in notes(w1))
    assert w2.role == REQUEST and "pair.retry" in [c for c, _ in notes(w2)]

    frames, t = frames[:8], 200.0
    echo_req, echo = frame(8, t, write, BOTH), frame(9, t + 4, write, BOTH)  # answered at once
    run(frames + [echo_req, echo])
    assert echo.role == RESPONSE and echo.pair == 8

    # the master's timer known (it retried a read after 100 ms): a write echoed after 40 ms is still the echo
    p = Pairer()
    lost = [frame(8, 200, READ, CAN_REQ), frame(9, 301, READ, CAN_REQ), frame(10, 402, READ, CAN_REQ)]
    slow_req, slow = frame(11, 500, write, BOTH), frame(12, 541, write, BOTH)
    run(frames + lost + [slow_req, slow], p)
    assert len(p.waits) == 2 and slow.role == RESPONSE and slow.pair == 11
    # ... and one 100 ms later is its retry
    p = Pairer()
    late_req, retry = frame(11, 500, write, BOTH), frame(12, 601, write, BOTH)
    run(frames + lost + [late_req, retry], p)
    assert retry.role == REQUEST and "pair.retry" in [c for c, _ in notes(retry)]


def test_pair_mismatch_from_response_mismatch():
    req, rsp = frame(0, 0, READ, CAN_REQ), frame(1, 5, "0103020001", CAN_RSP)  # 2 registers asked, 1 sent
    run([req, rsp])
    assert rsp.pair == 0 and notes(rsp) == [("pair.mismatch", "byte count 2, expected 4 for 2 registers")]
    for bad in (dict(crc_ok=False), dict(protocol="pd-rtu")):  # only CRC-good Modbus pairs are compared
        req, rsp = frame(0, 0, READ, CAN_REQ), frame(1, 5, "0103020001", CAN_RSP, **bad)
        run([req, rsp])
        assert rsp.pair == 0 and [c for c, _ in notes(rsp)] == []


def test_response_mismatch_cases():
    assert response_mismatch(bytes.fromhex(READ), bytes.fromhex(READ_RSP)) is None
    assert response_mismatch(bytes.fromhex("010600010055"), bytes.fromhex("010600010056")) == (
        "response is not an echo of the request")
    assert response_mismatch(bytes.fromhex("011000010002"), bytes.fromhex("011000010003")) == (
        "response says address 1 x 3, request was 1 x 2")
    assert response_mismatch(bytes.fromhex("010100000009"), bytes.fromhex("01010101")) == (
        "byte count 1, expected 2 for 9 bits")
    assert response_mismatch(bytes.fromhex(READ), bytes.fromhex("0103")) == "response too short for its request"
    assert response_mismatch(b"", b"") is None and response_mismatch(b"\x01", bytes.fromhex(READ_RSP)) is None


def test_latency_unknown_for_a_response_read_with_its_request():
    req = frame(0, 0, READ, CAN_REQ, time_source="read")
    rsp = frame(1, 0.5, READ_RSP, CAN_RSP, time_source="read")  # estimated back to before the request's end
    run([req, rsp])
    assert rsp.pair == 0 and rsp.latency_ms is None


# ------------------------------------------------------------------ fuzz: frames
_frames = st.lists(st.tuples(
    st.sampled_from([*protocols.NAMES, "noise"]), st.one_of(st.none(), st.integers(0, 255)),
    st.one_of(st.none(), st.integers(0, 255)), st.integers(0, 7), st.binary(max_size=8),
    st.sampled_from([None, True, False]), st.integers(0, 1500), st.booleans(),
), min_size=1, max_size=30)


@settings(max_examples=300, deadline=None)
@given(_frames)
def test_pairer_never_raises_on_any_frame(specs):
    p, pushed, out, t = Pairer(timeout_ms=500), [], [], 0
    for i, (proto, unit, fc, can, adu, crc_ok, gap_ms, tick) in enumerate(specs):
        t += gap_ms * MS
        f = Frame(i, t, t + MS, adu + b"\0\0", proto, unit=unit, function=fc, role_fits=can, crc_ok=crc_ok)
        f.adu = adu
        pushed.append(f)
        out += p.push(f)
        if tick:
            out += p.tick(t + 2 * MS)
    out += p.flush()
    assert [f.index for f in out] == [f.index for f in pushed]  # each once, in capture order
    by_index = {f.index: f for f in out}
    for f in out:
        if f.pair is not None:
            assert by_index[f.pair].pair == f.index and f.role in (REQUEST, RESPONSE)
        if f.protocol == "noise" or f.function is None or f.unit is None or not f.role_fits & BOTH:
            assert f.pair is None and f.annotations == []


# ------------------------------------------------------------------ fuzz: bytes, every protocol
LINE = LineSettings(9600, "N", 1)
CODEBOOK = default_registry().codebook


def _crc_frame(unit: int, fc: int, body: bytes, pd: bool) -> bytes:
    head = bytes([unit, fc]) + (bytes([len(body)]) if pd else b"") + body
    return head + crc_bytes(head)


def _ascii_frame(unit: int, fc: int, body: bytes, pd: bool) -> bytes:
    adu = bytes([unit, fc]) + (bytes([len(body)]) if pd else b"") + body
    return b":" + (adu + bytes([lrc(adu)])).hex().upper().encode() + b"\r\n"


_header = (st.sampled_from([0, 1, 2, 3, 247, 250, 255]), st.sampled_from([1, 2, 3, 4, 5, 6, 8, 15, 16, 0x81, 0x83]),
           st.binary(max_size=10), st.booleans())
_piece = st.one_of(
    st.binary(min_size=1, max_size=30),
    st.text(":0123456789ABCDEFabcdef\r\nGYz ", min_size=1, max_size=40).map(str.encode),
    st.builds(_crc_frame, *_header),
    st.builds(_ascii_frame, *_header),
)
_gap_chars = st.one_of(st.just(0.0), st.floats(0.0, 1.4), st.floats(1.5, 3.4), st.floats(3.5, 40.0),
                       st.floats(60.0, 200.0))  # 60+ characters at 9600: past the PD quiet time


@st.composite
def _traffic(draw):
    """Per-byte times: runs separated by silences of any class."""
    data, times, t = bytearray(), [], 0
    for gap, piece in draw(st.lists(st.tuples(_gap_chars, _piece), min_size=1, max_size=12)):
        t += int(gap * LINE.char_ns)
        for b in piece:
            data.append(b)
            times.append(t)
            t += LINE.char_ns
    return bytes(data), times


def _pipe(protocol: str, events) -> list[Frame]:
    p = Pipeline(CaptureInfo(), LINE, default_registry(), protocol=protocol, timeout_ms=20)
    out = []
    for ev in events:
        out += p.feed(ev)
    return out + p.finish()


def _cut(data: bytes, times: list[int], cuts: list[int]) -> list[Chunk]:
    out, i, k = [], 0, 0
    while i < len(data):
        j = min(len(data), i + cuts[k % len(cuts)])
        out.append(Chunk(times[i], data[i:j], tuple(times[i:j])))
        i, k = j, k + 1
    return out


def _signature(frames):
    return [(f.raw, f.t_ns, f.protocol, f.role, f.pair, f.crc_ok, tuple(notes(f)), f.summary) for f in frames]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(protocols.NAMES), _traffic(), st.lists(st.integers(1, 25), min_size=1, max_size=6))
def test_every_protocol_any_bytes_conserved_and_any_chunking_same_frames(protocol, traffic, cuts):
    data, times = traffic
    whole = _pipe(protocol, [Chunk(times[0], data, tuple(times))])
    assert b"".join(f.raw for f in whole) == data
    assert [f.index for f in whole] == list(range(len(whole)))
    for f in whole:
        assert f.raw
        assert f.is_noise or (f.unit is not None and f.function is not None and f.role_fits & BOTH), f
        for a in f.annotations:
            assert 0 <= a.start < a.end <= len(f.raw), (a, f)
            assert a.code in CODEBOOK, a.code
            assert not a.detail.startswith("decoder "), a.detail  # the registry caught an exception
        frame_record(f, 0)
    assert _signature(_pipe(protocol, _cut(data, times, cuts))) == _signature(whole)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(protocols.NAMES), st.lists(_piece, min_size=1, max_size=12),
       st.lists(st.integers(1, 64), min_size=1, max_size=6))
def test_every_protocol_per_read_chunks_conserved(protocol, pieces, cuts):
    """USB-style reads (no per-byte times), ticks between some: no exception, every byte in one frame."""
    data = b"".join(pieces)
    events, t, i, k = [], 1_000_000, 0, 0
    while i < len(data):
        j = min(len(data), i + cuts[k % len(cuts)])
        gap = (k % 4) * 30 * MS
        if gap and k % 2:
            events.append(Tick(t + gap - MS))  # in the silence before the next read
        t += gap + (j - i) * LINE.char_ns
        events.append(Chunk(t, data[i:j]))
        i, k = j, k + 1
    frames = _pipe(protocol, events)
    assert b"".join(f.raw for f in frames) == data


def test_latency_is_kept_to_the_microsecond_the_record_holds():
    """A viewer rebuilding frames from records prints the same latency as the capture (no double rounding)."""
    from sniffer.formats.records import frame_record
    from sniffer.formats.text import frame_line
    from sniffer.tui.store import frame_from_record

    p = Pairer()
    req = Frame(0, 0, 1_000_000, bytes.fromhex("010300000001840a"), "modbus-rtu", 1, 3, role_fits=CAN_REQ)
    rsp = Frame(1, 1_000_000 + 1_049_510, 1_000_000 + 2_000_000, bytes.fromhex("0103020001"), "modbus-rtu", 1, 3,
                role_fits=CAN_RSP)
    p.push(req)
    p.push(rsp)
    assert rsp.latency_ms == 1.05  # 1.049510 ms, to the microsecond
    back = frame_from_record(frame_record(rsp, 0), 0)
    assert frame_line(back, 0) == frame_line(rsp, 0) and "1.1ms" in frame_line(rsp, 0)
