"""Hypothesis fuzzing of every decoder: no exception on any bytes, spans inside, codes declared.

Decoders are called directly (not through the registry, whose safety net
would hide a crash as an annotation).
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.base import UnitState
from decoders.registry import builtin_decoders, default_registry
from sniffer.crc import crc_bytes
from sniffer.frame import CAN_REQ, CAN_RSP, REQUEST, RESPONSE, Frame

DECODERS = builtin_decoders()
CODEBOOK = default_registry().codebook
FCS = [1, 2, 3, 4, 5, 6, 7, 8, 0x0B, 0x0C, 0x0F, 0x10, 0x11, 0x14, 0x15, 0x16, 0x17, 0x18, 0x2B, 0x41,
       0x81, 0x83, 0x86, 0x90, 0xAB]


def _frame(adu: bytes, role: str, index: int) -> Frame:
    raw = adu + crc_bytes(adu)
    f = Frame(index, 0, 1, raw, "modbus-rtu", unit=adu[0], function=adu[1], can=CAN_REQ | CAN_RSP, crc_ok=True)
    f.adu = adu
    f.role = role
    return f


adus = st.builds(lambda u, fc, body: bytes([u, fc]) + body,
                 st.integers(0, 247), st.sampled_from(FCS), st.binary(max_size=40))


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(sorted(DECODERS)), adus, adus, st.booleans())
def test_any_bytes_decode_without_exception(model, req_adu, rsp_adu, with_request):
    dec = DECODERS[model]
    state = UnitState(req_adu[0])
    # a shadow that makes scaled registers resolve, sometimes
    state.holding.update({0x0301: 600, 0x2524: 5000})
    req = _frame(req_adu, REQUEST, 0)
    dec.decode(req, None, state)
    rsp = _frame(rsp_adu, RESPONSE, 1)
    dec.decode(rsp, req if with_request else None, state)
    for f in (req, rsp):
        for a in f.annotations:
            assert 0 <= a.start < a.end <= len(f.raw), (model, a, f.raw.hex())
            assert a.code in CODEBOOK, a.code
        for p in f.points:
            assert {"name", "address", "raw", "value", "unit"} <= p.keys()
