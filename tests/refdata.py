"""Load the outside reference data copied into captures/refcaptures (never ../shared)."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

from sniffer.line import LineSettings

ROOT = Path(__file__).resolve().parent.parent
REF = ROOT / "captures" / "refcaptures"
SIGROK = REF / "sigrok"
VECTORS = REF / "vectors" / "minimalmodbus_rtu_request_response.csv"
SIGROK_NAMES = sorted(p.name[: -len(".bytes.csv")] for p in SIGROK.glob("*.bytes.csv"))

_ANN = re.compile(r'^(\d+)-(\d+) modbus: ([a-z-]+): "(.*)"$')


def sigrok_meta(name: str) -> dict:
    return json.loads((SIGROK / f"{name}.json").read_text())


def sigrok_line(name: str) -> LineSettings:
    m = sigrok_meta(name)
    parity = {"none": "N", "even": "E", "odd": "O"}[m["parity"]]
    return LineSettings(m["baud"], parity, m["stop_bits"])


def sigrok_byte_starts(name: str) -> list[int]:
    """Start sample of every UART byte, in time order (the order our source merges them)."""
    rate = sigrok_meta(name)["samplerate"]
    rows = list(csv.DictReader(open(SIGROK / f"{name}.bytes.csv")))
    times = sorted(round(float(r["t_s"]) * rate) for r in rows)
    return times


def sigrok_crc_correct_frames(name: str) -> dict[tuple[int, int], set[str]]:
    """{(first byte index, last byte index): {roles whose parse says 'CRC correct'}}.

    An ADU starts at a `*-server-id` annotation and a `*-crc` "CRC correct"
    closes it; cs = request (client -> server), sc = response.
    """
    starts = sigrok_byte_starts(name)
    meta = sigrok_meta(name)
    char = meta["samplerate"] * 11 // meta["baud"]

    def byte_at(sample: int) -> int:
        best = None
        for i, s in enumerate(starts):
            if s <= sample < s + char:
                best = i
        if best is None:
            raise AssertionError(f"no byte under sample {sample}")
        return best

    open_adu: dict[str, int] = {}
    out: dict[tuple[int, int], set[str]] = {}
    for line in (SIGROK / f"{name}.sigrok-modbus.txt").read_text().splitlines():
        m = _ANN.match(line)
        if not m:
            continue
        ss, es, cls, text = int(m[1]), int(m[2]), m[3], m[4]
        side = cls[:2]
        if cls.endswith("server-id"):
            open_adu[side] = ss
        elif cls.endswith("-crc") and text == "CRC correct" and side in open_adu:
            key = (byte_at(open_adu[side]), byte_at(es - 1))
            out.setdefault(key, set()).add("request" if side == "cs" else "response")
    return out


def vector_rows() -> list[dict]:
    return list(csv.DictReader(open(VECTORS)))
