"""What the CSV and Parquet exports share: rows (rows.py) gathered a few thousand at a time.

A table sink keeps at most CONVERT rows of each table (frames, points) as
Python tuples and hands them to its writer (`_put`): memory stays flat however
long the capture is.  The CSV writer turns them into text itself (csvexport.py:
no pyarrow in the core install); the Parquet writers make one Arrow record
batch of them (`to_batch`), and Arrow (C++) writes it.  Arrays and writers use
the system allocator (`arrow_pool`, malloc): measured 121 against 134 MB peak RSS
exporting 256k frames with Arrow's default pool.
"""

from __future__ import annotations

from sniffer.events import CaptureInfo
from sniffer.frame import Frame
from sniffer.sinks.base import Sink
from sniffer.formats.rows import frame_row, point_rows

CONVERT = 4_096  # rows held as Python tuples before they go to the writer


def schemas():
    """Arrow schemas of the frames and points tables (sniffer.formats.schemas)."""
    from sniffer.formats.schemas import export_schemas

    return export_schemas()


def arrow_pool():
    """Arrow's system memory pool (malloc), which the Parquet writers allocate from."""
    import pyarrow as pa

    return pa.system_memory_pool()


def to_batch(rows: list, schema, pool):
    """Row tuples (in the schema's column order) -> one Arrow record batch (the columns transposed)."""
    import pyarrow as pa

    cols = [pa.array(col, type=field.type, memory_pool=pool) for col, field in zip(zip(*rows), schema)]
    return pa.RecordBatch.from_arrays(cols, schema=schema)


class TableSink(Sink):
    """Frames and points as lists of row tuples; subclasses say where the rows go (`_put`)."""

    def __init__(self) -> None:
        self._rows: tuple[list, list] = ([], [])
        self._t0 = 0
        self._anchor = 0
        self.frames = 0

    def start(self, info: CaptureInfo) -> None:
        self._t0, self._anchor = info.t0_ns, info.wall_anchor_ns

    def frame(self, f: Frame) -> None:
        rf, rp = self._rows
        rf.append(frame_row(f, self._t0, self._anchor))
        if f.points:
            rp.extend(point_rows(f, self._t0))
        self.frames += 1
        if len(rf) >= CONVERT:
            self._convert(0)
        if len(rp) >= CONVERT:
            self._convert(1)

    def _convert(self, table: int) -> None:
        """The waiting rows of table 0 (frames) or 1 (points) -> `_put`."""
        rows = self._rows[table]
        if not rows:
            return
        try:
            self._put(table, rows)
        finally:
            rows.clear()

    def _put(self, table: int, rows: list) -> None:  # pragma: no cover - subclasses write
        raise NotImplementedError

    def _end(self) -> None:
        """Called by close() after the last rows were written: finish the files."""

    def close(self) -> None:
        try:
            self._convert(0)
            self._convert(1)
        finally:
            self._end()
