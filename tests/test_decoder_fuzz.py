"""Hypothesis fuzzing of every decoder: no exception on any bytes, spans inside, codes declared,
and the writes a frame records are exactly what it did to the register shadow.

Decoders are called directly (not through the registry, whose safety net
would hide a crash as an annotation).
"""

from __future__ import annotations

from hypothesis import event, given, settings
from hypothesis import strategies as st
from struct import pack

from decoders.base import UnitState
from decoders.registry import builtin_decoders, default_registry
from sniffer.framing.crc import crc_bytes
from sniffer.frame import CAN_REQ, CAN_RSP, REQUEST, RESPONSE, Frame
from sniffer.protocols import TABLES

DECODERS = builtin_decoders()
CODEBOOK = default_registry().codebook
FCS = [1, 2, 3, 4, 5, 6, 7, 8, 0x0B, 0x0C, 0x0F, 0x10, 0x11, 0x14, 0x15, 0x16, 0x17, 0x18, 0x2B, 0x41,
       0x81, 0x83, 0x86, 0x90, 0xAB]


def _frame(adu: bytes, role: str, index: int, crc_ok: bool = True) -> Frame:
    raw = adu + crc_bytes(adu)
    f = Frame(index, 0, 1, raw, "modbus-rtu", unit=adu[0], function=adu[1], role_fits=CAN_REQ | CAN_RSP, crc_ok=crc_ok)
    f.adu = adu
    f.role = role
    return f


adus = st.builds(lambda u, fc, body: bytes([u, fc]) + body,
                 st.integers(0, 247), st.sampled_from(FCS), st.binary(max_size=40))
ADDRESSES = st.one_of(st.sampled_from([0x0000, 0x0020, 0x0301, 0x2500, 0x2501, 0x2520, 0x2524]),
                      st.integers(0, 0xFF00))


@st.composite
def transactions(draw):
    """A request and a response that fit each other (Modbus, and the PD-series' 01H/02H/04H)."""
    u = draw(st.sampled_from([0, 1, 2]))
    fc = draw(st.sampled_from([1, 2, 3, 4, 5, 6, 0x0F, 0x10, 0x16, 0x17, "pd1", "pd2", "pd4"]))
    a, q = draw(ADDRESSES), draw(st.integers(1, 20))

    def data(n):
        return draw(st.binary(min_size=n, max_size=n))

    if fc in (1, 2):
        return pack(">BBHH", u, fc, a, q), bytes([u, fc, (q + 7) // 8]) + data((q + 7) // 8)
    if fc in (3, 4):
        return pack(">BBHH", u, fc, a, q), bytes([u, fc, 2 * q]) + data(2 * q)
    if fc in (5, 6, 0x16):
        req = pack(">BBH", u, fc, a) + data(2 if fc != 0x16 else 4)
        return req, req
    if fc == 0x0F:
        return pack(">BBHHB", u, fc, a, q, (q + 7) // 8) + data((q + 7) // 8), pack(">BBHH", u, fc, a, q)
    if fc == 0x10:
        return pack(">BBHHB", u, fc, a, q, 2 * q) + data(2 * q), pack(">BBHH", u, fc, a, q)
    if fc == 0x17:
        wa, wq = draw(ADDRESSES), draw(st.integers(1, 10))
        return (pack(">BBHHHHB", u, fc, a, q, wa, wq, 2 * wq) + data(2 * wq),
                bytes([u, fc, 2 * q]) + data(2 * q))
    p = draw(st.sampled_from([3, 165, 172, 200]))
    if fc == "pd1":
        return bytes([u, 1, 1, p]), bytes([u, 1, 3, p]) + data(2)
    if fc == "pd2":
        req = bytes([u, 2, 3, p]) + data(2)
        return req, req
    cfg = draw(st.integers(0, 9))
    return bytes([u, 4, 1, cfg]), bytes([u, 4, 3, cfg]) + data(2)



def _applied(before: dict, writes: list) -> dict:
    out = dict(before)
    for table, start, values in writes:
        assert table in TABLES and isinstance(start, int) and values, (table, start, values)
        for i, v in enumerate(values):
            out[(table, start + i)] = v
    return out


MOSTLY = st.sampled_from([True, True, True, False])


@settings(max_examples=500, deadline=None)
@given(st.sampled_from(sorted(DECODERS)), st.one_of(transactions(), st.tuples(adus, adus)), MOSTLY, MOSTLY, MOSTLY)
def test_any_bytes_decode_without_exception(model, adu_pair, with_request, req_crc, rsp_crc):
    req_adu, rsp_adu = adu_pair
    dec = DECODERS[model]
    state = UnitState(req_adu[0])
    # a shadow that makes scaled registers resolve, sometimes
    state.holding.update({0x0301: 600, 0x2524: 5000})
    before = state.snapshot()
    req = _frame(req_adu, REQUEST, 0, req_crc)
    dec.decode(req, None, state)
    assert state.snapshot() == _applied(before, req.writes)  # the frame records what it did to the shadow
    before = state.snapshot()
    rsp = _frame(rsp_adu, RESPONSE, 1, rsp_crc)
    dec.decode(rsp, req if with_request else None, state)
    assert state.snapshot() == _applied(before, rsp.writes)
    event(f"writes on the request: {bool(req.writes)}, on the response: {bool(rsp.writes)}")
    for f in (req, rsp):
        for a in f.annotations:
            assert 0 <= a.start < a.end <= len(f.raw), (model, a, f.raw.hex())
            assert a.code in CODEBOOK, a.code
        for p in f.points:
            assert {"name", "address", "raw", "value", "unit", "span"} <= p.keys()
            s, e = p["span"]
            assert 0 <= s < e <= len(f.raw) - 2, (model, p, f.raw.hex())  # inside the ADU, before the CRC
        if not f.crc_ok or f.exception:
            assert f.writes == [], (model, f.raw.hex(), f.writes)
