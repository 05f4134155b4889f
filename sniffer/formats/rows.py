"""Rows of the CSV and Parquet exports: one per frame, one per decoded point.

Column types are plain (int64, float64, bool, string, nullable) so DuckDB
(`SELECT * FROM 'x.parquet'`), pandas (`read_parquet`/`read_csv`) and a
spreadsheet read them without a schema.  `t` is seconds from capture start,
`t_wall_ns` the wall-clock time (Unix ns, from the capture's anchor).

A point comes with its frame's `crc_ok` and `role`: values decoded from a
frame whose CRC failed are shown (they are what the line carried) but are not
the device's values; filter on `crc_ok` before aggregating
(`SELECT max(value) FROM pts WHERE crc_ok`).  Rows are tuples in column order:
the writers transpose batches of them.

A value of several registers (decoders/regtypes.py) is one point row: `raw` its
registers joined (a float's bit pattern; null where it does not fit int64, a u64
from 2**63 on, or is text), `value` the number as float64 (a 64-bit integer
beyond 2**53 is rounded there), `value_text` the exact number or the string.

`link` (last in both tables) is the frame's link in a capture of several links
(a unit is a unit of its link: group by link and unit), null for one line.

An annotation row (the fleet dataset's third table) is one annotation of a frame: its code,
severity, detail and byte span, with the frame's number, time, unit, function, role and model.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import msgspec

from sniffer.frame import Frame
from sniffer.hot import HOT

# Every column with its type, in row order: "int" (int64), "float" (float64), "str", "bool"; all nullable.
# The Arrow schemas (schemas.py) and the CSV writer (csvexport.py) are made from these.
FRAMES = (
    ("index", "int"), ("t", "float"), ("t_end", "float"), ("t_wall_ns", "int"), ("protocol", "str"),
    ("role", "str"), ("unit", "int"), ("function", "int"), ("crc_ok", "bool"), ("exception_code", "int"),
    ("model", "str"), ("pair", "int"), ("latency_ms", "float"), ("n_points", "int"), ("annotations", "str"),
    ("summary", "str"), ("raw", "str"), ("channel", "str"), ("time_source", "str"), ("noise_reason", "str"),
    ("link", "str"),
)
POINTS = (
    ("frame", "int"), ("t", "float"), ("unit", "int"), ("function", "int"), ("role", "str"), ("crc_ok", "bool"),
    ("model", "str"), ("address", "int"), ("name", "str"), ("id", "str"), ("raw", "int"), ("value", "float"),
    ("value_text", "str"), ("eng_unit", "str"), ("link", "str"),
)
ANNOTATIONS = (
    ("frame", "int"), ("t", "float"), ("unit", "int"), ("function", "int"), ("role", "str"), ("crc_ok", "bool"),
    ("model", "str"), ("code", "str"), ("severity", "str"), ("detail", "str"), ("span_start", "int"),
    ("span_end", "int"),
)
FRAME_COLUMNS = tuple(name for name, _ in FRAMES)
POINT_COLUMNS = tuple(name for name, _ in POINTS)
ANNOTATION_COLUMNS = tuple(name for name, _ in ANNOTATIONS)


def points_path(out: str | PathLike[str], suffix: str) -> Path:
    """OUT.csv -> OUT.points.csv (the second table of an export)."""
    p = Path(out)
    return p.with_name(p.stem + ".points" + suffix)


def frame_row(f: Frame, t0_ns: int, anchor_ns: int) -> tuple:
    lat = f.latency_ms
    exc = f.exception
    return (
        f.index, (f.t_ns - t0_ns) / 1e9, (f.t_end_ns - t0_ns) / 1e9,
        anchor_ns + (f.t_ns - t0_ns) if anchor_ns else None,
        f.protocol, f.role, f.unit, f.function, f.crc_ok, exc.get("code") if exc else None,
        f.model, f.pair, None if lat is None else round(lat, 3), len(f.points),
        " ".join([a.code for a in f.annotations]), f.summary, f.raw.hex(), f.channel, f.time_source,
        f.noise_reason, f.link or None,
    )


_INT64_MAX = (1 << 63) - 1


def _num(v):
    """A point's value as a number column: numbers (and bits) as float, anything else null."""
    t = type(v)
    if t is int or t is float or t is bool:
        return float(v)
    return None


def _text(v) -> str | None:
    if v is None:
        return None
    if isinstance(v, str):
        return v
    if isinstance(v, (int, float, bool)):
        return str(v)
    return msgspec.json.encode(v).decode()


# the rows of a frame's points built in C (sniffer/_hot.c point_rows); None: by point_rows_py, the reference
_POINT_ROWS = None if HOT is None else HOT.point_rows


def point_rows(f: Frame, t0_ns: int) -> list[tuple]:
    pts = f.points
    if not pts:
        return []
    t = (f.t_ns - t0_ns) / 1e9
    head = (f.index, t, f.unit, f.function, f.role, f.crc_ok, f.model)
    link = f.link or None
    if _POINT_ROWS is not None and type(pts) is list:
        rows = _POINT_ROWS(pts, head, link, _text)
        if rows is not None:  # None: a point that is not a plain dict
            return rows
    return point_rows_py(pts, head, link)


def point_rows_py(pts: list, head: tuple, link: str | None) -> list[tuple]:
    """point_rows' loop in Python: the reference (a row a point: its frame's `head`, its own cells, `link`)."""
    rows = []
    for p in pts:
        raw = p.get("raw")
        v = p.get("value")
        rows.append(head + (
            p.get("address"), p.get("name") or "", p.get("id") or "",
            raw if type(raw) is int and raw <= _INT64_MAX else None, _num(v), p.get("text") or _text(v),
            p.get("unit"), link,
        ))
    return rows


def annotation_rows(f: Frame, t0_ns: int) -> list[tuple]:
    anns = f.annotations
    if not anns:
        return []
    head = (f.index, (f.t_ns - t0_ns) / 1e9, f.unit, f.function, f.role, f.crc_ok, f.model)
    return [head + a for a in anns]  # an Annotation is a tuple: code, severity, detail, start, end
