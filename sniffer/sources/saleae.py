"""Saleae Logic async-serial CSV exports (Logic 2 and Logic 1.x).

Logic 2 analyzer export: `name,type,start_time,duration,data[,error]`, one
row per byte, data as `0x41`; rows of other types (e.g. errors of a frame)
are skipped unless they carry data.  Logic 1.x: `Time [s],Value,Parity
Error,Framing Error`.  Columns are found by name, values may be hex, decimal
or a quoted character (the display radix the user picked).  Times are the
start of each byte: per-byte timestamps.  Several analyzers in one export
(column `name`) become channels.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator

from ..events import FLAG_FRAMING, FLAG_PARITY, CaptureInfo, Chunk
from . import CaptureError
from .bytecsv import chunks_from_rows
from .timeparse import seconds_to_ns

_TIME = ("start_time", "time [s]", "time", "start time")
_DATA = ("data", "value")


def _find(header: list[str], names) -> int | None:
    for n in names:
        if n in header:
            return header.index(n)
    return None


def sniff(path: str) -> bool:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            header = [h.strip().lower() for h in next(csv.reader(fh), [])]
    except (OSError, UnicodeDecodeError, csv.Error):
        return False
    return _find(header, _TIME) is not None and _find(header, _DATA) is not None


def _value(text: str) -> int:
    t = text.strip().strip('"')
    if t.lower().startswith("0x"):
        v = int(t, 16)
    elif t.startswith("'") and t.endswith("'") and len(t) == 3:
        v = ord(t[1])
    elif t.isdigit():
        v = int(t)
    elif len(t) == 1:
        v = ord(t)
    else:
        raise ValueError(t)
    if not 0 <= v <= 255:
        raise ValueError(t)
    return v


def _flag(row: dict) -> str | None:
    for key, val in row.items():
        v = (val or "").strip().lower()
        if not v or "error" not in key and key != "error":
            continue
        if "parity" in key or "parity" in v:
            return FLAG_PARITY
        return FLAG_FRAMING
    return None


def open_saleae_csv(path: str) -> tuple[CaptureInfo, Iterator[Chunk]]:
    rows = []
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = [h.strip().lower() for h in next(reader, [])]
            ti, di = _find(header, _TIME), _find(header, _DATA)
            if ti is None or di is None:
                raise CaptureError(f"{path}: not a Saleae async-serial export (no time/data columns)")
            ni = header.index("name") if "name" in header else None
            tyi = header.index("type") if "type" in header else None
            for lineno, row in enumerate(reader, start=2):
                if not row or not "".join(row).strip():
                    continue
                if tyi is not None and row[tyi].strip().lower() not in ("data", ""):
                    continue
                if di >= len(row) or not row[di].strip():
                    continue
                try:
                    t = seconds_to_ns(row[ti])
                    b = _value(row[di])
                except (ValueError, IndexError):
                    raise CaptureError(f"{path}:{lineno}: bad row {','.join(row)!r}") from None
                extra = {header[k]: row[k] for k in range(min(len(header), len(row))) if k not in (ti, di)}
                ch = row[ni].strip() if ni is not None else ""
                rows.append((t, ch, b, _flag(extra)))
    except UnicodeDecodeError:
        raise CaptureError(f"{path}: not a text CSV file") from None
    except OSError as e:
        raise CaptureError(f"{path}: {e.strerror or e}") from None
    if not rows:
        raise CaptureError(f"{path}: no serial bytes in this export")
    rows.sort(key=lambda r: r[0])
    time_source, chunks = chunks_from_rows(rows)
    info = CaptureInfo(source=f"saleae-csv:{path}", time_source=time_source, t0_ns=0)
    return info, iter(chunks)
