"""`ingest` / `export --to dataset` take a capture in whole or not at all, and never twice.

A capture still being copied (an MCAP without its end) is not taken in as whole: one line, and the
whole copy is taken in later, once.  A file that changed since it was taken in (the same path and
first frame: the same capture, grown) replaces its rows; another capture at the same path is added.
A file that changes while it is read is not taken in.  A run killed outright leaves a staging folder
that the next run removes (and says so); a folder a live run holds is left alone.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_dataset import A510, _clocked_capture, files, sql

from sniffer.cli import main

duckdb = pytest.importorskip("duckdb", reason="duckdb is a dependency: pip install -e .")
WIZ = Path(__file__).resolve().parent.parent / "captures" / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv"


def _frames(ds: Path) -> int:
    return sql(ds, "SELECT count(*) FROM frames")[0][0]


def test_a_capture_still_being_copied_is_not_taken_in_and_the_whole_copy_is_taken_once(tmp_path, capsys):
    folder, ds = tmp_path / "captures", tmp_path / "fleet"
    folder.mkdir()
    whole = A510.read_bytes()
    (folder / "a510.mcap").write_bytes(whole[: len(whole) * 2 // 3])  # the copy so far
    assert main(["ingest", str(folder), "--to", str(ds)]) == 2
    err = capsys.readouterr().err
    assert "a510.mcap: not closed cleanly (still being copied or written" in err and "not taken in" in err
    assert _frames(ds) == 0 and not (ds / "_manifest").exists()
    (folder / "a510.mcap").write_bytes(whole)  # the copy is done
    assert main(["ingest", str(folder), "--to", str(ds)]) == 0
    assert main(["ingest", str(folder), "--to", str(ds)]) == 0  # and a third run: already there
    capsys.readouterr()
    assert main(["export", str(A510), "--to", "dataset", str(tmp_path / "alone")]) == 0
    assert _frames(ds) == _frames(tmp_path / "alone") > 0  # every frame once


def _pcap(src: Path, out: Path) -> list[int]:
    """`src` exported as pcap to `out`; the offset of each record."""
    assert main(["export", str(src), "--to", "pcap", "--out", str(out), "--baud", "9600"]) == 0
    data = out.read_bytes()
    offsets, pos = [], 24
    while pos < len(data):
        offsets.append(pos)
        pos += 16 + int.from_bytes(data[pos + 8:pos + 12], "little")
    return offsets


def test_a_file_that_grew_since_it_was_taken_in_replaces_its_rows(tmp_path, capsys):
    """A pcap has no end to miss: one cut at a record's end reads whole.  Taken in while it was being
    written, then again when it was done: the rows are the done file's, once."""
    whole = tmp_path / "whole.pcap"
    offsets = _pcap(WIZ, whole)
    line = tmp_path / "line.pcap"
    line.write_bytes(whole.read_bytes()[: offsets[len(offsets) // 2]])  # half of it, at a record's end
    ds = tmp_path / "fleet"
    assert main(["export", str(line), "--to", "dataset", str(ds), "--baud", "9600"]) == 0
    half = _frames(ds)
    shutil.copy(whole, line)  # the tool wrote the rest
    capsys.readouterr()
    assert main(["export", str(line), "--to", "dataset", str(ds), "--baud", "9600"]) == 0
    err = capsys.readouterr().err
    assert "the file changed since it was taken in: its rows replace those of line-" in err
    assert main(["export", str(whole), "--to", "dataset", str(tmp_path / "ref"), "--baud", "9600"]) == 0
    assert _frames(ds) == _frames(tmp_path / "ref") > half > 0  # replaced, not added to
    entries = [json.loads(p.read_text()) for p in (ds / "_manifest").glob("*.json")]
    assert len(entries) == 1 and entries[0]["replaces"][0].startswith("line-")
    assert not [f for f in files(ds) if entries[0]["replaces"][0] in f]  # the old files are gone


def test_another_capture_at_the_same_path_is_added(tmp_path, capsys):
    cap, ds = tmp_path / "cab3.mcap", tmp_path / "fleet"
    n1 = _clocked_capture(cap, 1_790_000_000 * 10**9, "/dev/ttyUSB3")
    assert main(["ingest", str(tmp_path), "--to", str(ds)]) == 0
    n2 = _clocked_capture(cap, 1_790_086_400 * 10**9, "/dev/ttyUSB3")  # the next day's, written over it
    assert main(["ingest", str(tmp_path), "--to", str(ds)]) == 0
    assert "replace" not in capsys.readouterr().err
    assert _frames(ds) == n1 + n2


def test_a_file_that_changes_while_it_is_read_is_not_taken_in(tmp_path):
    from sniffer.dataset.ingest import Failed, take_in
    from sniffer.dataset.layout import Known, create_dataset
    from sniffer.capture.session import CaptureSpec

    cap = tmp_path / "growing.csv"
    shutil.copy(WIZ, cap)
    ds = create_dataset(str(tmp_path / "fleet"))
    grown = []

    def append_once(_event):
        if not grown:
            grown.append(1)
            with open(cap, "a") as fh:
                fh.write("99.000000,RX,01,\n")

    got = take_in(ds, str(cap), CaptureSpec.of(baud=9600), Known([]), on_event=append_once)
    assert isinstance(got, Failed) and "changed while it was read" in got.why
    assert files(Path(ds.root)) == ["dataset.json"]


def test_a_killed_ingest_leaves_a_staging_folder_the_next_run_removes(tmp_path, capsys):
    folder, ds = tmp_path / "captures", tmp_path / "fleet"
    folder.mkdir()
    assert main(["simulate", "--scenario", "stress", "--duration", "3", "--out", str(folder / "stress.mcap")]) == 0
    run = subprocess.Popen([sys.executable, "-m", "sniffer", "ingest", str(folder), "--to", str(ds)],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while not list((ds / "_staging").glob("*")) and time.monotonic() < deadline and run.poll() is None:
        time.sleep(0.005)
    run.send_signal(signal.SIGKILL)
    run.wait()
    left = [p.name for p in (ds / "_staging").glob("*")]
    assert len(left) == 1, "the run ended before it could be killed mid-capture"
    capsys.readouterr()
    assert main(["ingest", str(folder), "--to", str(ds)]) == 0
    err = capsys.readouterr().err
    assert f"note: {ds / '_staging'}: removed 1 staging folder of killed runs ({left[0]})" in err
    assert not (ds / "_staging").exists()
    assert sql(ds, "SELECT count(DISTINCT capture) FROM frames") == [(1,)]


def test_tidy_leaves_the_staging_folder_of_a_live_run(tmp_path):
    from sniffer.dataset.ingest import tidy
    from sniffer.dataset.layout import create_dataset

    ds = create_dataset(str(tmp_path / "fleet"))
    staging = Path(ds.root) / "_staging"
    live, dead, older = staging / "a-0123.111", staging / "b-4567.222", staging / f"c-89ab.{2**22 + 4321}"
    for d in (live, dead, older):
        d.mkdir(parents=True)
    held = os.open(live / ".lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)  # a run writing it now
    os.close(os.open(dead / ".lock", os.O_RDWR | os.O_CREAT))  # its run was killed: nobody holds it
    os.utime(older, (time.time() - 3600, time.time() - 3600))  # an older sniffer's, its process gone
    try:
        said = tidy(ds)
        assert sorted(p.name for p in staging.iterdir()) == [live.name]
        assert said == [f"{staging}: removed 2 staging folders of killed runs ({dead.name}, {older.name})"]
    finally:
        os.close(held)


@pytest.mark.parametrize("field", ["source", "size", "mtime_ns", "sha256", "capture", "host", "files", "replaces",
                                   "first_ns"])
def test_a_manifest_entry_of_the_wrong_kinds_is_left_out(tmp_path, capsys, field):
    """An entry edited into other kinds (by hand, or by another program) is read as an unreadable one: left
    out of what is known, never a traceback; the capture is taken in again under its own name."""
    folder, ds = tmp_path / "captures", tmp_path / "fleet"
    folder.mkdir()
    shutil.copy(A510, folder / "a510.mcap")
    assert main(["ingest", str(folder), "--to", str(ds)]) == 0
    (entry,) = (ds / "_manifest").glob("*.json")
    good = json.loads(entry.read_text())
    for value in ([1], {"a": 1}, "x", 1.5, True, float("inf"), 10**30):
        entry.write_text(json.dumps({**good, field: value}))
        capsys.readouterr()
        for argv in (["ingest", str(folder), "--to", str(ds)], ["query", str(ds), "SELECT count(*) FROM captures"]):
            code = main(argv)
            err = capsys.readouterr().err
            assert code in (0, 2) and "Traceback" not in err, (field, value, argv[0], err)
        entry.write_text(json.dumps(good))
