"""Parquet export: OUT.parquet (frames) + OUT.points.parquet (points), written row group by row group.

Rows (rows.py) wait in a batch of at most `batch` rows per table, then become one
row group: memory stays flat however long the capture is.
"""

from __future__ import annotations

from ..events import CaptureInfo
from ..frame import Frame
from .base import Sink
from .rows import FRAME_COLUMNS, POINT_COLUMNS, frame_row, point_rows

BATCH = 32_768


def schemas():
    import pyarrow as pa

    i, f, s, b = pa.int64(), pa.float64(), pa.string(), pa.bool_()
    frames = pa.schema(list(zip(FRAME_COLUMNS, (
        i, f, f, i, s, s, i, i, b, i, s, i, f, i, s, s, s, s, s, s,
    ))))
    points = pa.schema(list(zip(POINT_COLUMNS, (i, f, i, i, s, b, s, i, s, s, i, f, s, s))))
    return frames, points


class ParquetSink(Sink):
    def __init__(self, frames_path: str, points_path: str, batch: int = BATCH) -> None:
        import pyarrow.parquet as pq

        self._fs, self._ps = schemas()
        self._wf = pq.ParquetWriter(frames_path, self._fs)
        try:
            self._wp = pq.ParquetWriter(points_path, self._ps)
        except BaseException:
            self._wf.close()
            raise
        self._rf: list[tuple] = []
        self._rp: list[tuple] = []
        self.batch = batch
        self._t0 = 0
        self._anchor = 0
        self.frames = 0

    def start(self, info: CaptureInfo) -> None:
        self._t0, self._anchor = info.t0_ns, info.wall_anchor_ns

    def frame(self, f: Frame) -> None:
        self._rf.append(frame_row(f, self._t0, self._anchor))
        if f.points:
            self._rp.extend(point_rows(f, self._t0))
        self.frames += 1
        if len(self._rf) >= self.batch:
            self._write(self._wf, self._fs, self._rf)
            self._rf = []
        if len(self._rp) >= self.batch:
            self._write(self._wp, self._ps, self._rp)
            self._rp = []

    @staticmethod
    def _write(writer, schema, rows: list[tuple]) -> None:
        import pyarrow as pa

        cols = [pa.array(col, type=field.type) for col, field in zip(zip(*rows), schema)]
        writer.write_table(pa.Table.from_arrays(cols, schema=schema))

    def close(self) -> None:
        try:
            if self._rf:
                self._write(self._wf, self._fs, self._rf)
            if self._rp:
                self._write(self._wp, self._ps, self._rp)
            self._rf, self._rp = [], []
        finally:
            self._wf.close()
            self._wp.close()
