"""Saleae Logic async-serial CSV exports (Logic 2 and Logic 1.x).

Logic 2 analyzer export: `name,type,start_time,duration,data[,error]`, one
row per byte, data as `0x41`; rows of other types (e.g. errors of a frame)
are skipped unless they carry data.  Logic 1.x: `Time [s],Value,Parity
Error,Framing Error`.  Columns are found by name, values may be hex, decimal
or a quoted character (the display radix the user picked).  Times are the
start of each byte: per-byte timestamps.  Several analyzers in one export
(column `name`) become channels.

Rows are read as a stream (sniffer.formats.csvstream says what is fatal and
what is damage).  Times before the trigger are negative in a triggered
Logic 2 export: if the first row is before 0, every time is shifted so the
capture starts at 0 (info.extra["saleae_time_offset_ns"] says by how much).
"""

from __future__ import annotations

import csv
import os
from collections.abc import Iterator

from sniffer.events import FLAG_FRAMING, FLAG_PARITY, CaptureInfo, Chunk
from sniffer.events import CaptureError
from sniffer.formats.reading import quote
from sniffer.inputs import open_regular
from sniffer.formats.csvstream import CsvRowSource, Row
from sniffer.formats.timeparse import seconds_to_ns

_TIME = ("start_time", "time [s]", "time", "start time")
_DATA = ("data", "value")


def _find(header: list[str], names) -> int | None:
    for n in names:
        if n in header:
            return header.index(n)
    return None


def sniff(path: str | os.PathLike[str]) -> bool:
    try:
        with open_regular(path) as fh:
            first = fh.readline(4096).decode("utf-8-sig")
        header = [h.strip().lower() for h in next(csv.reader([first]), [])]
    except (CaptureError, OSError, UnicodeDecodeError, csv.Error):
        return False
    return _find(header, _TIME) is not None and _find(header, _DATA) is not None


def _value(text: str) -> int:
    t = text.strip().strip('"')
    if len(t) > 12:
        raise ValueError("the data is not one byte")
    if t.lower().startswith("0x"):
        v = int(t, 16)
    elif t.startswith("'") and t.endswith("'") and len(t) == 3:
        v = ord(t[1])
    elif t.isdigit():
        v = int(t)
    elif len(t) == 1:
        v = ord(t)
    else:
        raise ValueError("the data is not one byte")
    if not 0 <= v <= 255:
        raise ValueError("the data is not one byte")
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


class SaleaeSource(CsvRowSource):
    kind = "Saleae export"

    def parse_header(self, header: list[str]) -> None:
        self.header = header
        self.ti, self.di = _find(header, _TIME), _find(header, _DATA)
        if self.ti is None or self.di is None:
            raise CaptureError(f"{self.path}: not a Saleae async-serial export (no time/data columns; "
                               f"header {quote(','.join(header))})")
        self.ni = header.index("name") if "name" in header else None
        self.tyi = header.index("type") if "type" in header else None
        self.other = [k for k in range(len(header)) if k not in (self.ti, self.di)]

    def parse_row(self, row: list[str]) -> Row | None:
        if self.tyi is not None and self.tyi < len(row) and row[self.tyi].strip().lower() not in ("data", ""):
            return None
        if self.di >= len(row):
            raise IndexError  # a row cut short
        if not row[self.di].strip():
            return None
        t = seconds_to_ns(row[self.ti])
        b = _value(row[self.di])
        header = self.header
        extra = {header[k]: row[k] for k in self.other if k < len(row)}
        ch = row[self.ni].strip() if self.ni is not None and self.ni < len(row) else ""
        return t, ch, b, _flag(extra)

    def first_time_offset(self, t_first: int) -> int:
        return -t_first if t_first < 0 else 0

    def make_info(self) -> CaptureInfo:
        info = CaptureInfo(source=f"saleae-csv:{self.path}", time_source="read" if self.per_read else "byte", t0_ns=0)
        if self.t_offset:
            info.extra["saleae_time_offset_ns"] = self.t_offset
        return info


def open_saleae_csv(path: str | os.PathLike[str]) -> tuple[CaptureInfo, Iterator[Chunk]]:
    """(CaptureInfo, events) of a Saleae export.  What was skipped is only in SaleaeSource.damage."""
    src = SaleaeSource(path)
    return src.open(), src.events()


SOURCE = SaleaeSource  # what sniffer.formats.files makes of a file of this format
