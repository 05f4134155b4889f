"""`sniffer report` and bad input: a missing or corrupt capture, an output that cannot be written, a failure
while writing: one error line, an exit code, and no report (nor part file) left behind; a damaged but
readable capture: a complete page that says what was lost, and exit code 2."""

from __future__ import annotations

import os

from test_report import SIM, cli, left_in, page_data

from sniffer.cli import main


def test_missing_capture_is_one_line_and_nothing_written(tmp_path, capsys):
    out = tmp_path / "r.html"
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", tmp_path / "nope.mcap", "--out", out)
    assert rc == 2 and lines == [f"sniffer: error: {tmp_path / 'nope.mcap'}: no such file"]
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", "--compare", tmp_path / "gone.mcap", "--out", out)
    assert rc == 2 and lines == [f"sniffer: error: {tmp_path / 'gone.mcap'}: no such file (--compare)"]
    assert left_in(tmp_path) == []


def test_corrupt_capture_is_one_line_and_no_half_report(tmp_path, capsys):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + os.urandom(3000))
    out = tmp_path / "r.html"
    out.write_text("the old report")
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", bad, "--out", out)  # found before errors.mcap is decoded
    assert rc == 2 and lines == [f"sniffer: error: {bad}: MCAP file cut off before its capture info (the last "
                                 f"record is cut off at byte 8); nothing to replay"]
    assert out.read_text() == "the old report" and left_in(tmp_path) == ["r.html"]
    csv = tmp_path / "bytes.csv"
    csv.write_text("t_s,channel,byte_hex,flags\n0.1,RX,01,\n")
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", csv, "--out", out)  # a byte CSV says no baud rate
    assert rc == 2 and len(lines) == 1 and "give --baud" in lines[0]
    assert out.read_text() == "the old report" and left_in(tmp_path) == ["r.html"]


def test_unwritable_out_is_one_line(tmp_path, capsys):
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", "--out", tmp_path / "no" / "r.html")
    assert rc == 2 and lines == [f"sniffer: error: {tmp_path / 'no' / 'r.html'}: folder {tmp_path / 'no'} "
                                 f"does not exist"]
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", "--out", tmp_path)
    assert rc == 2 and lines == [f"sniffer: error: {tmp_path}: is a folder, not a file name"]
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if not os.access(ro, os.W_OK):  # root may write anywhere: then this part says nothing
            rc, lines = cli(capsys, "report", SIM / "errors.mcap", "--out", ro / "r.html")
            assert rc == 2 and lines == [f"sniffer: error: {ro / 'r.html'}: folder {ro} is not writable"]
    finally:
        ro.chmod(0o700)
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", "--out", SIM / "errors.mcap")
    assert rc == 2 and lines == [f"sniffer: error: {SIM / 'errors.mcap'}: is also an input of this command; "
                                 f"write to another file"]


def test_write_failure_leaves_nothing(tmp_path, capsys, monkeypatch):
    import sniffer.report.page as page

    def boom(data, title):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(page, "render", boom)
    monkeypatch.setattr("sniffer.report.render", boom)
    rc, lines = cli(capsys, "report", SIM / "errors.mcap", "--out", tmp_path / "r.html")
    assert rc == 1 and lines == ["sniffer: error: No space left on device"]
    assert left_in(tmp_path) == []


def test_damaged_capture_is_reported_on_and_exits_2(tmp_path, capsys):
    csv = tmp_path / "line.csv"
    assert main(["simulate", "--scenario", "errors", "--duration", "3", "--out", str(csv)]) == 0
    rows = csv.read_text().splitlines()
    rows[len(rows) // 2] = "garbage,row,zz,"  # a row that is no time: skipped, the rest decoded
    csv.write_text("\n".join(rows) + "\n")
    capsys.readouterr()
    out = tmp_path / "r.html"
    rc, lines = cli(capsys, "report", csv, "--baud", "19200", "--parity", "E", "--out", out)
    assert rc == 2 and len(lines) == 2 and "input damaged: " in lines[0] and lines[1].startswith("sniffer: wrote")
    d = page_data(out)  # a complete page, saying what was lost
    assert "bad row" in d["captures"][0]["damage"][0] and d["totals"]["frames"] > 100
    assert d["totals"]["codes"]["source.gap"] >= 1
    assert left_in(tmp_path) == ["r.html"]
