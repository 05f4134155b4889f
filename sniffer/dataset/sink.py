"""The fleet dataset's sink: a capture's frames, points and annotations as hive-partitioned Parquet.

    sink = DatasetSink("DIR/_staging/line3-0a1b2c3d4e5f.1234", "line3-0a1b2c3d4e5f", link=None)

Each frame goes to its partition (its link: the frame's own in a capture of several links,
else the capture's, sniffer.dataset.layout.link_name; its UTC date), and within it to one
file per table, `TABLE/link=L/date=D/CAPTURE.parquet` under the staging folder; the command
moves the files into the dataset when the capture was read whole (sniffer.dataset.ingest).
Rows are those of the export (rows.py, the batches of tables.py), row groups those of the
Parquet export (parquet.RowGroupFile): memory is a few thousand rows per open partition,
however long the capture.  Every file's metadata says the schema version and the capture, and
`sniffer.decoder_state` what the decoders knew when its partition began (decoders/carry.py: the
state a replay of the capture from there needs to scale and name its values as here).
"""

from __future__ import annotations

import os

import msgspec

from decoders.carry import KEY

from sniffer.events import CaptureInfo
from sniffer.frame import Frame
from sniffer.formats.outputs import make_folders
from sniffer.formats.parquet import BATCH, RowGroupFile
from sniffer.formats.rows import annotation_rows, frame_row, point_rows
from sniffer.formats.schemas import DATASET_TABLES, SCHEMA_VERSION, dataset_bases, dataset_schemas
from sniffer.formats.tables import CONVERT, TableSink, arrow_pool, to_batch

NS = 1_000_000_000


def encodings(schema) -> dict:
    """How a dataset file is encoded: zstd; numbers by their shape rather than by dictionary.

    Times and counters rise by small steps (DELTA_BINARY_PACKED), floats compress once their bytes
    are split by position (BYTE_STREAM_SPLIT); text and flags keep dictionaries.  On a 1 M-frame
    segment of the bench scenario: 87.8 MB with the export's settings (snappy, dictionaries),
    63.5 MB with zstd, 36 MB with zstd and these encodings, and less CPU than either.  DuckDB,
    Arrow (Dask, pandas) and Spark read both encodings.
    """
    import pyarrow as pa

    floats = [f.name for f in schema if pa.types.is_floating(f.type)]
    ints = [f.name for f in schema if pa.types.is_integer(f.type) or pa.types.is_timestamp(f.type)]
    return {"compression": "zstd", "use_dictionary": [n for n in schema.names if n not in floats + ints],
            "column_encoding": {**dict.fromkeys(floats, "BYTE_STREAM_SPLIT"),
                                **dict.fromkeys(ints, "DELTA_BINARY_PACKED")}}


class _Partition:
    """One (link, date): rows waiting per table, and the table's file once it has rows."""

    __slots__ = ("key", "rows", "files", "paths", "state")

    def __init__(self, key: tuple[str, str], state: dict) -> None:
        self.key = key
        self.state = state  # what the decoders knew when its first frame came
        self.rows: tuple[list, list, list] = ([], [], [])
        self.files: list[RowGroupFile | None] = [None, None, None]
        self.paths: list[str] = ["", "", ""]  # relative to the staging (and the dataset) folder


class DatasetSink(TableSink):
    """See the module doc.  After close(): `written` [(relative path, table, rows)], `counts` per table,
    `first_ns` / `last_ns` (the first and last frame's wall clock; None when the capture does not know it)."""

    def __init__(self, staging: str, capture: str, link: str | None = None, source: str = "",
                 batch: int = BATCH) -> None:
        super().__init__()
        self._pool = arrow_pool()
        self.batch = batch
        self.staging = staging
        self.capture = capture
        self.given_link = link
        self.source = source
        self.tables = dataset_schemas()
        self._base = dataset_bases()  # to_batch takes a row's first columns: a trailing `link` is left out
        self._parts: dict[tuple[str, str], _Partition] = {}
        self._cur: _Partition | None = None
        self._link = ""
        self._lo = self._hi = 0
        self.link = ""
        self._clock = False
        self._meta: dict = {}
        self.written: list[tuple[str, str, int]] = []
        self.counts = dict.fromkeys(DATASET_TABLES, 0)
        self.first_ns: int | None = None
        self.last_ns: int | None = None
        self.decoder_state = None  # the session binds its pipeline's (Pipeline.decoder_state, state_version)
        self.state_version = None
        self._state: dict = {}
        self._version = None

    def bind(self, pipeline) -> None:
        self.decoder_state = pipeline.decoder_state
        self.state_version = pipeline.state_version

    def start(self, info: CaptureInfo) -> None:
        from sniffer.dataset.layout import link_name

        super().start(info)
        self.link = link_name(info, self.given_link)
        self._clock = info.wall_anchor_ns > 0
        self._meta = {b"sniffer.schema_version": str(SCHEMA_VERSION).encode(),
                      b"sniffer.capture": self.capture.encode(), b"sniffer.source": self.source.encode(),
                      b"sniffer.time_source": info.time_source.encode()}
        self._state = info.extra.get(KEY) or {}

    def frame(self, f: Frame) -> None:
        link = getattr(f, "link", "") or self.link
        wall = self._anchor + f.t_ns - self._t0  # anchor 0 (no wall clock): from the epoch
        part = self._cur
        if part is None or link != self._link or not self._lo <= wall < self._hi:
            part = self._switch(link, wall)
        self.last_ns = wall
        rf, rp, ra = part.rows
        rf.append(frame_row(f, self._t0, self._anchor))
        if f.points:
            rp.extend(point_rows(f, self._t0))
        if f.annotations:
            ra.extend(annotation_rows(f, self._t0))
        self.frames += 1
        if self.state_version is not None:  # what a partition that begins with the next frame starts with
            v = self.state_version()
            if v != self._version:
                self._version, self._state = v, self.decoder_state()
        if len(rf) >= CONVERT:
            self._write(part, 0)
        if len(rp) >= CONVERT:
            self._write(part, 1)
        if len(ra) >= CONVERT:
            self._write(part, 2)

    def rows_on_disk(self) -> int:
        """Rows of every table written to the files so far (in closed row groups)."""
        return sum(f.rows for p in self._parts.values() for f in p.files if f is not None)

    @property
    def partitions(self) -> list[tuple[str, str]]:
        """The (link, date) partitions the capture's frames went to, sorted."""
        return sorted(self._parts)

    def _switch(self, link: str, wall: int) -> _Partition:
        from sniffer.dataset.layout import NO_CLOCK_DATE, date_of, day_bounds

        self._lo, self._hi = day_bounds(wall)
        date = date_of(wall) if self._clock else NO_CLOCK_DATE
        if not self._clock:
            self._lo, self._hi = -(1 << 62), 1 << 62  # one date for the whole capture
        if self.first_ns is None:
            self.first_ns = wall
        key = (link, date)
        self._link = link
        part = self._parts.get(key)
        if part is None:
            part = self._parts[key] = _Partition(key, self._state)
        self._cur = part
        return part

    def _write(self, part: _Partition, table: int) -> None:
        """The partition's waiting rows of `table` -> a record batch with `time` and `capture` -> its file."""
        import pyarrow as pa
        import pyarrow.compute as pc

        rows = part.rows[table]
        if not rows:
            return
        base = to_batch(rows, self._base[table], self._pool)
        rows.clear()
        n = base.num_rows
        ts = pa.timestamp("ns", tz="UTC")
        if not self._clock:
            time = pa.nulls(n, ts)
        elif table == 0:
            time = base.column("t_wall_ns").cast(ts)
        else:  # seconds from the capture's start -> wall-clock ns
            ns = pc.cast(pc.round(pc.multiply(base.column("t"), float(NS))), pa.int64())
            time = pc.add(ns, self._anchor).cast(ts)
        name = DATASET_TABLES[table]
        schema = self.tables[name]
        batch = pa.RecordBatch.from_arrays([*base.columns, time, pa.repeat(self.capture, n)], schema=schema)
        f = part.files[table]
        if f is None:
            from sniffer.dataset.layout import partition

            rel = os.path.join(partition(name, *part.key), self.capture + ".parquet")
            path = os.path.join(self.staging, rel)
            make_folders(os.path.dirname(path))
            meta = {**self._meta, b"sniffer.decoder_state": msgspec.json.encode(part.state)}
            f = part.files[table] = RowGroupFile(path, schema.with_metadata(meta), self._pool, self.batch,
                                                  encodings(schema))
            part.paths[table] = rel
        f.put(batch)
        self.counts[name] += n

    def close(self) -> None:
        """Every partition's last rows, then every file closed (all of them, whatever fails first)."""
        error = None
        for part in self._parts.values():
            for table in range(3):
                try:
                    if error is None:
                        self._write(part, table)
                except BaseException as e:  # noqa: BLE001 - closing the rest first; raised below
                    error = e
                f = part.files[table]
                if f is not None:
                    try:
                        f.close()
                    except BaseException as e:  # noqa: BLE001 - as above
                        error = error or e
        self.written = [(part.paths[t], DATASET_TABLES[t], f.rows)
                        for part in self._parts.values() for t, f in enumerate(part.files) if f is not None]
        if not self._clock:
            self.first_ns = self.last_ns = None
        if error is not None:
            raise error
