"""Rotated captures: segments that replay alone and as one capture, the index, retention, the status file.

Simulated captures (sniffer simulate) written again with `replay --rotate`, which takes the session path a
live capture takes; the live path itself, kills included, is tests/test_unattended_live.py.
"""

from __future__ import annotations

import json
import os
import shutil

import pytest
from mcap.reader import make_reader

from sniffer.cli import main
from sniffer.formats.mcap.segments import INDEX_NAME, STATUS_NAME, Keep, Rotate, Segment, read_index
from sniffer.capture.session import CaptureSpec, decode_capture
from sniffer.sinks.base import Sink

_CACHE: dict = {}


def _cli(capsys, *args) -> tuple[int, str, str]:
    capsys.readouterr()
    rc = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture
def capture(tmp_path_factory):
    """A 60 s simulated capture of the `errors` scenario (CRC errors, exceptions, timeouts, noise)."""
    if "errors" not in _CACHE:
        path = tmp_path_factory.mktemp("sim") / "errors.mcap"
        assert main(["simulate", "--out", str(path), "--scenario", "errors", "--duration", "60", "--seed", "5"]) == 0
        _CACHE["errors"] = path
    return _CACHE["errors"]


def _jsonl(capsys, *inputs, flags=()) -> list[str]:
    rc, out, err = _cli(capsys, "replay", *inputs, "--format", "jsonl", *flags)
    assert rc == 0, err
    return out.splitlines()


def _rotate(capsys, capture, folder, *flags) -> str:
    rc, _out, err = _cli(capsys, "replay", capture, "--quiet", "--out", folder, *flags)
    assert rc == 0, err
    return err


def _data_section(path) -> int:
    """Bytes before the summary of a finished MCAP (the footer's summary start)."""
    import struct

    with open(path, "rb") as fh:
        fh.seek(-8 - 20, os.SEEK_END)
        return struct.unpack("<Q", fh.read(8))[0]


def _index(folder) -> list[dict]:
    with open(os.path.join(folder, INDEX_NAME)) as fh:
        return json.load(fh)["segments"]


# ---------------------------------------------------------------- the flags
@pytest.mark.parametrize("values, want", [
    (["1h"], Rotate(3600 * 10**9, 0)), (["100MB"], Rotate(0, 100 * 10**6)),
    (["30m,2GB"], Rotate(1800 * 10**9, 2 * 10**9)),
    (["1d", "512MiB"], Rotate(86400 * 10**9, 512 * 2**20)), (["90s"], Rotate(90 * 10**9, 0)),
])
def test_rotate_takes_a_size_a_time_or_both(values, want):
    assert Rotate.parse(values) == want


@pytest.mark.parametrize("values, want", [
    (["7d"], Keep(7 * 86400 * 10**9, 0, 0)), (["20GB"], Keep(0, 20 * 10**9, 0)), (["48"], Keep(0, 0, 48)),
    (["12h", "1TB", "10"], Keep(12 * 3600 * 10**9, 10**12, 10)),
])
def test_keep_takes_an_age_a_size_or_a_count(values, want):
    assert Keep.parse(values) == want


@pytest.mark.parametrize("args, says", [
    (["--rotate", "1x"], "--rotate '1x': a size (100MB, 2GB) or a time (30m, 1h, 1d)"),
    (["--rotate", "10kB"], "--rotate 10kB: segments of at least 1MB (each carries its own schemas, channels and "
                           "index: tens of kB)"),
    (["--rotate", "64KiB"], "--rotate 64KiB: segments of at least 1MB (each carries its own schemas, channels and "
                            "index: tens of kB)"),
    (["--rotate", "1h", "--keep", "0"], "--keep 0: keep at least one segment"),
    (["--rotate", "1h", "--keep", "soon"], "--keep 'soon': an age (7d, 12h), a size (20GB) or a number of segments"),
    (["--keep", "7d"], "--keep needs --rotate (it deletes a rotated capture's oldest segments)"),
    (["--rotate", "1h"], "replay writes a capture again only as segments: give --rotate and --out FOLDER together "
                         "(one file: sniffer export --to mcap)"),
])
def test_bad_rotation_flags_are_one_line(capsys, capture, args, says):
    rc, _out, err = _cli(capsys, "replay", capture, *args)
    assert rc == 2 and err.strip() == f"sniffer: error: {says}"


def test_rotate_without_an_output_is_refused(capsys):
    rc, _out, err = _cli(capsys, "demo", "--headless", "--rotate", "1h", "--no-out")
    assert rc == 2
    assert err.strip() == "sniffer: error: --rotate writes the capture's MCAP as segments: not with --no-out"


# ---------------------------------------------------------------- segments
def test_segments_replay_alone_and_as_one_capture(capsys, capture, tmp_path):
    whole = _jsonl(capsys, capture)
    folder = tmp_path / "cab3"
    err = _rotate(capsys, capture, folder, "--rotate", "10s")
    index = _index(folder)
    assert len(index) == 6 and f"6 segments in {folder}" in err
    names = [s["file"] for s in index]
    assert names == sorted(names) and all(n.startswith("cab3-") for n in names)  # the names sort in time
    assert [s["seq"] for s in index] == [1, 2, 3, 4, 5, 6] and {s["state"] for s in index} == {"closed"}
    alone = []
    for seg in index:
        path = folder / seg["file"]
        with open(path, "rb") as fh:  # complete: the mcap library's indexed reader opens it (summary, footer)
            reader = make_reader(fh)
            assert reader.get_summary() is not None
            meta = {m.name: m.metadata for m in reader.iter_metadata()}
        extra = json.loads(meta["sniffer.capture"]["extra"])
        assert extra["segment"] == seg["seq"] and extra["capture_id"] == seg["capture_id"]
        assert json.loads(meta["sniffer.capture"]["baud"]) == 19200  # the capture's metadata in every segment
        lines = _jsonl(capsys, path)
        assert len(lines) == seg["frames"] > 0
        alone += lines
        recs = [json.loads(line) for line in lines]
        assert seg["t_start"] <= recs[0]["t"] and recs[-1]["t"] <= seg["t_end"]  # one clock: the capture's
    # cut where nothing was pending: each segment alone gives the frames the whole did, paired alike (what
    # needs history, a retry of a request in the segment before, is not seen alone)
    keys = ("t", "t_end", "raw", "role", "crc_ok", "latency_ms", "summary", "exception")
    assert [[json.loads(line)[k] for k in keys] for line in alone] == [[json.loads(line)[k] for k in keys]
                                                                        for line in whole]
    # the folder, its index and the files (in any order) replay as the one capture, numbered on
    assert _jsonl(capsys, folder) == whole
    assert _jsonl(capsys, folder / INDEX_NAME) == whole
    rc, out, err = _cli(capsys, "replay", folder, "--quiet", "--progress")
    assert rc == 0 and out == "" and "Traceback" not in err
    assert _jsonl(capsys, *[folder / n for n in reversed(names)]) == whole


def test_export_and_check_read_a_set(capsys, capture, tmp_path):
    folder = tmp_path / "set"
    _rotate(capsys, capture, folder, "--rotate", "15s")
    a, b = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    assert _cli(capsys, "export", capture, "--to", "jsonl", "--out", a)[0] == 0
    assert _cli(capsys, "export", folder, "--to", "jsonl", "--out", b)[0] == 0
    assert a.read_bytes() == b.read_bytes() and a.stat().st_size > 10_000
    golden = tmp_path / "golden.txt"
    assert _cli(capsys, "check", capture, "--golden", golden, "--update-golden")[0] == 0
    assert _cli(capsys, "check", folder, "--golden", golden)[0] == 0
    first = sorted(folder.glob("*.mcap"))[0]
    assert _cli(capsys, "check", first, "--golden", golden)[0] == 1  # a part differs from the whole


def test_size_rotation(capsys, tmp_path):
    sim = tmp_path / "stress.mcap"
    assert main(["simulate", "--out", str(sim), "--scenario", "stress", "--duration", "90"]) == 0
    folder = tmp_path / "bysize"
    _rotate(capsys, sim, folder, "--rotate", "1MB")
    index = _index(folder)
    assert len(index) >= 3
    # a segment closes at the first settled moment past the size (its summary and its open chunk counted):
    # its data section is at most that wait (up to 5 s on this line that is never quiet) over; the summary
    # repeats the channels (a Foxglove capture has one per register: 648 here)
    assert all(_data_section(folder / s["file"]) < 10**6 + 300_000 for s in index)
    assert all(s["bytes"] >= 10**6 for s in index[:-1])
    assert _jsonl(capsys, folder) == _jsonl(capsys, sim)


def test_keep_a_count_deletes_the_oldest(capsys, capture, tmp_path):
    folder = tmp_path / "k"
    _rotate(capsys, capture, folder, "--rotate", "10s", "--keep", "2")
    index = _index(folder)
    assert [s["seq"] for s in index] == [5, 6]
    assert sorted(p.name for p in folder.glob("*.mcap")) == [s["file"] for s in index]
    status = json.loads((folder / STATUS_NAME).read_text())
    assert status["segments"]["deleted"] == 4 and status["segments"]["count"] == 2
    # what is left replays; its first frame says a part of the capture is missing before it
    recs = [json.loads(line) for line in _jsonl(capsys, folder)]
    assert recs[0]["t"] >= 40 and recs[0]["index"] == 0


def test_keep_an_age_and_a_size(capsys, capture, tmp_path):
    folder = tmp_path / "age"
    _rotate(capsys, capture, folder, "--rotate", "10s", "--keep", "25s")
    index = _index(folder)
    end = index[-1]["end_ns"]
    assert all(end - s["end_ns"] <= 25 * 10**9 for s in index)  # every older segment went
    assert [s["seq"] for s in index] == [4, 5, 6]
    sizes = [s["bytes"] for s in _index(folder)]
    folder2 = tmp_path / "size"
    # room for the last three (the open one counts), and for the few bytes each segment's compressed metadata
    # differs by between two runs (the run's random capture id): the chunks themselves are the same
    limit = sum(sizes) + 10 * len(sizes)
    _rotate(capsys, capture, folder2, "--rotate", "10s", "--keep", f"{limit}B")
    kept = _index(folder2)
    assert sum(s["bytes"] for s in kept) <= limit and [s["seq"] for s in kept][-1] == 6 and len(kept) >= 3


def test_retention_never_deletes_the_open_segment():
    closed = [Segment(f"s{i}.mcap", i, end_ns=i * 10, bytes=100) for i in range(1, 6)]
    assert Keep(count=1).to_delete(closed, 100, open_bytes=50) == closed  # keep 1: the open one is it
    assert Keep(max_bytes=10).to_delete(closed, 100, open_bytes=50) == closed  # the open one alone is too big
    assert Keep(age_ns=55).to_delete(closed, 100) == closed[:4]
    assert Keep(count=3).to_delete(closed, 100, open_count=0) == closed[:2]  # the end: no open segment


def test_a_missing_segment_is_a_gap_and_frames_number_on(capsys, capture, tmp_path):
    folder = tmp_path / "hole"
    _rotate(capsys, capture, folder, "--rotate", "10s")
    index = _index(folder)
    os.remove(folder / index[2]["file"])
    recs = [json.loads(line) for line in _jsonl(capsys, folder)]
    assert [r["index"] for r in recs] == list(range(len(recs)))
    after = next(i for i, r in enumerate(recs) if r["t"] >= index[3]["t_start"])
    codes = [a["code"] for a in recs[after]["annotations"]]
    assert "source.gap" in codes
    assert sum("source.gap" in [a["code"] for a in r["annotations"]] for r in recs) == 1


def test_a_restart_into_the_same_folder_continues_it(capsys, capture, tmp_path):
    folder = tmp_path / "again"
    _rotate(capsys, capture, folder, "--rotate", "20s")
    _rotate(capsys, capture, folder, "--rotate", "20s")
    index = _index(folder)
    assert [s["seq"] for s in index] == [1, 2, 3, 4, 5, 6] and len({s["capture_id"] for s in index}) == 2
    whole = _jsonl(capsys, capture)
    recs = [json.loads(line) for line in _jsonl(capsys, folder)]
    assert len(recs) == 2 * len(whole)
    n = len(whole)
    assert [r["t"] for r in recs[:n]] == [json.loads(line)["t"] for line in whole]
    # one clock: the second capture after the first (a simulated one has no wall clock to place it by)
    assert min(r["t"] for r in recs[n:]) > max(r["t"] for r in recs[:n])
    second = recs[len(whole)]
    assert "source.gap" in [a["code"] for a in second["annotations"]]


def test_a_folder_is_written_by_one_capture_at_a_time(capsys, capture, tmp_path):
    from sniffer.formats.mcap.rotating import SegmentPlan

    plan = SegmentPlan(str(tmp_path / "busy"), Rotate(10**10))
    try:
        rc, _out, err = _cli(capsys, "replay", capture, "--out", tmp_path / "busy", "--rotate", "10s")
        assert rc == 2 and err.strip() == f"sniffer: error: {tmp_path / 'busy'}: another capture writes there " \
                                          f"(pid {os.getpid()})"
    finally:
        os.close(plan.lock_fd)
    (tmp_path / "file").write_text("x")
    rc, _out, err = _cli(capsys, "replay", capture, "--out", tmp_path / "file", "--rotate", "10s")
    assert rc == 2 and "exists and is not a folder" in err


def test_a_killed_segment_is_read_and_listed(capsys, capture, tmp_path):
    folder = tmp_path / "killed"
    _rotate(capsys, capture, folder, "--rotate", "20s")
    index = _index(folder)
    last = folder / index[-1]["file"]
    data = last.read_bytes()
    os.remove(last)
    (folder / (index[-1]["file"] + ".part")).write_bytes(data[: len(data) * 2 // 3])  # as a SIGKILL leaves it
    segs = read_index(str(folder))
    assert segs[-1].state == "killed" and segs[-1].extra["part"].endswith(".part")
    rc, out, err = _cli(capsys, "replay", folder, "--format", "jsonl")
    assert rc == 0 and "was not closed cleanly" in err and ".part" in err
    assert len(out.splitlines()) > sum(s["frames"] for s in index[:-1])
    # a capture started into the folder lists it as killed, and counts it (its retention may delete it)
    (folder / f"{INDEX_NAME}.tmp4242").write_text("{")  # killed while it rewrote the index
    _rotate(capsys, capture, folder, "--rotate", "30s")
    assert not list(folder.glob("*.tmp*"))
    assert [s["state"] for s in _index(folder)][:3] == ["closed", "closed", "killed"]


def _header_only(segment) -> bytes:
    """The first bytes of a real segment up to the end of its MCAP header record: what a writer killed just
    after it began a file leaves (magic, header; no capture info, no event)."""
    import struct

    data = segment.read_bytes()
    assert data[8] == 0x01  # the header record's opcode
    return data[: 8 + 9 + struct.unpack_from("<Q", data, 9)[0]]


@pytest.mark.parametrize("empty", ["part", "header-only", "both"])
def test_an_empty_or_header_only_segment_is_skipped_with_a_note(capsys, capture, tmp_path, empty):
    """SIGKILL right after a rotation leaves the next segment empty (or its header alone): `replay FOLDER`
    (and export, check) read the capture around it, with a note on stderr, not an error."""
    folder = tmp_path / "rotated"
    _rotate(capsys, capture, folder, "--rotate", "20s")
    index = _index(folder)
    want = _jsonl(capsys, folder)
    last = index[-1]["file"]
    seq = int(last[-10:-5])
    made = []
    if empty in ("part", "both"):  # the open segment a kill right after the rotation left: nothing written
        made.append(folder / last.replace(f"{seq:05d}.mcap", f"{seq + 1:05d}.mcap.part"))
        made[-1].write_bytes(b"")
    if empty in ("header-only", "both"):
        made.append(folder / last.replace(f"{seq:05d}.mcap", f"{seq + 2:05d}.mcap"))
        made[-1].write_bytes(_header_only(folder / last))
    listed = {seg.extra.get("part") or seg.file for seg in read_index(str(folder))}
    assert all(p.name in listed for p in made)  # the folder's segments, as a replay finds them
    rc, out, err = _cli(capsys, "replay", folder, "--format", "jsonl")
    assert rc == 0, err
    assert out.splitlines() == want  # every frame, nothing after them
    notes = [line for line in err.splitlines() if line.startswith("sniffer: note:")]
    assert len(notes) == len(made) and all(any(str(p) in n for n in notes) for p in made)
    assert all("holds nothing" in n for n in notes) and "error" not in err
    rc, _out, err = _cli(capsys, "export", folder, "--to", "jsonl", "--out", tmp_path / "all.jsonl")
    assert rc == 0 and "holds nothing" in err, err
    assert len((tmp_path / "all.jsonl").read_text().splitlines()) == len(want)


def test_an_empty_segment_alone_is_nothing_to_replay(capsys, capture, tmp_path):
    folder = tmp_path / "nothing"
    folder.mkdir()
    (folder / "nothing-19700101T000000Z-00001.mcap.part").write_bytes(b"")
    rc, _out, err = _cli(capsys, "replay", folder / "nothing-19700101T000000Z-00001.mcap.part")
    assert rc == 2 and err.count("\n") == 1 and "empty file" in err
    (folder / "nothing-19700101T000001Z-00002.mcap").write_bytes(b"\x89MCAP0\r\n")
    rc, _out, err = _cli(capsys, "replay", folder)
    assert rc == 2 and "holds anything recorded" in err and "Traceback" not in err


# ---------------------------------------------------------------- the status file
def test_status_counts_what_the_frames_say(capsys, capture, tmp_path):
    folder = tmp_path / "st"
    _rotate(capsys, capture, folder, "--rotate", "20s")
    status = json.loads((folder / STATUS_NAME).read_text())
    recs = [json.loads(line) for line in _jsonl(capsys, capture)]
    codes = [[a["code"] for a in r["annotations"]] for r in recs]
    assert status["state"] == "ended" and status["frames"] == len(recs)
    assert status["errors"]["crc"] == sum(r["crc_ok"] is False for r in recs) > 0
    assert status["errors"]["exceptions"] == sum(bool(r["exception"]) for r in recs) > 0
    assert status["errors"]["timeouts"] == sum("pair.no_response" in c or "pair.timeout" in c for c in codes) > 0
    assert status["errors"]["noise"] == sum(r["protocol"] == "noise" for r in recs) > 0
    assert status["last_frame"]["t"] == pytest.approx(recs[-1]["t"])
    assert status["segments"]["count"] == 3 and status["segments"]["open"] is None
    assert status["segments"]["bytes"] == sum(p.stat().st_size for p in folder.glob("*.mcap"))
    rc, out, _err = _cli(capsys, "status", folder)
    assert rc == 1  # ended
    lines = dict(line.split(None, 1) for line in out.splitlines())
    assert lines["capture"].endswith("ended (stopped, or the input ended)")
    assert f"crc {status['errors']['crc']}" in lines["errors"]
    assert lines["segments"].startswith(f"3 in {folder}") and "free on its disk" in lines["segments"]
    assert isinstance(status["segments"]["disk_free"], int) and status["segments"]["disk_free"] > 0


class _Triggers(Sink):
    """A sink contributing a section to the status, as the triggers do (a Sink: the session asks only Sinks
    for the hooks past start/raw/frame/close)."""

    def __init__(self) -> None:
        self.seen = 0

    def start(self, info) -> None:
        pass

    def raw(self, event) -> None:
        pass

    def frame(self, f) -> None:
        self.seen += f.crc_ok is False

    def close(self) -> None:
        pass

    def status(self) -> dict:
        return {"counter": {"fired": self.seen, "rules": {"crc": self.seen}}}


def test_a_sink_adds_its_section_and_status_shows_it(capsys, capture, tmp_path):
    from sniffer.commands.replay import file_source
    from sniffer.capture.session import Session

    path = tmp_path / "s.json"
    spec = CaptureSpec(input=str(capture), status=str(path))
    trig = _Triggers()
    Session(spec, file_source(spec), [trig]).run()
    d = json.loads(path.read_text())
    assert d["counter"] == {"fired": trig.seen, "rules": {"crc": trig.seen}} and trig.seen > 0
    d["state"], d["pid"] = "running", os.getpid()  # as a running capture's file reads
    d["updated_ns"] = __import__("time").time_ns()
    path.write_text(json.dumps(d))
    rc, out, _err = _cli(capsys, "status", path)
    assert rc == 0
    assert f"counter   fired {trig.seen}, rules.crc {trig.seen}" in out.splitlines()
    d["pid"] = 2**22 + 12345  # no such process: the capture is gone
    path.write_text(json.dumps(d))
    rc, out, _err = _cli(capsys, "status", path)
    assert rc == 1 and "not running: its process" in out
    rc, _out, err = _cli(capsys, "status", tmp_path / "nothing")
    assert rc == 2 and "no such file" in err


def test_set_settings_must_agree(capsys, capture, tmp_path):
    other = tmp_path / "fast.mcap"
    assert main(["simulate", "--out", str(other), "--scenario", "fast", "--duration", "2"]) == 0
    rc, _out, err = _cli(capsys, "replay", capture, other)
    assert rc == 2 and "replay them separately" in err and err.count("\n") == 1


def test_decode_capture_reads_a_folder(capsys, capture, tmp_path):
    folder = tmp_path / "dc"
    _rotate(capsys, capture, folder, "--rotate", "30s")
    spec = CaptureSpec(input=str(folder), inputs=(str(folder),))
    session = decode_capture(str(folder), spec)
    n = sum(1 for _ in session)
    assert n == len(_jsonl(capsys, capture)) and session.info.extra["set_files"] == 2
    shutil.rmtree(folder)


def test_the_capture_process_gets_the_unattended_flags():
    """The TUI and serve run the capture as a process of its own: its CaptureSpec goes to it whole."""
    from sniffer.cli import build_parser

    spec = CaptureSpec.from_args(build_parser().parse_args(
        ["live", "/dev/ttyUSB0", "--rotate", "1h", "--rotate", "200MB", "--keep", "14d,20GB", "--keep", "30",
         "--status", "/tmp/s.json", "--wait-port", "--out", "cab3"]))
    again = CaptureSpec.decode(spec.encode())
    assert (again.rotate, again.keep, again.status, again.wait_port, again.out) == \
           (spec.rotate, spec.keep, "/tmp/s.json", True, "cab3")
    assert spec.rotate == Rotate(3600 * 10**9, 200 * 10**6) and spec.keep == Keep(14 * 86400 * 10**9, 20 * 10**9, 30)


def test_a_multi_link_capture_rotates_and_replays_with_its_links(tmp_path):
    """Two links on one timeline (sniffer.capture.links), cut into segments: every frame keeps its link, a
    segment is cut only when both links are settled, and the folder replays as the whole did."""
    from helpers import ListSink, bursts, fr

    from sniffer.events import CaptureInfo, Chunk
    from sniffer.line import LineSettings
    from sniffer.capture.session import EventSource, Session
    from sniffer.formats.mcap.rotating import SegmentPlan

    line = LineSettings(19200, "E", 1)
    info = CaptureInfo(baud=19200, parity="E", links=[
        {"name": n, "ports": [f"/dev/{n}"], "tap": False, "baud": 19200, "parity": "E"} for n in ("A", "B")])
    events = []
    for i in range(300):  # 30 s: a transaction on each link every 100 ms, B 40 ms after A
        for link, off, pair in (("A", 0, ("010300000002", "01030400010002")),
                                ("B", 40, ("020400100001", "0204020007"))):
            for c in bursts([fr(h) for h in pair], line, t0=(i * 100 + off) * 10**6):
                events.append(Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", link))
    events.sort(key=lambda c: c.t_ns)

    def run(sinks, spec=None):
        source = EventSource(CaptureInfo.from_dict(info.to_dict()), iter(events))
        session = Session(spec or CaptureSpec(), source, sinks)
        session.run()
        assert session.error is None
        return session

    whole = ListSink()
    run([whole])
    folder = tmp_path / "links"
    rotate = Rotate(5 * 10**9)
    run([SegmentPlan(str(folder), rotate)], CaptureSpec(out=str(folder), rotate=rotate))
    index = _index(folder)
    # 1,200 frames; without ticks a link's last frame closes only with its next bytes: the cuts wait
    assert len(index) == 6 and sum(s["frames"] for s in index) == len(whole.records) == 1200
    assert all(0 <= s["t_end"] - 5 * (i + 1) < 5 for i, s in enumerate(index[:-1]))
    spec = CaptureSpec(input=str(folder), inputs=(str(folder),))
    again = [(f.link, f.raw.hex(), f.role, f.pair) for f in decode_capture(str(folder), spec)]
    assert again == [(r["link"], r["raw"], r["role"], r["pair"]) for r in whole.records]
    first = [f for f in decode_capture(str(folder / index[1]["file"]))]
    assert {f.link for f in first} == {"A", "B"} and all(f.crc_ok for f in first)
    status = json.loads((folder / "status.json").read_text())
    assert status["line"].startswith("A: 19200 8E1") and "; B: 19200 8E1" in status["line"]  # each link's


def test_status_names_each_lost_port_of_several_links(tmp_path):
    """Several links: the status says which adapters are away (here two of three), and since when."""
    import time
    from types import SimpleNamespace

    from sniffer.commands.status import lines
    from sniffer.capture.status import StatusSink

    now = time.monotonic_ns()
    readers = [SimpleNamespace(port="/dev/ttyUSB0", lost_since_ns=None),
               SimpleNamespace(port="/dev/ttyUSB1", lost_since_ns=now - 5 * 10**9, lost_reason="hang-up"),
               SimpleNamespace(port="/dev/ttyUSB2", lost_since_ns=now - 9 * 10**9, lost_reason="port path vanished")]
    said = []
    session = SimpleNamespace(source=SimpleNamespace(readers=readers), sinks=[], resolved=None, bytes_in=0)
    sink = StatusSink(str(tmp_path / "s.json"), session, "live A B C", announce=said.append)
    port = sink._port()
    assert port["state"] == "lost" and port["ports"] == ["/dev/ttyUSB1", "/dev/ttyUSB2"]
    assert port["reason"] == "port path vanished"  # the first to go
    text = dict(lines({"port": port}, "running"))["port"]
    assert text.startswith("/dev/ttyUSB1, /dev/ttyUSB2: lost since ") and text.endswith("(port path vanished)")


def test_port_notices_say_an_outage_shorter_than_a_look():
    """PortNotices looks every 50 ms: a port that went and came back between two looks is said too."""
    from types import SimpleNamespace

    from sniffer.capture.status import PortNotices

    said = []
    port = SimpleNamespace(port="/dev/ttyUSB0", lost_since_ns=None, lost_reason="", losses=0)
    notices = PortNotices(SimpleNamespace(readers=[port]), announce=said.append)
    notices.check()
    assert said == []
    port.lost_since_ns, port.lost_reason, port.losses = 123, "hang-up", 1
    notices.check()
    notices.check()
    assert said == ["/dev/ttyUSB0: port lost (hang-up); waiting for it to come back"]
    port.lost_since_ns = None
    notices.check()
    port.losses = 2  # away and back again before the next look
    notices.check()
    assert said[1:] == ["/dev/ttyUSB0: port back; capturing again",
                        "/dev/ttyUSB0: port lost (hang-up); waiting for it to come back",
                        "/dev/ttyUSB0: port back; capturing again"]


def test_a_segment_closed_for_its_size_holds_frames_not_only_its_own_records(tmp_path):
    """Each segment declares its registers' channels (twice: in its data and its summary): on a line polling
    thousands of registers those records alone fill a 1MB segment, so it is closed only once a quarter of
    it is messages (before: a new segment every half poll cycle, 6 % of it messages).  No flush by wall time:
    how many chunks a loaded machine cut changed the compressed sizes around the quarter."""
    from mcap.reader import make_reader

    from sniffer.events import CaptureInfo
    from sniffer.line import LineSettings
    from sniffer.capture.session import EventSource, Session
    from sniffer.formats.mcap.rotating import SegmentPlan
    from tests.helpers import bursts, fr

    line = LineSettings(115200, "N", 1)
    frames = []
    for k in range(1920):  # 6000 registers of unit 1 polled 125 at a time, 40 times: a channel each
        addr = (k % 48) * 125
        data = "".join(f"{(addr + i + k) & 0xFFFF:04X}" for i in range(125))
        frames += [fr(f"0103{addr:04X}007D"), fr("0103FA" + data)]
    info = CaptureInfo(baud=line.baud, parity=line.parity, stopbits=line.stopbits)
    size = 10**6
    # flushed as the writer fills its chunks (as replay and simulate write segments): the frames come as fast as
    # this process makes them, so a flush every wall-clock second would cut chunks by the machine's load (more
    # chunks, more message indexes: 249,881 bytes of messages against 250,000 on a loaded machine)
    Session(CaptureSpec(), EventSource(info, bursts(frames, line, gap_chars=40)),
            [SegmentPlan(str(tmp_path / "wide"), Rotate(max_bytes=size), timed_flush=False)]).run()
    index = _index(tmp_path / "wide")
    assert len(index) >= 3
    for s in index[:-1]:
        with open(tmp_path / "wide" / s["file"], "rb") as fh:
            summary = make_reader(fh).get_summary()
        assert sum(c.compressed_size for c in summary.chunk_indexes) >= size // 4


def _two_busy_links(path) -> str:
    """Two links of the default scenario read by USB adapters (per-read times): both busy, seldom quiet at once,
    so most segment cuts fall while a request waits on one link (and the merge holds frames of the other)."""
    from sniffer.capture.session import EventSource, Session
    from sniffer.events import CaptureInfo, Chunk
    from sniffer.formats import FileSink
    from sniffer.simulator import get_scenario, simulate, usb_chunks

    sc = get_scenario("default")
    events = sorted((Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", link)
                     for link, seed in (("a", 3), ("b", 4)) for c in usb_chunks(simulate(sc, sc.line, 40, seed))),
                    key=lambda c: c.t_ns)
    line = {"baud": sc.line.baud, "parity": sc.line.parity, "stopbits": sc.line.stopbits}
    info = CaptureInfo(**line, links=[{"name": "a", **line}, {"name": "b", **line}])
    Session(CaptureSpec(), EventSource(info, events), [FileSink("mcap", str(path), timed_flush=False)]).run()
    return str(path)


def _figures(records) -> dict:
    """Per link and unit: requests, responses, answers with a latency, orphan answers, unanswered requests."""
    from collections import Counter

    c = Counter()
    for x in map(json.loads, records):
        key = (x.get("link"), x.get("unit"))
        codes = {a["code"] for a in x["annotations"]}
        c[(*key, x["role"])] += x["role"] in ("request", "response")
        c[(*key, "latency")] += x.get("latency_ms") is not None
        c[(*key, "orphan")] += "pair.orphan_response" in codes
        c[(*key, "timeout")] += "pair.timeout" in codes
    return {k: v for k, v in c.items() if v}


def test_each_segment_of_busy_links_read_alone_has_the_whole_captures_figures(capsys, tmp_path):
    """A segment cut while a request waits (its answer in the next segment) records that request in its
    metadata: read alone (a fleet dataset takes segments in one by one), the next segment pairs the answer as
    the whole capture does, so the segments' figures add up to the whole capture's (an echo was a request of
    its own, an answer an orphan without latency)."""
    from sniffer.events import WAITING_KEY
    from sniffer.sources.files import FileSource

    folder = tmp_path / "F"
    _rotate(capsys, _two_busy_links(tmp_path / "two.mcap"), folder, "--rotate", "5s", "--jobs", "1")
    segments = sorted(str(p) for p in folder.glob("*.mcap"))
    carried = 0
    for seg in segments:
        src = FileSource(seg)
        carried += bool(src.open().extra.get(WAITING_KEY))
        src.close()
    assert len(segments) >= 6 and carried >= 2  # cuts that split an exchange: what the test is about
    whole = _figures(_jsonl(capsys, folder, flags=("--jobs", "1")))
    alone = _figures([r for seg in segments for r in _jsonl(capsys, seg, flags=("--jobs", "1"))])
    assert alone == whole


def test_a_file_replayed_into_segments_gives_the_same_segments_however_loaded_the_machine(capsys, capture, tmp_path):
    """Segments made from a file are written as their writer fills them, not every second of wall time: their
    chunks, sizes (what --rotate SIZE and --keep SIZE go by) and bytes depend on the capture alone.  The
    second replay's sink is flushed as if every call came a second later (a machine loaded to a crawl)."""
    import sniffer.formats.mcap.sink as mcap_sink

    _rotate(capsys, capture, tmp_path / "a", "--rotate", "10s")
    ticks = iter(range(0, 1 << 62, 10**9))
    old = mcap_sink.McapSink.__init__.__kwdefaults__["clock"]
    mcap_sink.McapSink.__init__.__kwdefaults__["clock"] = lambda: next(ticks)
    try:
        _rotate(capsys, capture, tmp_path / "b", "--rotate", "10s")
    finally:
        mcap_sink.McapSink.__init__.__kwdefaults__["clock"] = old
    from mcap.reader import make_reader

    def chunks(folder) -> list[list[tuple]]:
        """Each segment's chunks: (first, last message time, bytes before compression).  Their compressed bytes
        differ by the few the capture's random id takes (a run's own, in every segment's metadata)."""
        out = []
        for s in _index(folder):
            with open(folder / s["file"], "rb") as fh:
                idx = make_reader(fh).get_summary().chunk_indexes
            out.append([(c.message_start_time, c.message_end_time, c.uncompressed_size) for c in idx])
        return out

    a, b = chunks(tmp_path / "a"), chunks(tmp_path / "b")
    assert a == b and len(a) >= 5 and max(len(c) for c in a) >= 2
