"""Byte CSV: `t_s,channel,byte_hex,flags`, one row per byte.

The format of sigrok's UART output in ../shared/refcaptures and of our own
CSV export.  If every byte has its own time, timestamps are per byte.  If
consecutive bytes share one `t_s` (a USB adapter delivering a chunk), the
whole file is taken as per-read: each run of equal times is one read.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator

from ..events import FLAG_FRAMING, FLAG_PARITY, CaptureInfo, Chunk
from . import CaptureError
from .timeparse import seconds_to_ns

HEADER = ["t_s", "channel", "byte_hex", "flags"]
_FLAGS = {"": None, "framing": FLAG_FRAMING, "parity": FLAG_PARITY}
PER_BYTE_CHUNK = 4096


def sniff(path: str) -> bool:
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            first = fh.readline().strip().lower()
    except (OSError, UnicodeDecodeError):
        return False
    return first.replace(" ", "").split(",")[:3] == HEADER[:3]


def read_rows(path: str) -> list[tuple[int, str, int, str | None]]:
    rows = []
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh)
            header = [h.strip().lower() for h in next(reader, [])]
            if header[:3] != HEADER[:3]:
                raise CaptureError(f"{path}: not a byte CSV (header must start with t_s,channel,byte_hex)")
            for lineno, row in enumerate(reader, start=2):
                if not row or not "".join(row).strip():
                    continue
                try:
                    t = seconds_to_ns(row[0])
                    ch = row[1].strip()
                    b = int(row[2], 16)
                    if not 0 <= b <= 255:
                        raise ValueError
                    flag = _FLAGS[(row[3].strip().lower() if len(row) > 3 else "")]
                except (ValueError, IndexError, KeyError):
                    raise CaptureError(f"{path}:{lineno}: bad row {','.join(row)!r}") from None
                rows.append((t, ch, b, flag))
    except UnicodeDecodeError:
        raise CaptureError(f"{path}: not a text CSV file") from None
    except OSError as e:
        raise CaptureError(f"{path}: {e.strerror or e}") from None
    rows.sort(key=lambda r: r[0])  # two-channel captures: merge by time (stable)
    return rows


def chunks_from_rows(rows) -> tuple[str, list[Chunk]]:
    per_read = any(
        rows[i][0] == rows[i - 1][0] and rows[i][1] == rows[i - 1][1] for i in range(1, len(rows))
    )
    out: list[Chunk] = []
    i = 0
    n = len(rows)
    while i < n:
        j = i + 1
        if per_read:
            while j < n and rows[j][0] == rows[i][0] and rows[j][1] == rows[i][1]:
                j += 1
        else:
            while j < n and j - i < PER_BYTE_CHUNK and rows[j][1] == rows[i][1]:
                j += 1
        part = rows[i:j]
        data = bytes(r[2] for r in part)
        flags = tuple((k, r[3]) for k, r in enumerate(part) if r[3])
        if per_read:
            out.append(Chunk(part[0][0], data, None, flags, part[0][1]))
        else:
            out.append(Chunk(part[0][0], data, tuple(r[0] for r in part), flags, part[0][1]))
        i = j
    return ("read" if per_read else "byte"), out


def open_byte_csv(path: str) -> tuple[CaptureInfo, Iterator[Chunk]]:
    rows = read_rows(path)
    time_source, chunks = chunks_from_rows(rows)
    info = CaptureInfo(source=f"byte-csv:{path}", time_source=time_source, t0_ns=0)
    info.extra["channels"] = sorted({r[1] for r in rows})
    return info, iter(chunks)


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
