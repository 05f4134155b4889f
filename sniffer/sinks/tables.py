"""CSV and Parquet export: one row per frame, and one row per decoded point.

Column types are plain (int64, float64, bool, string, nullable) so DuckDB
(`SELECT * FROM 'x.parquet'`), pandas (`read_parquet`/`read_csv`) and a
spreadsheet read them without a schema.  `t` is seconds from capture start,
`t_wall` the wall-clock time (UTC, from the capture's anchor).
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import orjson

from ..events import CaptureInfo
from ..frame import Frame

FRAME_COLUMNS = [
    "index", "t", "t_end", "t_wall_ns", "protocol", "role", "unit", "function", "crc_ok", "exception_code",
    "model", "pair", "latency_ms", "n_points", "annotations", "summary", "raw", "channel", "time_source",
    "noise_reason",
]
POINT_COLUMNS = [
    "frame", "t", "unit", "function", "role", "model", "address", "name", "id", "raw", "value",
    "value_text", "eng_unit",
]


def points_path(out: str | os.PathLike[str], suffix: str) -> Path:
    p = Path(out)
    return p.with_name(p.stem + ".points" + suffix)


def frame_row(f: Frame, info: CaptureInfo) -> dict:
    return {
        "index": f.index,
        "t": (f.t_ns - info.t0_ns) / 1e9,
        "t_end": (f.t_end_ns - info.t0_ns) / 1e9,
        "t_wall_ns": info.wall_anchor_ns + (f.t_ns - info.t0_ns) if info.wall_anchor_ns else None,
        "protocol": f.protocol,
        "role": f.role,
        "unit": f.unit,
        "function": f.function,
        "crc_ok": f.crc_ok,
        "exception_code": (f.exception or {}).get("code"),
        "model": f.model,
        "pair": f.pair,
        "latency_ms": None if f.latency_ms is None else round(f.latency_ms, 3),
        "n_points": len(f.points),
        "annotations": " ".join(a.code for a in f.annotations),
        "summary": f.summary,
        "raw": f.raw.hex(),
        "channel": f.channel,
        "time_source": f.time_source,
        "noise_reason": f.noise_reason,
    }


def _num(v):
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, (int, float)):
        return float(v)
    return None


def _text(v) -> str | None:
    if v is None:
        return None
    if isinstance(v, str):
        return v
    if isinstance(v, (int, float, bool)):
        return str(v)
    return orjson.dumps(v).decode()


def point_rows(f: Frame, info: CaptureInfo) -> list[dict]:
    t = (f.t_ns - info.t0_ns) / 1e9
    rows = []
    for p in f.points:
        raw = p.get("raw")
        rows.append({
            "frame": f.index, "t": t, "unit": f.unit, "function": f.function, "role": f.role,
            "model": f.model, "address": p.get("address"), "name": p.get("name") or "",
            "id": p.get("id") or "",
            "raw": raw if isinstance(raw, int) and not isinstance(raw, bool) else None,
            "value": _num(p.get("value")),
            "value_text": p.get("text") or _text(p.get("value")),
            "eng_unit": p.get("unit"),
        })
    return rows


class CsvSink:
    """OUT.csv (frames) + OUT.points.csv (points); empty cells for None."""

    def __init__(self, out: str | os.PathLike[str]) -> None:
        self.path = Path(out)
        self.points_path = points_path(out, ".csv")
        self.info = CaptureInfo()
        self._ff = open(self.path, "w", newline="", encoding="utf-8")
        self._fp = open(self.points_path, "w", newline="", encoding="utf-8")
        self._wf = csv.DictWriter(self._ff, FRAME_COLUMNS)
        self._wp = csv.DictWriter(self._fp, POINT_COLUMNS)
        self.frames = 0

    def start(self, info: CaptureInfo) -> None:
        self.info = info
        self._wf.writeheader()
        self._wp.writeheader()

    def raw(self, event) -> None:
        pass

    def frame(self, f: Frame) -> None:
        self._wf.writerow(frame_row(f, self.info))
        self._wp.writerows(point_rows(f, self.info))
        self.frames += 1

    def close(self) -> None:
        self._ff.close()
        self._fp.close()


def _schemas():
    import pyarrow as pa

    frames = pa.schema([
        ("index", pa.int64()), ("t", pa.float64()), ("t_end", pa.float64()), ("t_wall_ns", pa.int64()),
        ("protocol", pa.string()), ("role", pa.string()), ("unit", pa.int64()), ("function", pa.int64()),
        ("crc_ok", pa.bool_()), ("exception_code", pa.int64()), ("model", pa.string()), ("pair", pa.int64()),
        ("latency_ms", pa.float64()), ("n_points", pa.int64()), ("annotations", pa.string()),
        ("summary", pa.string()), ("raw", pa.string()), ("channel", pa.string()),
        ("time_source", pa.string()), ("noise_reason", pa.string()),
    ])
    points = pa.schema([
        ("frame", pa.int64()), ("t", pa.float64()), ("unit", pa.int64()), ("function", pa.int64()),
        ("role", pa.string()), ("model", pa.string()), ("address", pa.int64()), ("name", pa.string()),
        ("id", pa.string()), ("raw", pa.int64()), ("value", pa.float64()), ("value_text", pa.string()),
        ("eng_unit", pa.string()),
    ])
    return frames, points


class ParquetSink:
    """OUT.parquet (frames) + OUT.points.parquet (points), written in row groups of `batch` rows."""

    def __init__(self, out: str | os.PathLike[str], batch: int = 50_000) -> None:
        import pyarrow.parquet as pq

        self.path = Path(out)
        self.points_path = points_path(out, ".parquet")
        self.info = CaptureInfo()
        self._fs, self._ps = _schemas()
        self._wf = pq.ParquetWriter(self.path, self._fs)
        self._wp = pq.ParquetWriter(self.points_path, self._ps)
        self._rf: list[dict] = []
        self._rp: list[dict] = []
        self.batch = batch
        self.frames = 0

    def start(self, info: CaptureInfo) -> None:
        self.info = info

    def raw(self, event) -> None:
        pass

    def frame(self, f: Frame) -> None:
        self._rf.append(frame_row(f, self.info))
        self._rp.extend(point_rows(f, self.info))
        self.frames += 1
        if len(self._rf) >= self.batch:
            self._flush()

    def _flush(self) -> None:
        import pyarrow as pa

        if self._rf:
            self._wf.write_table(pa.Table.from_pylist(self._rf, schema=self._fs))
        if self._rp:
            self._wp.write_table(pa.Table.from_pylist(self._rp, schema=self._ps))
        self._rf, self._rp = [], []

    def close(self) -> None:
        try:
            self._flush()
        finally:
            self._wf.close()
            self._wp.close()
