"""No summary, point, filter range, register write or export names a register past 65535, or a quantity
its function cannot carry, whatever a frame's fields say (CRC-bad junk, a device's bug).

A CRC-bad 8-byte burst `01 10 83 83 FF 2C ..` read as a write-multiple response was summarised
`wrote holding 33667..98990 (65324)`.
"""

from __future__ import annotations

import csv
import random
import re

import pytest
from helpers import bursts, run_events

from sniffer.framing.crc import crc_bytes
from sniffer.filterlang.facts import registers_of
from sniffer.line import LineSettings
from sniffer.protocols import MODBUS_MAX_QUANTITY

LINE = LineSettings(9600)


def rtu(h: str, good: bool = True) -> str:
    b = bytes.fromhex(h)
    return (b + (crc_bytes(b) if good else b"\x00\x00")).hex()


def problems(f) -> list[str]:
    """What a frame names that no register can be."""
    out = []
    # summaries: register numbers and counts are decimal (generic) or hex ending in H (models)
    for n in re.findall(r"(?<![\w.])(\d+)(?![\w.])", f.summary or ""):
        if int(n) > 0xFFFF:
            out.append(f"summary names {n}: {f.summary}")
    for h in re.findall(r"\b([0-9A-F]+)H\b", f.summary or ""):
        if int(h, 16) > 0xFFFF:
            out.append(f"summary names {h}H: {f.summary}")
    m = re.search(r"\((\d+)\)\s*$", f.summary or "")
    hi = MODBUS_MAX_QUANTITY.get(f.function or 0)
    if m and hi is not None and not 1 <= int(m.group(1)) <= hi:
        out.append(f"summary counts {m.group(1)}: {f.summary}")
    for p in f.points:
        a = p.get("address")
        if a is not None and not 0 <= a + len(p.get("words") or (0,)) - 1 <= 0xFFFF:
            out.append(f"point at {a}")
    for _table, lo, hi_ in registers_of(f):
        if not 0 <= lo < hi_ <= 0x10000:
            out.append(f"filter range {lo}..{hi_}")
    for _table, start, values in f.writes:
        if start + len(values) > 0x10000:
            out.append(f"shadow write {start}+{len(values)}")
    return out


def test_the_junk_write_response_of_the_report():
    got = run_events(bursts([rtu("01108383ff2c", good=False)], LINE), LINE)
    (f,) = got
    assert (f.function, f.role, f.crc_ok) == (0x10, "response", False)
    assert problems(f) == [] and "33667" in f.summary  # where it starts is what the bytes say
    assert any(a.code == "modbus.quantity.range" and "65324" in a.detail for a in f.annotations)


@pytest.mark.parametrize("hexbody, good", [
    ("0103fff00064", True),  # a read of 100 registers from 65520: past the end
    ("0103fff00064", False),
    ("0110fffa000a14" + "0001" * 10, False),  # ten values written from 65530
    ("0110fffa000a14" + "0001" * 10, True),
    ("010f0000ffff02ffff", False),  # 65535 coils: more than a 0FH carries
    ("01100000ff2c02ffff", True),
])
def test_fields_no_function_can_carry_name_no_registers(hexbody, good):
    frames = run_events(bursts([rtu(hexbody, good)], LINE), LINE)
    assert frames and all(problems(f) == [] for f in frames), [f.summary for f in frames]


@pytest.mark.parametrize("devices", [None, {1: "a510", 2: "tds-v8", 3: "spl"}])
def test_random_fields_through_every_decoder(devices):
    """Property: random address and quantity fields (and CRC-bad bodies) of every function that names
    registers, through the generic decoder and three models: nothing names a register that cannot be."""
    rnd = random.Random(23)
    frames_hex = []
    for _ in range(400):
        unit, fc = rnd.choice((1, 2, 3)), rnd.choice((0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F, 0x10, 0x17))
        a = rnd.choice((0, 0x2520, 0x8383, 0xFFF0, 0xFFFF, rnd.randrange(0x10000)))
        q = rnd.choice((0, 1, 2, 10, 125, 126, 2000, 0xFF2C, rnd.randrange(0x10000)))
        body = bytes([unit, fc]) + a.to_bytes(2, "big") + q.to_bytes(2, "big")
        if fc in (0x0F, 0x10):
            n = rnd.randrange(0, 40)
            body += bytes([n]) + rnd.randbytes(n)
        elif fc == 0x17:
            n = rnd.randrange(0, 20)
            body += rnd.randbytes(4) + bytes([n]) + rnd.randbytes(n)
        frames_hex.append(rtu(body.hex(), good=rnd.random() < 0.5))
        if rnd.random() < 0.5:  # an answer too: a read response of random length, or the echo
            k = rnd.randrange(0, 120)
            rsp = bytes([unit, fc]) + (bytes([k]) + rnd.randbytes(k) if fc <= 0x04 else body[2:6])
            frames_hex.append(rtu(rsp.hex(), good=rnd.random() < 0.7))
    frames = run_events(bursts(frames_hex, LINE, gap_chars=4), LINE, devices=devices)
    bad = [(f.summary, p) for f in frames for p in problems(f)]
    assert bad == []
    assert sum(f.crc_ok is False for f in frames) > 100 and sum(bool(f.points) for f in frames) > 50


def test_the_export_names_no_register_past_the_end(tmp_path):
    from helpers import export

    from sniffer.formats.bytecsv.reader import write_byte_csv

    frames_hex = [rtu("0110fffa000a14" + "0001" * 10, good=False), rtu("0110fffa000a", good=False),
                  rtu("01108383ff2c", good=False)]
    src = tmp_path / "junk.csv"
    write_byte_csv(str(src), bursts(frames_hex, LINE, gap_chars=20))
    out = tmp_path / "junk-out.csv"
    assert export(src, "csv", out, "--baud", "9600") == 0
    with open(out) as fh:
        summaries = [r["summary"] for r in csv.DictReader(fh)]
    with open(out.with_name("junk-out.points.csv")) as fh:
        addresses = [int(r["address"]) for r in csv.DictReader(fh) if r["address"]]
    assert len(summaries) == 3 and all(0 <= a <= 0xFFFF for a in addresses)
    assert not [n for s in summaries for n in re.findall(r"(?<![\w.])(\d+)(?![\w.])", s) if int(n) > 0xFFFF]
