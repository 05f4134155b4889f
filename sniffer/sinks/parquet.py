"""Parquet export: OUT.parquet (frames) + OUT.points.parquet (points), written row group by row group.

Record batches (tables.py) are gathered until a table has `batch` rows, then
written as one row group.
"""

from __future__ import annotations

from .tables import TableSink, schemas

BATCH = 8_192  # rows per row group: with 32,768 a 256k-frame export peaked at 115 MB, with 8,192 at 96 MB

__all__ = ["ParquetSink", "schemas"]

# what pyarrow.parquet.ParquetWriter passes to its engine by default (pyarrow 14-26)
_SETTINGS = {"compression": "snappy", "version": "2.6", "use_dictionary": True, "write_statistics": True,
             "writer_engine_version": "V2", "data_page_version": "1.0", "use_compliant_nested_type": True,
             "store_schema": True}


def _writer(path: str, schema, pool):
    """A Parquet file writer with pyarrow.parquet's default settings.

    Importing pyarrow.parquet imports pyarrow.fs and with it the S3, GCS, Azure and HDFS modules
    and ssl: 9.8 MB of RSS (measured), a tenth of a million-frame export's peak, for a local file.
    Its engine, pyarrow._parquet.ParquetWriter, is called directly with the settings the public
    class would pass; should a pyarrow release change that private signature, the public class
    is used (test_export reads every file back with pyarrow.parquet).
    """
    try:
        from pyarrow import _parquet

        return _parquet.ParquetWriter(path, schema, memory_pool=pool, **_SETTINGS)
    except (ImportError, AttributeError, TypeError):
        import pyarrow.parquet as pq

        return pq.ParquetWriter(path, schema, memory_pool=pool)


class ParquetSink(TableSink):
    def __init__(self, frames_path: str, points_path: str, batch: int = BATCH) -> None:
        super().__init__()
        fs, ps = self.schemas
        self._writers = [_writer(frames_path, fs, self._pool)]
        try:
            self._writers.append(_writer(points_path, ps, self._pool))
        except BaseException:
            self._writers[0].close()
            raise
        self._staged: tuple[list, list] = ([], [])  # record batches of the next row group, per table
        self.batch = batch

    def _put(self, table: int, batch) -> None:
        staged = self._staged[table]
        staged.append(batch)
        if sum(b.num_rows for b in staged) >= self.batch:
            self._row_group(table)

    def _row_group(self, table: int) -> None:
        import pyarrow as pa

        staged = self._staged[table]
        if staged:
            self._writers[table].write_table(pa.Table.from_batches(staged, schema=self.schemas[table]))
            staged.clear()

    def _end(self) -> None:
        try:
            self._row_group(0)
            self._row_group(1)
        finally:
            for w in self._writers:
                w.close()
