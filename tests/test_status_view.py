"""`sniffer status` in words: the data rate, what --keep holds at that rate, the trigger section.

A real rotated capture of three slow links (the README's unattended example: `--keep 14d --keep 20GB`)
written by the session as `live` writes one; the status file read back by the command."""

from __future__ import annotations

import json
import os
import re
import time
from pathlib import Path

from sniffer.capture.session import CaptureSpec, EventSource, Session
from sniffer.cli import main
from sniffer.events import CaptureInfo, Chunk
from sniffer.formats.mcap.rotating import SegmentPlan
from sniffer.formats.mcap.segments import Keep, Rotate, held, parse_size, parse_span
from sniffer.simulator import get_scenario, simulate, usb_chunks

DAY = 86_400
SIM = Path(__file__).resolve().parent.parent / "captures" / "sim"


def _status(capsys, path) -> tuple[int, dict[str, str]]:
    code = main(["status", str(path)])
    out = capsys.readouterr().out
    lines: dict[str, str] = {}
    label = ""
    for line in out.splitlines():
        label = line[:9].strip() or label
        lines[label] = (lines[label] + "\n" + line[10:]) if label in lines else line[10:]
    return code, lines


def _as_running(path) -> None:
    """The status file as a running capture's reads (the test's session has ended)."""
    d = json.loads(path.read_text())
    d["state"], d["pid"], d["updated_ns"] = "running", os.getpid(), time.time_ns()
    path.write_text(json.dumps(d))


def test_status_says_what_keep_holds_on_three_slow_links(tmp_path, capsys):
    """Three 19200-baud lines polled back to back, kept with --keep 14d --keep 10GB (docs/unattended.md): the 10GB
    comes first, after about a week, and `status` says so from the rate the segments grew by."""
    sc = get_scenario("default")
    seconds = 240
    names = ("drives", "pumps", "fans")
    events = []
    for i, name in enumerate(names):
        sent = simulate(sc, sc.line, seconds, seed=i + 1)
        events += [Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", name) for c in usb_chunks(sent, seed=i + 1)]
    events.sort(key=lambda c: c.t_ns)
    info = CaptureInfo(source="serial:a,b,c", baud=19200, parity="E", stopbits=1, time_source="read", links=[
        {"name": n, "ports": [f"/dev/ttyUSB{i}"], "baud": 19200, "parity": "E", "stopbits": 1}
        for i, n in enumerate(names)])
    folder = tmp_path / "plant"
    rotate, keep = Rotate.parse(["1h"]), Keep.parse(["14d", "10GB"])
    spec = CaptureSpec(out=str(folder), rotate=rotate, keep=keep)
    Session(spec, EventSource(info, events), [SegmentPlan(str(folder), rotate, keep)], keep_partial=True).run()
    status = folder / "status.json"
    d = json.loads(status.read_text())
    seg = d["segments"]
    assert seg["written"] > 0 and abs(d["capture_s"] - seconds) < 2

    _as_running(status)
    code, lines = _status(capsys, folder)
    assert code == 0
    line_rate = d["bytes"] / d["capture_s"]
    disk_rate = seg["written"] / d["capture_s"]
    rate = lines["rate"]
    assert f"{round(line_rate)}B/s from the line" in rate or f"{line_rate / 1e3:.3g}kB/s from the line" in rate
    assert f"{disk_rate / 1e3:.3g}kB/s into the segments" in rate
    assert f"({seg['written'] / d['bytes']:.1f}x the line, " in rate  # what the segments cost per byte on the line

    keeps = lines["keeps"]
    m = re.search(r"about ([\d.]+) (d|h) of capture", keeps)
    assert m, keeps
    shown_s = float(m.group(1)) * (DAY if m.group(2) == "d" else 3600)
    assert abs(shown_s - parse_size("10GB") / disk_rate) / shown_s < 0.05  # what 10GB holds at that rate
    assert "10GB comes first" in keeps and parse_size("10GB") / disk_rate < parse_span("14d") / 1e9
    assert 4 * DAY < shown_s < 11 * DAY  # about a week of capture, not the fortnight --keep 14d seems to ask for


def test_held_takes_the_first_limit_to_bite():
    lim = {"rotate_s": 3600.0, "rotate_bytes": 0, "keep_s": 14 * DAY, "keep_bytes": 20e9, "keep_count": 0}
    assert held(1e3, lim) == (14 * DAY, "14d")  # 20GB would last 231 days
    s, which = held(1e5, lim)
    assert which == "20GB" and s == 20e9 / 1e5
    lim = {"rotate_s": 0, "rotate_bytes": 100e6, "keep_s": 0, "keep_bytes": 0, "keep_count": 48}
    assert held(1e4, lim) == (48 * 100e6 / 1e4, "48 segments")  # 48 segments of 100MB
    assert held(1e4, {"rotate_s": 3600.0}) is None  # no --keep: nothing is deleted
    assert held(1e4, {"keep_s": "x", "keep_bytes": 10**400, "keep_count": float("nan")}) is None  # a file's odd values


def test_no_keep_says_how_long_the_disk_lasts(tmp_path, capsys):
    folder = tmp_path / "cab3"
    rotate = Rotate.parse(["1h"])
    spec = CaptureSpec(input=str(SIM / "default.mcap"), out=str(folder), rotate=rotate)
    from sniffer.commands.replay import file_source

    Session(spec, file_source(spec), [SegmentPlan(str(folder), rotate)]).run()
    status = folder / "status.json"
    _as_running(status)
    d = json.loads(status.read_text())
    code, lines = _status(capsys, folder)
    assert code == 0
    free, rate = d["segments"]["disk_free"], d["segments"]["written"] / d["capture_s"]
    assert lines["keeps"].startswith("everything (no --keep); the disk's ")
    m = re.search(r"fill in about ([\d.]+) (d|h|min|s)\b", lines["keeps"])
    unit = {"d": DAY, "h": 3600, "min": 60, "s": 1}[m.group(2)]
    assert abs(float(m.group(1)) * unit - free / rate) <= 0.06 * free / rate


def test_the_trigger_section_is_in_words(tmp_path, capsys):
    status = tmp_path / "status.json"
    code = main(["replay", str(SIM / "errors.mcap"), "--quiet", "--trigger", "exception", "--pre", "2s", "--post",
                 "1s", "--windows", str(tmp_path / "w"), "--status", str(status)])
    assert code == 0
    d = json.loads(status.read_text())
    t = d["triggers"]
    assert t["fired"] >= 1 and t["windows"] >= 1
    _as_running(status)
    capsys.readouterr()
    code, lines = _status(capsys, status)
    assert code == 0
    text = lines["triggers"]
    first, last = text.splitlines()[:2]
    def n(k: int, word: str) -> str:
        return f"{k:,} {word}{'s' if k != 1 else ''}"

    assert first.startswith(f"fired {n(t['fired'], 'time')}, {n(t['windows'], 'window')} written")
    assert f", {t['window_bytes'] / t['window_line_bytes']:.1f}x the line's bytes they hold)" in first
    assert "held for --pre" in first and ("fired nothing" in first) == bool(t["suppressed"])
    assert last.startswith("last: 'exception' at ") and f"frame #{t['last']['frame']}" in last
    assert last.endswith(f"-> {t['last']['window']}")
    for raw in ("ring_bytes", "failed_windows", "last.record", "suppressed ", "on_trigger"):  # no raw keys
        assert raw not in text
