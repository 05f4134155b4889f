"""The CSV export is written without pyarrow (the core install has none), byte for byte as Arrow's CSV writer
wrote it before: the same rows give the same text, and a capture exported with pyarrow blocked gives the files
that Arrow's writer gives."""

from __future__ import annotations

import io
import math
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.capture.session import CaptureSpec, Session
from sniffer.formats.csvexport import csv_text, float_text, header
from sniffer.formats.tables import TableSink, arrow_pool, schemas, to_batch
from sniffer.sources.files import FileSource

pa = pytest.importorskip("pyarrow", reason="pyarrow is in the test extra: pip install -e '.[test]'")
pcsv = pytest.importorskip("pyarrow.csv")

ROOT = Path(__file__).resolve().parents[1]
SIM = ROOT / "captures" / "sim"
KINDS = ("int", "float", "str", "bool")


def arrow_csv(rows: list, columns) -> bytes:
    """What pyarrow's CSV writer (quoting_style="needed", as the export used) makes of the rows."""
    types = {"int": pa.int64(), "float": pa.float64(), "str": pa.string(), "bool": pa.bool_()}
    schema = pa.schema([(name, types[kind]) for name, kind in columns])
    out = io.BytesIO()
    w = pcsv.CSVWriter(out, schema, write_options=pcsv.WriteOptions(quoting_style="needed"))
    if rows:
        w.write_batch(to_batch(rows, schema, arrow_pool()))
    w.close()
    return out.getvalue()


def ours(rows: list, columns) -> bytes:
    return header(columns) + (csv_text(rows, columns) if rows else b"")


NUMBERS = [0.0, -0.0, 1.0, 3.0, -2.5, 0.1, 1e-4, 1.5e-5, 1e-6, 1.234e-6, 1e-7, 9.999999999999999e-07, 123456789.0,
           9999999999.0, 1e10, 12345678901.5, -12345678901.5, 1e15, 1e16, 2.0 ** 53, 1e21, 1e22, 5e-324,
           1.7976931348623157e308, math.inf, -math.inf, math.nan, 0.30000000000000004, 100.0, 11.757]


def test_floats_as_arrow_writes_them():
    cols = (("f", "float"),)
    cases = NUMBERS + [math.nextafter(10.0 ** k, d) for k in range(-8, 12) for d in (0.0, math.inf)]
    rows = [(v,) for v in cases] + [(None,)]
    assert ours(rows, cols) == arrow_csv(rows, cols)
    assert [float_text(v) for v in (3.0, 1e-7, 1e10, -0.0, None)] == ["3", "1e-7", "1e+10", "-0", ""]


def _value(kind: str):
    if kind == "int":
        return st.integers(-(2 ** 63), 2 ** 63 - 1)
    if kind == "float":
        return st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(NUMBERS)
    if kind == "str":
        return st.text(alphabet=st.characters(exclude_categories=("Cs",)), max_size=12) | st.sampled_from(
            ['"', 'a"b', "a,b", "x\ny", "\r\n", "", " "])
    return st.booleans()


@st.composite
def tables(draw):
    kinds = draw(st.lists(st.sampled_from(KINDS), min_size=1, max_size=6))
    columns = tuple((f"c{i}", k) for i, k in enumerate(kinds))
    rows = draw(st.lists(st.tuples(*[st.none() | _value(k) for k in kinds]), max_size=20))
    return columns, rows


@settings(max_examples=200, deadline=None)
@given(tables())
def test_any_rows_as_arrow_writes_them(table):
    columns, rows = table
    assert ours(rows, columns) == arrow_csv(rows, columns)


class ArrowCsvSink(TableSink):
    """The export's CSV sink as it was: the rows as Arrow record batches, written by Arrow's CSV writer."""

    def __init__(self, frames_path, points_path) -> None:
        super().__init__()
        self.schemas, self._pool = schemas(), arrow_pool()
        self._files = [open(frames_path, "wb"), open(points_path, "wb")]
        options = pcsv.WriteOptions(quoting_style="needed")
        self._writers = [pcsv.CSVWriter(fh, s, write_options=options) for fh, s in zip(self._files, self.schemas)]

    def _put(self, table, rows) -> None:
        self._writers[table].write_batch(to_batch(rows, self.schemas[table], self._pool))

    def _end(self) -> None:
        for w, fh in zip(self._writers, self._files):
            w.close()
            fh.close()


BLOCKED = "import sys; sys.modules['pyarrow'] = None; from sniffer.cli import main; sys.exit(main(sys.argv[1:]))"


@pytest.mark.parametrize("capture", ["a510", "errors", "pd-series"])
def test_export_without_pyarrow_gives_arrows_files(tmp_path, capture):
    path = SIM / f"{capture}.mcap"
    ref = ArrowCsvSink(tmp_path / "arrow.csv", tmp_path / "arrow.points.csv")
    session = Session(CaptureSpec(), FileSource(str(path)), [ref])
    session.open()
    session.run()
    assert session.frames_out > 100
    out = tmp_path / "plain.csv"
    r = subprocess.run([sys.executable, "-c", BLOCKED, "export", str(path), "--to", "csv", "--out", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes() == (tmp_path / "arrow.csv").read_bytes()
    assert (tmp_path / "plain.points.csv").read_bytes() == (tmp_path / "arrow.points.csv").read_bytes()
