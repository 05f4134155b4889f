"""Parquet export: OUT.parquet (frames) + OUT.points.parquet (points), written row group by row group.

Rows (tables.py) become record batches, gathered until a table has `batch` rows, then
written as one row group (`RowGroupFile`, which the fleet dataset's sink writes
its partition files with too).
"""

from __future__ import annotations

import os

from sniffer.formats.outputs import FILE_MODE
from sniffer.formats.tables import TableSink, arrow_pool, schemas, to_batch

BATCH = 8_192  # rows per row group: with 32,768 a 256k-frame export peaked at 115 MB, with 8,192 at 96 MB

__all__ = ["ParquetSink", "RowGroupFile", "schemas"]

# what pyarrow.parquet.ParquetWriter passes to its engine by default (pyarrow 14-26)
_SETTINGS = {"compression": "snappy", "version": "2.6", "use_dictionary": True, "write_statistics": True,
             "writer_engine_version": "V2", "data_page_version": "1.0", "use_compliant_nested_type": True,
             "store_schema": True}


def _writer(path: str, schema, pool, options: dict | None = None):
    """A Parquet file writer with pyarrow.parquet's default settings.

    Importing pyarrow.parquet imports pyarrow.fs and with it the S3, GCS, Azure and HDFS modules
    and ssl: 9.8 MB of RSS (measured), a tenth of a million-frame export's peak, for a local file.
    Its engine, pyarrow._parquet.ParquetWriter, is called directly with the settings the public
    class would pass; should a pyarrow release change that private signature, the public class
    is used (test_export reads every file back with pyarrow.parquet).  `options` replace settings
    (compression, use_dictionary, column_encoding: the fleet dataset's, dataset/sink.py).
    """
    os.close(os.open(path, os.O_WRONLY | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), FILE_MODE))  # at most 0644
    try:
        from pyarrow import _parquet

        return _parquet.ParquetWriter(path, schema, memory_pool=pool, **{**_SETTINGS, **(options or {})})
    except (ImportError, AttributeError, TypeError):
        import pyarrow.parquet as pq

        return pq.ParquetWriter(path, schema, memory_pool=pool, **(options or {}))


class RowGroupFile:
    """One Parquet file: record batches gathered into row groups of `batch` rows.

    The schema's metadata (if any) goes into the file's key-value metadata."""

    def __init__(self, path: str, schema, pool, batch: int = BATCH, options: dict | None = None) -> None:
        self.schema = schema
        self.batch = batch
        self.rows = 0
        self._writer = _writer(path, schema, pool, options)
        self._staged: list = []
        self._staged_rows = 0

    def put(self, batch) -> None:
        self._staged.append(batch)
        self._staged_rows += batch.num_rows
        if self._staged_rows >= self.batch:
            self._row_group()

    def _row_group(self) -> None:
        import pyarrow as pa

        if self._staged:
            self._writer.write_table(pa.Table.from_batches(self._staged, schema=self.schema))
            self.rows += self._staged_rows
            self._staged.clear()
            self._staged_rows = 0

    def close(self) -> None:
        try:
            self._row_group()
        finally:
            self._writer.close()


class ParquetSink(TableSink):
    def __init__(self, frames_path: str, points_path: str, batch: int = BATCH) -> None:
        super().__init__()
        self._pool = arrow_pool()
        self.schemas = fs, ps = schemas()
        self._files = [RowGroupFile(frames_path, fs, self._pool, batch)]
        try:
            self._files.append(RowGroupFile(points_path, ps, self._pool, batch))
        except BaseException:
            self._files[0].close()
            raise

    def _put(self, table: int, rows: list) -> None:
        self._files[table].put(to_batch(rows, self.schemas[table], self._pool))

    def _end(self) -> None:
        try:
            self._files[0].close()
        finally:
            self._files[1].close()


def open_sink(fmt: str, path: str, parts: list[str]) -> ParquetSink:
    """The Parquet sink writing its part files (named in the table of sniffer.formats)."""
    return ParquetSink(*parts)
