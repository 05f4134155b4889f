"""`sniffer status` on a status file of the right syntax and the wrong kinds: never a traceback.

A status file is written by the capture (sniffer.capture.status), but `sniffer status` reads whatever is
at the path: one edited by hand, one of another program, one a script filled in.  Every field the
command shows is given every wrong kind of value in turn: the command shows the rest, `?` for
that field and one warning line naming it, with the exit code of the state it can read (0
running, 1 not).  What is not a status file at all (not an object, nested 100,000 deep, huge) is
one error line, exit 2.
"""

from __future__ import annotations

import json
import os
import time

import pytest

from sniffer.cli import main

STATUS = {
    "format": "sniffer.status/1", "state": "running", "pid": os.getpid(), "command": "live /dev/ttyUSB0",
    "source": "serial:/dev/ttyUSB0", "line": "19200 8E1 modbus-rtu", "started": "2026-11-25T10:41:00Z",
    "updated": "2026-11-25T11:41:00Z", "updated_ns": 0, "every_s": 2.0, "uptime_s": 3600.2,
    "frames": 81234, "bytes": 1620000, "capture_s": 3599.99,
    "errors": {"crc": 2, "exceptions": 1, "timeouts": 4, "faults": 0, "noise": 0, "uart": 0, "gaps": 1},
    "last_frame": {"t": 3599.98, "wall": "2026-11-25T11:40:59Z"},
    "port": {"state": "lost", "since": "2026-11-25T11:40:00Z", "reason": "hang-up", "ports": ["/dev/ttyUSB0"]},
    "segments": {"folder": "/srv/cab3", "count": 3, "closed": 2, "killed": 1, "open": "cab3-1.mcap",
                 "bytes": 123456, "disk_free": 10**9, "deleted": 4, "rotate": "1h", "keep": "7d",
                 "delete_errors": ["cab3-0.mcap: Permission denied"], "written": 4_500_000,
                 "limits": {"rotate_s": 3600.0, "rotate_bytes": 0, "keep_s": 604800.0, "keep_bytes": 0,
                            "keep_count": 0}},
    "ended": "interrupted",
    "triggers": {"fired": 3, "windows": 2, "open": 1, "suppressed": 4, "failed_windows": 0, "ring_bytes": 123456,
                 "last": {"rule": "fault", "t": 3500.5, "time": "2026-11-25T11:39:20.500Z", "frame": 80001,
                          "summary": "u2 fc03 fault OL1", "window": "/srv/cab3.trigger-0002.mcap"},
                 "on_trigger": {"ran": 2, "failed": 1, "timed_out": 0, "dropped": 0, "last_error": "exit 1"}},
}
# every field path the command reads
FIELDS = [(k,) for k in STATUS] + [(s, k) for s in ("errors", "last_frame", "port", "segments", "triggers")
                                   for k in STATUS[s]]
WRONG = ["x", 1.5, -1, -(10**400), float("nan"), [], {}, None, True, {"a": {"b": {"c": 1}}}, "\ud800",
         "\n" * 3 + "y" * 100_000]


def _with(path: tuple, value) -> dict:
    d = json.loads(json.dumps(STATUS))
    d["updated_ns"] = time.time_ns()
    target = d
    for k in path[:-1]:
        target = target[k]
    target[path[-1]] = value
    return d


def _run(capsys, path, *flags) -> tuple[int, str, list[str]]:
    code = main(["status", str(path), *flags])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.splitlines() if line.strip()]


def test_the_good_file_reads_without_a_warning(tmp_path, capsys):
    p = tmp_path / "status.json"
    p.write_text(json.dumps(_with(("state",), "running")))
    code, out, err = _run(capsys, p)
    assert code == 0 and err == [] and "81,234" in out and "?" not in out


@pytest.mark.parametrize("field", FIELDS, ids=[".".join(f) for f in FIELDS])
def test_every_field_of_every_wrong_kind(tmp_path, capsys, field):
    p = tmp_path / "status.json"
    for value in WRONG:
        p.write_text(json.dumps(_with(field, value)))
        code, out, err = _run(capsys, p)
        assert code in (0, 1), (field, value, err)
        assert len(err) <= 1 and all(line.startswith("sniffer: warning: ") for line in err), (field, value, err)
        assert out.startswith("capture ") and all(len(line) < 1000 for line in out.splitlines()), (field, value)
    code, out, err = _run(capsys, p, "--json")
    assert code == 0 and err == [] and json.loads(out) is not None


def test_a_field_of_the_wrong_kind_is_shown_as_a_question_mark_and_named(tmp_path, capsys):
    p = tmp_path / "status.json"
    d = _with(("frames",), "many")
    d["segments"]["bytes"] = [1]
    d["pid"] = 10**30
    p.write_text(json.dumps(d))
    code, out, err = _run(capsys, p)
    assert code == 1 and "not running: its process (?) is gone" in out  # a pid it cannot read: not running
    said = dict(line.split(None, 1) for line in out.splitlines() if line[:1].strip())
    assert said["frames"].startswith("? (1.62MB received)") and said["segments"].startswith("3 in /srv/cab3 (?; ")
    assert err == [f"sniffer: warning: {p}: frames, pid, segments.bytes not as a capture writes them (shown as ?)"]


@pytest.mark.parametrize("number", ["NaN", "Infinity", "-Infinity", "1e400"])
def test_a_number_that_is_not_finite_is_no_number(tmp_path, capsys, number):
    """JSON as Python reads it takes NaN, Infinity and 1e400 (inf): they read as no number (the field is shown
    as ?, as one the file lacks), and --json writes null (it could not write them back as JSON)."""
    p = tmp_path / "status.json"
    p.write_text(json.dumps(STATUS).replace('"frames": 81234', f'"frames": {number}'))
    code, out, err = _run(capsys, p)
    said = dict(line.split(None, 1) for line in out.splitlines() if line[:1].strip())
    assert said["frames"].startswith("? (1.62MB received)")
    assert not any("Traceback" in line for line in err)
    main(["status", str(p), "--json"])
    assert json.loads(capsys.readouterr().out)["frames"] is None


@pytest.mark.parametrize("text, why", [
    ("[" * 100_000 + "]" * 100_000, "nested too deep to be a status file"),
    ('{"a": ' * 100_000 + "1" + "}" * 100_000, "nested too deep to be a status file"),
    ("[1, 2]", "not a status file (JSON object)"),
    ('"running"', "not a status file (JSON object)"),
    ("{" + '"frames": ' + "9" * 5000 + "}", "not a status file (JSON object)"),
    ("\xff\xfe{}", "not a status file (JSON object)"),
])
def test_what_is_not_a_status_file_is_one_line(tmp_path, capsys, text, why):
    p = tmp_path / "status.json"
    p.write_bytes(text.encode("utf-8", "surrogateescape") if not text.startswith("\xff") else b"\xff\xfe{}")
    for flags in ((), ("--json",)):
        code, _out, err = _run(capsys, p, *flags)
        assert code == 2 and len(err) == 1 and err[0].startswith("sniffer: error: ") and why in err[0], err


def test_a_status_path_that_is_a_fifo_does_not_block(tmp_path, capsys):
    p = tmp_path / "status.json"
    os.mkfifo(p)
    code, _out, err = _run(capsys, p)
    assert code == 2 and "not a regular file" in err[0]
