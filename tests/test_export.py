"""sniffer export: csv, parquet (read back by DuckDB and pyarrow), mcap re-export with other settings."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from helpers import decoded, export

from sniffer.analysis.check import golden_text
from sniffer.capture.session import CaptureSpec, Session
from sniffer.formats import make_sink
from sniffer.sources.files import FileSource

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
A510 = CAPTURES / "sim" / "a510.mcap"
ERRORS = CAPTURES / "sim" / "errors.mcap"


@pytest.fixture(scope="module")
def a510():
    return decoded(A510)


def test_csv_frames_and_points(tmp_path, a510):
    info, frames = a510
    out = tmp_path / "a510.csv"
    assert export(A510, "csv", out) == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == len(frames)
    assert [int(r["index"]) for r in rows] == [f.index for f in frames]
    assert rows[1]["role"] == "response" and rows[1]["latency_ms"] == "11.757" and rows[1]["crc_ok"] == "true"
    assert rows[0]["raw"] == frames[0].raw.hex()
    points = list(csv.DictReader((tmp_path / "a510.points.csv").open()))
    assert len(points) == sum(len(f.points) for f in frames)
    freq = next(p for p in points if p["name"] == "Frequency command")
    assert freq["eng_unit"] == "Hz" and float(freq["value"]) == 32.5 and freq["raw"] == "3250"
    assert {p["crc_ok"] for p in points} == {"true"}  # every point says whether its frame's CRC held


def test_parquet_reads_in_duckdb_and_pyarrow(tmp_path, a510):
    duckdb = pytest.importorskip("duckdb", reason="duckdb is in the test extra: pip install -e '.[test]'")
    import pyarrow.parquet as pq

    info, frames = a510
    out = tmp_path / "a510.parquet"
    export(A510, "parquet", out)
    n, lat_max = duckdb.sql(f"SELECT count(*), max(latency_ms) FROM '{out}'").fetchall()[0]
    assert n == len(frames)
    assert lat_max == round(max(f.latency_ms for f in frames if f.latency_ms is not None), 3)  # as JSONL
    pts = tmp_path / "a510.points.parquet"
    (avg,) = duckdb.sql(f"SELECT avg(value) FROM '{pts}' WHERE name = 'Frequency command'").fetchall()[0]
    assert avg > 0
    t = pq.read_table(out)
    assert str(t.schema.field("unit").type) == "int64" and str(t.schema.field("crc_ok").type) == "bool"
    assert t.column("function").to_pylist() == [f.function for f in frames]
    assert pq.read_table(pts).num_rows == sum(len(f.points) for f in frames)


def test_parquet_of_noise_and_exceptions(tmp_path):
    duckdb = pytest.importorskip("duckdb", reason="duckdb is in the test extra")
    out = tmp_path / "e.parquet"
    export(ERRORS, "parquet", out)
    (noise,) = duckdb.sql(f"SELECT count(*) FROM '{out}' WHERE protocol = 'noise'").fetchall()[0]
    (exc,) = duckdb.sql(f"SELECT count(*) FROM '{out}' WHERE exception_code IS NOT NULL").fetchall()[0]
    assert noise > 0 and exc > 0


def test_mcap_reexport_with_other_settings_replays_to_the_new_decode(tmp_path):
    out = tmp_path / "a510-generic.mcap"
    assert export(A510, "mcap", out, "--device", "1=generic", "--device", "2=generic") == 0
    info, frames = decoded(out)
    assert info.devices == {1: "generic", 2: "generic"}  # the new settings travel with the capture
    assert {f.model for f in frames if not f.is_noise} == {"generic"}
    # the raw bytes are the same capture: decoding it as A510 again gives the original decode
    back = decoded(out, CaptureSpec.of(devices={1: "a510", 2: "a510"}))
    assert golden_text(back[0].t0_ns, back[1]) == golden_text(a510_info_t0(), decoded(A510)[1])


def a510_info_t0() -> int:
    return decoded(A510)[0].t0_ns


def _interrupt_after(n: int):
    seen = []

    def on_event(ev):
        seen.append(ev)
        if len(seen) == n:
            raise KeyboardInterrupt

    return on_event


def test_csv_export_interrupted_leaves_a_valid_file(tmp_path):
    out = tmp_path / "cut.csv"
    session = Session(CaptureSpec(), FileSource(str(A510)), [make_sink("csv", out)], on_event=_interrupt_after(200))
    with pytest.raises(KeyboardInterrupt):
        session.run()
    rows = list(csv.DictReader(out.open()))  # Ctrl-C keeps what was written: a valid, shorter file
    assert 0 < len(rows) < 502 and all(r["raw"] for r in rows)
    assert not list(tmp_path.glob("*.part"))


def test_progress_bar_export(tmp_path, capfd):
    assert export(A510, "csv", tmp_path / "p.csv", "--progress") == 0
    assert len(list(csv.DictReader((tmp_path / "p.csv").open()))) == 502


def test_unknown_format(tmp_path):
    with pytest.raises(ValueError, match="unknown output format 'xls'"):
        make_sink("xls", tmp_path / "x")


def test_mcap_export_of_a_csv_keeps_the_line_settings(tmp_path):
    wiz = CAPTURES / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv"
    out = tmp_path / "wiz.mcap"
    assert export(wiz, "mcap", out, "--baud", "9600") == 0
    info, frames = decoded(out)  # no --baud needed any more
    assert info.baud == 9600 and len(frames) == 88
    w_info, w_frames = decoded(wiz, CaptureSpec.of(baud=9600))
    assert golden_text(info.t0_ns, frames) == golden_text(w_info.t0_ns, w_frames)


def test_parquet_export_interrupted_leaves_valid_files(tmp_path):
    import pyarrow.parquet as pq

    out = tmp_path / "cut.parquet"
    sink = make_sink("parquet", out)
    sink.batch = 50  # several row groups
    session = Session(CaptureSpec(), FileSource(str(A510)), [sink], on_event=_interrupt_after(300))
    with pytest.raises(KeyboardInterrupt):
        session.run()
    n = pq.read_table(out).num_rows
    assert 0 < n < 502
    pq.read_table(tmp_path / "cut.points.parquet")


def test_progress_total_from_mcap_summary(tmp_path):
    from sniffer.capture.progress import estimate_events

    assert estimate_events(A510) == 570  # the /raw events of the MCAP summary
    assert estimate_events(CAPTURES / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv") is None
    n = []
    Session(CaptureSpec(), FileSource(str(A510)), on_event=n.append).run()
    assert len(n) == 570


def test_parquet_export_does_not_load_pyarrow_file_systems(tmp_path):
    """The Parquet files are written by pyarrow's engine directly (formats/parquet.py): the cloud file
    system modules pyarrow.parquet would import (9.8 MB of RSS) stay out; the files read back whole."""
    import subprocess
    import sys

    import pyarrow.parquet as pq

    out = tmp_path / "e.parquet"
    code = ("import sys\nfrom sniffer.cli import main\n"
            f"rc = main(['export', {str(ERRORS)!r}, '--to', 'parquet', '--out', {str(out)!r}])\n"
            "assert rc == 0, rc\nassert 'pyarrow.fs' not in sys.modules, 'pyarrow.fs was imported'\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    frames, points = pq.read_table(out), pq.read_table(tmp_path / "e.points.parquet")
    assert frames.num_rows == len(decoded(ERRORS)[1]) and points.num_rows > 0
    assert pq.ParquetFile(out).metadata.row_group(0).column(0).compression == "SNAPPY"
