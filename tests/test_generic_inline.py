"""The generic decoder reads the common function codes from the ADU in place: the same length rules
and values as the construct layouts of schema.py (the reference for every standard function)."""

from __future__ import annotations

import random

import pytest
from construct import ConstructError
from refdata import vector_rows

from decoders.base import UnitState
from decoders.generic import GenericModbus
from decoders.generic.schema import LAYOUTS
from helpers import bursts, run_events
from sniffer.frame import REQUEST, RESPONSE, Frame
from sniffer.line import LineSettings

HOT = [(fc, role) for fc in (0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F, 0x10) for role in (REQUEST, RESPONSE)]


def _construct(fc: int, role: str, body: bytes):
    """The construct layout's reading of a body (None where it does not fit)."""
    try:
        return LAYOUTS[fc, role].parse(body)
    except (ConstructError, ValueError, IndexError):
        return None


def _agrees(f: Frame, parsed, bits_wanted: int | None) -> None:
    """The decoder's reading of f (decoded) is the layout's `parsed` (None: the body is too short).

    bits_wanted: the bit count its request asked for (a bits response), None if not known."""
    fc, role = f.function, f.role
    short = any(a.code == "modbus.decode.short" for a in f.annotations)
    assert short == (parsed is None), (fc, role, f.adu.hex())
    if parsed is None:
        return
    if fc in (0x03, 0x04) and role == RESPONSE:
        assert [p["raw"] for p in f.points] == parsed["values"]
    elif fc in (0x01, 0x02) and role == RESPONSE:
        bits = [(parsed["status"][i >> 3] >> (i & 7)) & 1 for i in range(len(parsed["status"]) * 8)]
        assert [p["raw"] for p in f.points] == (bits[:bits_wanted] if bits_wanted is not None else
                                                  bits[:len(f.points)])
    elif fc == 0x10 and role == REQUEST:
        assert [p["raw"] for p in f.points] == parsed["values"]
        assert f.points[0]["address"] == parsed["address"] if f.points else True
    elif fc == 0x0F and role == REQUEST:
        vals = parsed["values"]
        n = min(parsed["quantity"], len(vals) * 8)
        assert [p["raw"] for p in f.points] == [(vals[i >> 3] >> (i & 7)) & 1 for i in range(n)]
    elif fc in (0x05, 0x06):
        assert f.points[0]["address"] == parsed["address"]
    else:  # "read holding 16..140 (125)", or where fields name no range "read holding from 16 (...)"
        words = f.summary.split()
        assert words[3 if words[2] == "from" else 2].startswith(str(parsed["address"]))


def _frame(adu: bytes, role: str, peer: Frame | None = None) -> Frame:
    f = Frame(0, 0, 1, adu + b"\x00\x00", "modbus-rtu", adu[0], adu[1], 3, True)
    f.adu, f.role, f.peer = adu, role, peer
    return f


def _bodies(rng: random.Random, n: int):
    for _ in range(n):
        size = rng.choice((0, 1, 2, 3, 4, 5, 6, 7, 9, 17, rng.randint(0, 260)))
        body = bytearray(rng.randint(0, 255) for _ in range(size))
        if size > 4 and rng.random() < 0.5:
            body[4] = rng.choice((0, 1, 2, 4, size - 5, size - 4))  # a write's byte count that may fit
        if size and rng.random() < 0.5:
            body[0] = rng.choice((0, 1, 2, size - 1, size))  # a response's byte count that may fit
        yield bytes(body)


@pytest.mark.parametrize(("fc", "role"), HOT, ids=[f"{fc:02x}-{r}" for fc, r in HOT])
def test_inline_reader_agrees_with_the_layouts_on_random_bodies(fc, role):
    rng = random.Random(fc * 7 + len(role))
    decoder, state = GenericModbus(), UnitState(1)
    request = _frame(bytes([1, fc, 0x00, 0x10, 0x00, 0x7D]), REQUEST)
    for body in _bodies(rng, 400):
        f = _frame(bytes([1, fc]) + body, role, request if role == RESPONSE else None)
        decoder.decode(f, f.peer, state)
        _agrees(f, _construct(fc, role, body), 0x7D)


def test_inline_reader_agrees_with_the_layouts_on_the_vectors():
    """minimalmodbus' request/response vectors, decoded by the pipeline (request context and all)."""
    line = LineSettings(19200)
    checked = 0
    for row in vector_rows():
        hexes = [row["request_hex"]] + ([row["response_hex"]] if row["response_hex"] else [])
        for f in run_events(bursts(hexes, line), line):
            if f.crc_ok and (f.function, f.role) in HOT:
                _agrees(f, _construct(f.function, f.role, f.raw[2:-2]), None)
                checked += 1
    assert checked > 150
