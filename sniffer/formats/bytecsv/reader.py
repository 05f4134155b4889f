"""Byte CSV: `t_s,channel,byte_hex,flags`, one row per byte.

The format of sigrok's UART output in ../shared/refcaptures and of our own
CSV export.  If every byte has its own time, timestamps are per byte.  If
consecutive bytes of one channel share one `t_s` (a USB adapter delivering a
chunk), the whole file is taken as per-read: each run of equal times is one
read.  Rows are read as a stream (sniffer.formats.csvstream says what is
fatal and what is damage); a time must be a non-negative decimal number of
seconds, a byte two hex digits, a flag empty, `framing` or `parity`.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

from sniffer.events import FLAG_FRAMING, FLAG_PARITY, CaptureInfo, Chunk
from sniffer.events import CaptureError
from sniffer.formats.reading import quote
from sniffer.inputs import open_regular
from sniffer.formats.csvstream import PER_BYTE_CHUNK, CsvRowSource, Row, chunks_from_rows
from sniffer.formats.timeparse import seconds_to_ns

__all__ = ["HEADER", "PER_BYTE_CHUNK", "ByteCsvSource", "chunks_from_rows", "open_byte_csv", "sniff",
           "write_byte_csv"]

HEADER = ["t_s", "channel", "byte_hex", "flags"]
_FLAGS = {"": None, "framing": FLAG_FRAMING, "parity": FLAG_PARITY}
_BYTES = {form: v for v in range(256) for form in (f"{v:02x}", f"{v:02X}", f"{v:x}", f"{v:X}")}


def sniff(path: str | os.PathLike[str]) -> bool:
    try:
        with open_regular(path) as fh:
            first = fh.readline(4096).decode("utf-8").strip().lower()
    except (CaptureError, OSError, UnicodeDecodeError):
        return False
    return first.replace(" ", "").split(",")[:3] == HEADER[:3]


class ByteCsvSource(CsvRowSource):
    kind = "byte CSV"

    def parse_header(self, header: list[str]) -> None:
        if [h.replace(" ", "") for h in header[:3]] != HEADER[:3]:
            raise CaptureError(f"{self.path}: not a byte CSV (header must start with t_s,channel,byte_hex; "
                               f"found {quote(','.join(header))})")

    _last_time = ("", 0)  # rows of one read share their time text: parse it once

    def parse_row(self, row: list[str]) -> Row:
        text, t = self._last_time
        if row[0] != text:
            t = seconds_to_ns(row[0])
            if t < 0:
                raise ValueError("negative time")
            self._last_time = (row[0], t)
        b = _BYTES.get(row[2])
        if b is None:
            b = _BYTES.get(row[2].strip())
            if b is None:
                raise ValueError("the byte is not 00..ff")
        if len(row) == 4 and not row[3]:  # the common row: no flag
            return t, row[1].strip(), b, None
        flag_text = row[3] if len(row) > 3 else ""
        if flag_text not in _FLAGS:
            flag_text = flag_text.strip().lower()
            if flag_text not in _FLAGS:
                raise ValueError(f"unknown flag {quote(flag_text, 40)} (framing, parity or empty)")
        return t, row[1].strip(), b, _FLAGS[flag_text]

    def make_info(self) -> CaptureInfo:
        info = CaptureInfo(source=f"byte-csv:{self.path}", time_source="read" if self.per_read else "byte", t0_ns=0)
        info.extra["channels"] = sorted(self.channels)
        return info


def open_byte_csv(path: str | os.PathLike[str]) -> tuple[CaptureInfo, Iterator[Chunk]]:
    """(CaptureInfo, events) of a byte CSV.  What was skipped is only in ByteCsvSource.damage: use FileSource."""
    src = ByteCsvSource(path)
    return src.open(), src.events()


def write_byte_csv(path: str, chunks) -> int:
    """Write chunks as a byte CSV (per-read chunks share their read time). Returns rows written."""
    n = 0
    with open(path, "w", newline="", encoding="utf-8") as fh:
        fh.write("t_s,channel,byte_hex,flags\n")
        for ch in chunks:
            flags = dict(ch.flags)
            for k, b in enumerate(ch.data):
                t = ch.byte_t_ns[k] if ch.byte_t_ns is not None else ch.t_ns
                fh.write(f"{t // 1_000_000_000}.{t % 1_000_000_000:09d},{ch.channel},{b:02x},{flags.get(k, '')}\n")
                n += 1
    return n


SOURCE = ByteCsvSource  # what sniffer.formats.files makes of a file of this format
