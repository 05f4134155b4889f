"""The fleet dataset: export/ingest into hive-partitioned Parquet, read back by DuckDB (sniffer query) and pyarrow."""

from __future__ import annotations

import datetime as dt
import json
import os
import shutil
from pathlib import Path

import pytest

from helpers import decoded

from sniffer.cli import main

duckdb = pytest.importorskip("duckdb", reason="duckdb is a dependency: pip install -e .")

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
A510 = CAPTURES / "sim" / "a510.mcap"
ERRORS = CAPTURES / "sim" / "errors.mcap"

# schema version 1, column by column: a change here is a new schema version (sniffer/formats/schemas.py)
V1 = {
    "frames": "index:int64 t:double t_end:double t_wall_ns:int64 protocol:string role:string unit:int64 "
              "function:int64 crc_ok:bool exception_code:int64 model:string pair:int64 latency_ms:double "
              "n_points:int64 annotations:string summary:string raw:string channel:string time_source:string "
              "noise_reason:string time:timestamp[ns, tz=UTC] capture:string",
    "points": "frame:int64 t:double unit:int64 function:int64 role:string crc_ok:bool model:string address:int64 "
              "name:string id:string raw:int64 value:double value_text:string eng_unit:string "
              "time:timestamp[ns, tz=UTC] capture:string",
    "annotations": "frame:int64 t:double unit:int64 function:int64 role:string crc_ok:bool model:string code:string "
                   "severity:string detail:string span_start:int64 span_end:int64 time:timestamp[ns, tz=UTC] "
                   "capture:string",
}


def files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


def sql(root, query: str):
    from sniffer.dataset.layout import open_dataset
    from sniffer.dataset.query import connect

    con = connect(open_dataset(str(root)))
    try:
        return con.execute(query).fetchall()
    finally:
        con.close()


@pytest.fixture(scope="module")
def truth():
    """(frames, points, annotations) per capture, decoded as replay decodes them."""
    out = {}
    for path in (A510, ERRORS):
        _, frames = decoded(path)
        out[path.name] = (len(frames), sum(len(f.points) for f in frames), sum(len(f.annotations) for f in frames),
                          sum(1 for f in frames for a in f.annotations if a.severity == "error"))
    return out


def test_export_two_captures_as_segments(tmp_path, truth, capsys):
    ds = tmp_path / "fleet"
    assert main(["export", str(A510), str(ERRORS), "--to", "dataset", str(ds)]) == 0
    got = files(ds)
    for stem in ("a510", "errors"):
        for table in V1:
            assert sum(1 for f in got if f.startswith(f"{table}/link=default/date=1970-01-01/{stem}-")) == 1
    assert sum(1 for f in got if f.startswith("_manifest/")) == 2 and "dataset.json" in got
    assert not any(".part" in f or f.startswith("_staging") for f in got)
    rows = dict(((c, t), n) for c, t, n in sql(ds, """
        SELECT split_part(capture, '-', 1), 'frames', count(*) FROM frames GROUP BY ALL UNION ALL
        SELECT split_part(capture, '-', 1), 'points', count(*) FROM points GROUP BY ALL UNION ALL
        SELECT split_part(capture, '-', 1), 'annotations', count(*) FROM annotations GROUP BY ALL"""))
    for name, (nf, np_, na, _) in truth.items():
        stem = name.removesuffix(".mcap")
        assert (rows[stem, "frames"], rows[stem, "points"], rows[stem, "annotations"]) == (nf, np_, na)
    (link, date), = sql(ds, "SELECT DISTINCT link, date FROM frames")
    assert (link, date) == ("default", dt.date(1970, 1, 1))  # typed partitions: VARCHAR and DATE
    assert sql(ds, "SELECT count(*) FROM frames WHERE time IS NOT NULL") == [(0,)]  # no wall clock: no time
    err = capsys.readouterr().err
    assert f"{truth['a510.mcap'][0]} frames" in err and "2 captures taken in" in err


def test_schema_is_stable_and_in_every_file(tmp_path):
    import pyarrow.parquet as pq

    ds = tmp_path / "fleet"
    assert main(["export", str(ERRORS), "--to", "dataset", "--out", str(ds)]) == 0
    meta = json.loads((ds / "dataset.json").read_text())
    assert meta["format"] == "sniffer-dataset" and meta["schema_version"] == 1
    assert meta["partitioning"] == ["link", "date"]
    for table, cols in V1.items():
        assert " ".join(f"{n}:{t}" for n, t in meta["tables"][table]["columns"]) == cols
        (path,) = (ds / table).rglob("*.parquet")
        f = pq.ParquetFile(path)
        assert " ".join(f"{x.name}:{x.type}" for x in f.schema_arrow) == cols
        kv = f.metadata.metadata
        assert kv[b"sniffer.schema_version"] == b"1" and kv[b"sniffer.capture"].startswith(b"errors-")


def test_appends_never_rewrite_and_known_captures_are_skipped(tmp_path, capsys):
    ds = tmp_path / "fleet"
    assert main(["export", str(A510), "--to", "dataset", str(ds)]) == 0
    before = {f: (ds / f).stat().st_mtime_ns for f in files(ds)}
    copy = tmp_path / "renamed.mcap"
    shutil.copy(A510, copy)  # the same content under another name: known by its hash
    capsys.readouterr()
    assert main(["export", str(A510), str(copy), "--to", "dataset", str(ds)]) == 0
    err = capsys.readouterr().err
    assert err.count("already in the dataset as a510-") == 2 and "0 captures taken in" in err
    assert main(["export", str(ERRORS), "--to", "dataset", str(ds)]) == 0
    after = {f: (ds / f).stat().st_mtime_ns for f in files(ds)}
    assert {f: after[f] for f in before if f != "dataset.json"} == {f: m for f, m in before.items()
                                                                     if f != "dataset.json"}
    assert len(after) == len(before) + 4  # three tables and a manifest entry, nothing rewritten


def test_ingest_is_incremental(tmp_path, truth, capsys):
    folder, ds = tmp_path / "captures", tmp_path / "fleet"
    (folder / "line3").mkdir(parents=True)
    shutil.copy(A510, folder / "line3" / "a510.mcap")
    (folder / "killed.mcap.part").write_bytes(b"not yet")  # a capture still being written: left out
    assert main(["ingest", str(folder), "--to", str(ds)]) == 0
    shutil.copy(ERRORS, folder / "errors.mcap")
    capsys.readouterr()
    assert main(["ingest", str(folder), "--to", str(ds), "--link", "line3"]) == 0
    err = capsys.readouterr().err
    assert "1 capture taken in" in err and "1 already there" in err and "a510.mcap: already in the dataset" in err
    counts = dict(sql(ds, "SELECT link, count(*) FROM frames GROUP BY link"))
    assert counts == {"default": truth["a510.mcap"][0], "line3": truth["errors.mcap"][0]}
    entries = sql(ds, "SELECT capture, frames FROM captures ORDER BY capture")
    assert [n for _, n in entries] == [truth["a510.mcap"][0], truth["errors.mcap"][0]]
    (ds / "_manifest" / "zz-by-hand.json").write_text("{broken")  # a damaged entry: left out, queries still run
    assert sql(ds, "SELECT count(*) FROM captures") == [(2,)]


def _clocked_capture(path: Path, anchor_ns: int, port: str) -> int:
    """An MCAP of 4 s of the errors scenario with a wall clock from `anchor_ns`, as if captured on `port`."""
    from sniffer.events import CaptureInfo
    from sniffer.capture.session import CaptureSpec, EventSource, Session
    from sniffer.simulator import get_scenario, simulate, wire_chunks
    from sniffer.formats import FileSink

    sc = get_scenario("errors")
    chunks = wire_chunks(list(simulate(sc, sc.line, 4.0, 3)))
    info = CaptureInfo(source=f"serial:{port}", port=port, baud=sc.line.baud, parity=sc.line.parity,
                       stopbits=sc.line.stopbits, time_source="byte", wall_anchor_ns=anchor_ns)
    s = Session(CaptureSpec.of(devices=sc.devices), EventSource(info, chunks), [FileSink("mcap", path)]).run()
    assert s.error is None
    return s.frames_out


def test_dates_split_at_midnight_utc_and_link_from_port(tmp_path):
    midnight = dt.datetime(2026, 11, 25, tzinfo=dt.UTC)
    anchor = int(midnight.timestamp()) * 10**9 - 2 * 10**9  # 2 s before midnight
    cap = tmp_path / "cab3.mcap"
    n = _clocked_capture(cap, anchor, "/dev/ttyUSB3")
    ds = tmp_path / "fleet"
    assert main(["export", str(cap), "--to", "dataset", str(ds)]) == 0
    got = {(d.isoformat(), link): k for d, link, k in sql(ds, "SELECT date, link, count(*) FROM frames GROUP BY ALL")}
    assert set(got) == {("2026-11-24", "ttyUSB3"), ("2026-11-25", "ttyUSB3")} and sum(got.values()) == n
    # each row sits in the partition of its own time, and time is the anchor plus t
    assert sql(ds, "SELECT count(*) FROM frames WHERE CAST(time AS DATE) <> date") == [(0,)]
    assert sql(ds, f"SELECT max(abs(epoch_ns(time) - ({anchor} + CAST(round(t * 1e9) AS BIGINT)))) FROM frames") \
        <= [(1000,)]
    assert sql(ds, "SELECT count(*) FROM points p WHERE CAST(p.time AS DATE) <> p.date") == [(0,)]
    assert sql(ds, "SELECT min(time) < TIMESTAMPTZ '2026-11-25 00:00:00+00' FROM annotations") == [(True,)]


def test_query_formats_and_presets(tmp_path, truth, capsys):
    ds = tmp_path / "fleet"
    assert main(["export", str(A510), str(ERRORS), "--to", "dataset", str(ds)]) == 0
    capsys.readouterr()
    assert main(["query", str(ds), "SELECT link, count(*) AS n FROM frames GROUP BY link", "--format", "csv"]) == 0
    assert capsys.readouterr().out == f"link,n\ndefault,{truth['a510.mcap'][0] + truth['errors.mcap'][0]}\n"
    assert main(["query", str(ds), "--preset", "faults", "--format", "json"]) == 0
    faults = json.loads(capsys.readouterr().out)
    errors = sum(r["n"] for r in faults if r["severity"] == "error")
    assert errors == sum(t[3] for t in truth.values())
    assert {"model.fault", "modbus.exception", "modbus.crc.mismatch"} <= {r["code"] for r in faults}
    assert main(["query", str(ds), "--preset", "latency"]) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[0].split() == ["link", "unit", "measured", "median_ms", "p95_ms", "p99_ms", "max_ms"]
    assert table[-1].endswith("rows)")
    assert main(["query", str(ds), "--preset", "writes", "--format", "json"]) == 0
    writes = json.loads(capsys.readouterr().out)
    assert writes and {w["function"] for w in writes} <= {5, 6, 15, 16, 22, 23}
    assert "confirmed" in {w["outcome"] for w in writes}
    assert main(["query", str(ds), "SELECT * FROM frames", "--max-rows", "3"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 + 3 + 1 and "more not shown" in out[-1]


def test_query_read_only_gives_the_same_answers_and_no_access(tmp_path, capsys):
    """--read-only: every preset and the views give what they give without it; SQL that would read a file,
    write one (into the dataset too), attach a database, install or load an extension, or turn the
    setting back is refused with one line and exit 2, and nothing is written."""
    ds = tmp_path / "fleet"
    assert main(["export", str(A510), str(ERRORS), "--to", "dataset", str(ds)]) == 0
    before = sorted(p.relative_to(ds) for p in ds.rglob("*"))
    secret = tmp_path / "secret.csv"
    secret.write_text("who,pin\nops,1234\n")
    for argv in (["--preset", "faults", "--format", "json"], ["--preset", "latency", "--format", "csv"],
                 ["--preset", "writes", "--format", "json"],
                 ["SELECT link, date, capture, count(*) AS n, min(time) AS t FROM points GROUP BY ALL ORDER BY ALL",
                  "--format", "csv"], ["SELECT * FROM captures ORDER BY capture", "--format", "json"]):
        capsys.readouterr()
        assert main(["query", str(ds), *argv]) == 0
        plain = capsys.readouterr().out
        assert main(["query", str(ds), *argv, "--read-only"]) == 0
        got = capsys.readouterr().out
        if argv[0] == "--preset" and argv[1] == "faults":  # its `example` is any_value(): either scan's pick
            got, plain = ([{k: v for k, v in r.items() if k != "example"} for r in json.loads(x)] for x in (got, plain))
        assert got == plain and len(plain) > 2
    out = tmp_path / "out.csv"
    for sql in (f"SELECT * FROM read_csv('{secret}')", f"SELECT * FROM '{secret}'",
                f"COPY (SELECT * FROM frames) TO '{out}'", f"COPY (SELECT 1) TO '{ds}/frames/x.parquet'",
                f"ATTACH '{tmp_path}/db.duckdb'", "INSTALL httpfs", "LOAD httpfs",
                "SET enable_external_access = true", "SELECT * FROM 'https://example.com/x.parquet'",
                f"SELECT * FROM glob('{tmp_path}/*')"):
        capsys.readouterr()
        assert main(["query", str(ds), sql, "--read-only"]) == 2, sql
        err = capsys.readouterr().err
        assert err.startswith("sniffer: error: query:") and len(err.strip().splitlines()) == 1, (sql, err)
        assert "1234" not in err
    assert not out.exists() and not (tmp_path / "db.duckdb").exists()
    assert sorted(p.relative_to(ds) for p in ds.rglob("*")) == before


def test_query_read_only_has_no_temporary_folder_and_takes_its_flags_anywhere(tmp_path, capsys, monkeypatch):
    """DuckDB's temporary folder is ./.tmp of the current folder, and external access off still lets SQL read and
    write there: --read-only has none.  Its flags may come before the SQL, the dataset, or after both."""
    ds = tmp_path / "fleet"
    assert main(["export", str(A510), "--to", "dataset", str(ds)]) == 0
    monkeypatch.chdir(tmp_path)
    (tmp_path / ".tmp").mkdir()
    (tmp_path / ".tmp" / "secret.csv").write_text("who,pin\nops,1234\n")
    for sql in ("SELECT * FROM '.tmp/secret.csv'", f"SELECT * FROM read_csv('{tmp_path}/.tmp/secret.csv')",
                "COPY (SELECT 1) TO '.tmp/out.csv'", "SET temp_directory = '.tmp'"):
        capsys.readouterr()
        assert main(["query", str(ds), sql, "--read-only"]) == 2, sql
        err = capsys.readouterr().err
        assert err.startswith("sniffer: error: query:") and "1234" not in err and len(err.splitlines()) == 1, err
    assert sorted(os.listdir(tmp_path / ".tmp")) == ["secret.csv"]
    sql = "SELECT count(*) AS n FROM frames"
    outs = []
    for argv in ([str(ds), sql, "--read-only", "--format", "csv"], [str(ds), "--read-only", sql, "--format", "csv"],
                 ["--read-only", "--format", "csv", str(ds), sql], ["--format", "csv", str(ds), "--read-only", sql]):
        capsys.readouterr()
        assert main(["query", *argv]) == 0, argv
        outs.append(capsys.readouterr().out)
    assert len(set(outs)) == 1 and outs[0].startswith("n\n") and int(outs[0].split()[1]) > 0
    assert main(["query", str(ds), "--read-only", sql, "more"]) == 2  # a word too many is still refused
    assert "unrecognized arguments: more" in capsys.readouterr().err


def test_query_of_an_empty_table_and_a_new_dataset(tmp_path, capsys):
    ds = tmp_path / "fleet"
    assert main(["ingest", str(tmp_path), "--to", str(ds)]) == 0  # no captures: an empty dataset
    assert main(["query", str(ds), "--preset", "faults", "--format", "csv"]) == 0
    assert capsys.readouterr().out.startswith("link,unit,code,severity,n,")


@pytest.mark.parametrize("argv, text", [
    (["query", "{ds}", "SELEKT 1"], "sniffer: error: query: Parser Error"),
    (["query", "{ds}", "SELECT nope FROM frames"], "sniffer: error: query: Binder Error"),
    (["query", "{missing}", "SELECT 1"], "no such dataset folder"),
    (["query", "{tmp}", "SELECT 1"], "not a sniffer dataset"),
    (["query", "{ds}"], "query needs SQL or --preset NAME"),
    (["query", "{ds}", ""], "query: no SQL statement in it"),
    (["query", "{ds}", "-- nothing"], "query: no SQL statement in it"),
    (["query", "{ds}", " ; /* c */ ;"], "query: no SQL statement in it"),
    (["export", "{a510}", "--to", "csv", "{ds}"], "--to csv takes no folder"),
    (["export", "{a510}", "{errors}", "--to", "csv", "--out", "{tmp}/x.csv"], "writes one capture"),
])
def test_bad_query_and_flags_are_one_line(tmp_path, argv, text, capsys):
    ds = tmp_path / "fleet"
    assert main(["export", str(ERRORS), "--to", "dataset", str(ds)]) == 0
    capsys.readouterr()
    args = [a.format(ds=ds, missing=tmp_path / "nope", tmp=tmp_path, a510=A510, errors=ERRORS) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert text in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_json_takes_what_orjson_refuses(tmp_path, capsys):
    """An integer past 64 bits, a time with a zone, NaN: JSON as the other rows are, not a traceback."""
    ds = tmp_path / "fleet"
    assert main(["ingest", str(tmp_path), "--to", str(ds)]) == 0
    capsys.readouterr()
    assert main(["query", str(ds), "SELECT 1::HUGEINT << 100 AS big, '12:00:00+01'::TIMETZ AS t, "
                 "'nan'::DOUBLE AS n", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out) == [{"big": 1 << 100, "t": "12:00:00+01:00", "n": None}]


def test_corrupt_capture_is_left_out_whole(tmp_path, truth, capsys):
    bad = tmp_path / "bad.mcap"
    data = A510.read_bytes()
    bad.write_bytes(data[: len(data) // 2] + b"\xff" * 64 + data[len(data) // 2 + 64:])  # a broken chunk
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"this is not a capture at all\n" * 10)
    ds = tmp_path / "fleet"
    assert main(["export", str(bad), str(ERRORS), str(junk), "--to", "dataset", str(ds)]) == 2
    err = capsys.readouterr().err
    assert "bad.mcap" in err and "junk.mcap" in err and "not taken in" in err and "Traceback" not in err
    got = files(ds)
    assert not any("bad-" in f or "junk-" in f for f in got) and not any(f.startswith("_staging") for f in got)
    assert sql(ds, "SELECT count(*) FROM frames") == [(truth["errors.mcap"][0],)]  # the good one is in


def test_interrupted_capture_leaves_nothing(tmp_path):
    from sniffer.dataset.ingest import take_in
    from sniffer.dataset.layout import Known, create_dataset
    from sniffer.capture.session import CaptureSpec

    ds = create_dataset(str(tmp_path / "fleet"))
    seen = []

    def stop_midway(_event):
        seen.append(1)
        if len(seen) == 300:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        take_in(ds, str(A510), CaptureSpec(), Known([]), on_event=stop_midway)
    assert files(Path(ds.root)) == ["dataset.json"]
    assert type(take_in(ds, str(A510), CaptureSpec(), Known(ds.manifest()))).__name__ == "Taken"  # taken in later


def test_streams_row_groups_as_frames_pass(stress_mcap, tmp_path):
    import pyarrow.parquet as pq

    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.dataset.sink import DatasetSink
    from sniffer.sources.files import FileSource

    sink = DatasetSink(str(tmp_path), "stress-0", batch=512)
    session = Session(CaptureSpec(), FileSource(stress_mcap), [sink])
    on_disk = []
    for i, _ in enumerate(session):
        if i == 360:  # past 4,096 points (CONVERT): a batch, so a row group
            on_disk.append(sink.rows_on_disk())
    assert on_disk[0] >= 4096  # row groups were written while the capture was read, not at its end
    (points,) = tmp_path.rglob("points/*/*/stress-0.parquet")
    meta = pq.ParquetFile(points).metadata
    assert meta.num_row_groups >= 2 and sink.counts["points"] == meta.num_rows


def test_a_folder_with_other_files_is_not_made_a_dataset(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["export", str(A510), "--to", "dataset", str(tmp_path)]) == 2
    assert "holds other files" in capsys.readouterr().err
    assert os.listdir(tmp_path) == ["notes.txt"]


def test_disk_full_leaves_the_dataset_as_it_was(tmp_path):
    import subprocess
    import sys

    ds = tmp_path / "fleet"
    assert main(["export", str(A510), "--to", "dataset", str(ds)]) == 0
    before = files(ds)
    code = ("import resource,sys; resource.setrlimit(resource.RLIMIT_FSIZE,(10000,10000));"
            "import signal; signal.signal(signal.SIGXFSZ, signal.SIG_IGN);"
            "from sniffer.cli import main; sys.exit(main(sys.argv[1:]))")
    r = subprocess.run([sys.executable, "-c", code, "export", str(ERRORS), "--to", "dataset", str(ds)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, r.stderr
    assert "cannot write the dataset" in r.stderr and "Traceback" not in r.stderr
    assert files(ds) == before  # no half file, no staging folder, no manifest entry


def test_export_of_a_rotated_folder_takes_its_segments(tmp_path, capsys):
    """`export FOLDER --to dataset` of a rotated capture: each closed segment one capture of the dataset (as ingest
    takes them), every frame in; a segment still open is a note and left for a later run."""
    folder = tmp_path / "cab3"
    assert main(["simulate", "--scenario", "default", "--duration", "7", "--rotate", "2s", "--out", str(folder)]) == 0
    index = json.loads((folder / "index.json").read_text())["segments"]
    assert len(index) >= 3
    ds = tmp_path / "fleet"
    capsys.readouterr()
    assert main(["export", str(folder), "--to", "dataset", str(ds)]) == 0
    err = capsys.readouterr().err
    assert f"{len(index)} captures taken in ({sum(s['frames'] for s in index)} frames)" in err
    assert sql(ds, "SELECT count(*) FROM frames") == [(sum(s["frames"] for s in index),)]
    assert sql(ds, "SELECT count(DISTINCT capture) FROM frames") == [(len(index),)]
    # its index names the folder as well; what is in already is skipped
    assert main(["export", str(folder / "index.json"), "--to", "dataset", str(ds)]) == 0
    assert f"0 captures taken in (0 frames), {len(index)} already there" in capsys.readouterr().err
    # the last segment open (a running capture): the others go in, it is said and left for later
    last = folder / index[-1]["file"]
    last.rename(folder / (index[-1]["file"] + ".part"))
    ds2 = tmp_path / "fleet2"
    assert main(["export", str(folder), "--to", "dataset", str(ds2)]) == 0
    err = capsys.readouterr().err
    assert f"note: {folder / index[-1]['file']}.part: not closed" in err
    assert f"{len(index) - 1} captures taken in" in err


def test_export_of_a_folder_that_is_no_rotated_capture_says_ingest(tmp_path, capsys):
    (tmp_path / "site" / "line3").mkdir(parents=True)
    shutil.copy(A510, tmp_path / "site" / "line3" / "a510.mcap")
    assert main(["export", str(tmp_path / "site"), "--to", "dataset", str(tmp_path / "fleet")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line]
    assert len(err) == 1 and "sniffer ingest FOLDER" in err[0]
    assert not (tmp_path / "fleet").exists()
