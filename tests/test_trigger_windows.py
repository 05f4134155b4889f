"""Trigger windows written as MCAP and read back: synthetic polls with exceptions at known times.

A master polls unit 1 every 100 ms (request at k * 100 ms, answer 10 ms later, a silence tick at 50 ms
as a live source gives); at chosen polls the unit answers with an exception instead.  The session runs
with `--trigger exc --pre 5s --post 3s`, and each window file is read back: its frames are exactly
the capture's frames from the last quiet point at or before `trigger - pre` to `last match + post`,
its replay gives those frames again, and its metadata names the rule, the frame and the spans.
"""

import pytest
from helpers import ListSink, fr, frames_of

from sniffer.events import CaptureInfo, Chunk, Tick
from sniffer.line import LineSettings
from sniffer.capture.session import CaptureSpec, EventSource, Session
from sniffer.formats.mcap.reader import open_mcap
from sniffer.triggers import TriggerSpec, read_trigger
from sniffer.triggers.ring import FRAME, RAW, Ring

S = 1_000_000_000
MS = 1_000_000
LINE = LineSettings(19200, "E", 1)
WALL = 1_764_000_000 * S
REQ = bytes.fromhex(fr("010300000001"))
RSP = bytes.fromhex(fr("0103020007"))
EXC = bytes.fromhex(fr("018302"))


def _burst(t: int, data: bytes) -> Chunk:
    return Chunk(t, data, tuple(t + i * LINE.char_ns for i in range(len(data))))


def polls(n: int, exceptions: set[int]) -> list[Chunk]:
    out = []
    for k in range(n):
        t = k * 100 * MS
        out.append(_burst(t, REQ))
        out.append(_burst(t + 10 * MS, EXC if k in exceptions else RSP))
        out.append(Tick(t + 50 * MS))  # the line is quiet: a live source ticks (and the framer closes)
    return out


def run(tmp_path, events, **trigger):
    trigger.setdefault("pre_s", 5.0)
    trigger.setdefault("post_s", 3.0)
    spec = CaptureSpec(trigger=TriggerSpec(tuple(trigger.pop("rules", ("exc",))), windows=str(tmp_path), **trigger))
    info = CaptureInfo(source="synthetic", baud=LINE.baud, parity=LINE.parity, stopbits=LINE.stopbits,
                       time_source="byte", t0_ns=0, wall_anchor_ns=WALL)
    everything = ListSink()
    lines = []
    session = Session(spec, EventSource(info, events), [everything])
    session.open()
    session.sinks[-1].report = lines.append
    session.run()
    assert session.error is None
    return everything.records, sorted(tmp_path.glob("*.mcap")), lines


def _between(records, lo_s, hi_s):
    return [(r["t"], r["raw"]) for r in records if lo_s - 1e-9 <= r["t"] <= hi_s + 1e-9]


def test_each_window_holds_its_frame_and_exactly_the_pre_and_post_spans(tmp_path):
    records, files, lines = run(tmp_path, polls(1300, {300, 310, 1200}))
    assert [f.name for f in files] == ["sniffer.trigger-0001.mcap", "sniffer.trigger-0002.mcap"]
    # window 1: exception at 30.01 s, another at 31.01 s (same rule: the window grows to 31.01 + 3)
    m = read_trigger(str(files[0]))
    assert m["rules"] == ["exc"] and m["matches"] == {"exc": 2} and m["firings_total"] == 1
    first = m["firings"][0]
    assert first["t"] == pytest.approx(30.01) and first["record"]["exception"]["code"] == 2
    assert first["time"].startswith("2025-11-24T") and "fc83" in first["summary"]
    assert m["trigger_t"] == pytest.approx(30.01) and m["asked_start_t"] == pytest.approx(25.01)
    assert m["start_t"] == pytest.approx(25.0)  # the request before: the last quiet point before t - pre
    assert m["end_t"] == pytest.approx(34.01) and m["pre_complete"] and m["post_complete"]
    got = [(r["t"], r["raw"]) for r in frames_of(files[0])]
    assert got == _between(records, 25.0, 34.01)
    assert (pytest.approx(30.01), EXC.hex()) in got and got[-1] == (pytest.approx(34.01), RSP.hex())
    # window 2: one exception at 120.01 s
    m2 = read_trigger(str(files[1]))
    assert (m2["start_t"], m2["end_t"]) == (pytest.approx(115.0), pytest.approx(123.01))
    assert [(r["t"], r["raw"]) for r in frames_of(files[1])] == _between(records, 115.0, 123.01)
    assert sum("trigger 'exc' at 30.010 s" in x for x in lines) == 1 and any("window " in x for x in lines)


def test_a_window_replays_alone_to_the_frames_it_holds(tmp_path):
    records, files, _ = run(tmp_path, polls(600, {300}))
    info, events = open_mcap(str(files[0]))
    assert info.extra["trigger"]["rule"] == "exc" and info.baud == LINE.baud and info.t0_ns == 0
    replayed = ListSink()
    Session(CaptureSpec(), EventSource(info, events), [replayed]).run()
    m = read_trigger(str(files[0]))
    held = [r for r in records if m["start_t"] - 1e-9 <= r["t"] <= m["end_t"] + 1e-9]  # the capture's, in its span
    assert [(r["t"], r["raw"], r["role"]) for r in replayed.records] == [(r["t"], r["raw"], r["role"]) for r in held]
    assert replayed.records[0]["role"] == "request"  # starts where nothing was pending: no orphan answer


def test_two_rules_in_one_window_are_both_recorded(tmp_path):
    records, files, _ = run(tmp_path, polls(700, {300, 320}), rules=("exc", "u:1 rate(exc) >= 2/5s"))
    assert len(files) == 1
    m = read_trigger(str(files[0]))
    assert m["rules"] == ["exc", "u:1 rate(exc) >= 2/5s"]
    assert [f["t"] for f in m["firings"]] == [pytest.approx(30.01), pytest.approx(32.01)]
    # two exceptions within 5 s from the second (32.01) while the first is younger than 5 s: every frame
    # of unit 1 before 35.01 matches, the last the request at 35.0; the window ends post after it
    assert m["end_t"] == pytest.approx(35.0 + 3)
    assert m["matches"]["u:1 rate(exc) >= 2/5s"] == sum(1 for r in records if 32.01 - 1e-9 <= r["t"] < 35.01)


def test_a_capture_that_starts_or_ends_inside_the_spans_says_so(tmp_path):
    records, files, _ = run(tmp_path, polls(50, {20}))
    m = read_trigger(str(files[0]))
    assert not m["pre_complete"] and m["start_t"] == 0.0 and not m["post_complete"]
    assert [(r["t"], r["raw"]) for r in frames_of(files[0])] == _between(records, 0, 5.01)


def test_a_restarted_capture_numbers_its_windows_on(tmp_path):
    run(tmp_path, polls(200, {50}))
    _, files, _ = run(tmp_path, polls(200, {50}))
    assert [f.name for f in files] == ["sniffer.trigger-0001.mcap", "sniffer.trigger-0002.mcap"]


def test_the_ring_drops_old_blocks_and_keeps_under_its_byte_bound():
    ring = Ring(keep_ns=10 * S, max_bytes=1 << 20)
    blob = bytes(range(256)) * 64  # 16 KiB, poorly compressible enough
    import os
    for i in range(2000):
        ring.add(RAW if i % 2 else FRAME, i * 10 * MS, i * 10 * MS, os.urandom(2048) + blob[:64])
    times = [t for _, t, _, _ in ring.records()]
    assert times == sorted(times) and times[-1] == 1999 * 10 * MS
    assert times[0] >= (1999 * 10 - 10_000) * MS - 2 * S  # whole blocks go: at most a block older than keep
    assert ring.nbytes <= 1 << 20
    small = Ring(keep_ns=3600 * S, max_bytes=1 << 20)
    for i in range(2000):
        small.add(RAW, i * MS, i * MS, os.urandom(2048))
    assert small.nbytes <= 1 << 20 and small.cut_ns is not None and small.first_ns > 0


def test_the_sink_reports_its_triggers_for_a_status_file(tmp_path):
    spec = CaptureSpec(trigger=TriggerSpec(("exc",), pre_s=5.0, post_s=3.0, windows=str(tmp_path)))
    info = CaptureInfo(source="synthetic", baud=LINE.baud, parity=LINE.parity, stopbits=LINE.stopbits,
                       time_source="byte", t0_ns=0, wall_anchor_ns=WALL)
    session = Session(spec, EventSource(info, polls(400, {100, 300})), [])
    session.open()
    sink = session.sinks[-1]
    sink.report = lambda text: None
    session.run()
    st = sink.status()["triggers"]
    assert (st["fired"], st["windows"], st["open"], st["failed_windows"]) == (2, 2, 0, 0)
    assert st["last"]["rule"] == "exc" and st["last"]["t"] == pytest.approx(30.01)
    assert st["last"]["window"].endswith("sniffer.trigger-0002.mcap")
    # the windows' bytes, and the line's bytes they hold: each window 8 s of polls, a request and an answer
    # (8 and 7 bytes, or 5 for an exception) every 100 ms, the read that starts a window's span added
    files = sorted(tmp_path.glob("*.mcap"))
    assert st["window_bytes"] == sum(f.stat().st_size for f in files)
    assert 2 * 81 * 15 - 4 <= st["window_line_bytes"] <= 2 * 82 * 15


def test_the_trigger_flags_travel_to_a_capture_process_unchanged():
    """live with the TUI and serve start the capture as a process of its own, its CaptureSpec whole."""
    from sniffer.cli import build_parser

    argv = ["live", "/dev/ttyUSB0", "--trigger", "fault", "--trigger", 'u:1 "Output frequency" > 55',
            "--pre", "90s", "--post", "2min", "--ring", "--ring-max", "8MiB", "--max-window", "30m",
            "--windows", "/tmp", "--on-trigger", "echo $SNIFFER_TRIGGER_FILE", "--on-trigger-timeout", "5"]
    spec = CaptureSpec.from_args(build_parser().parse_args(argv))
    assert spec.trigger == TriggerSpec(("fault", 'u:1 "Output frequency" > 55'), 90.0, 120.0, True, 8 << 20,
                                       1800.0, "/tmp", "echo $SNIFFER_TRIGGER_FILE", 5.0)
    again = CaptureSpec.decode(spec.encode())
    assert again.trigger == spec.trigger


def test_a_window_that_cannot_be_written_is_one_line_and_the_capture_goes_on(tmp_path):
    folder = tmp_path / "windows"
    folder.mkdir()

    def events():
        for i, ev in enumerate(polls(600, {300, 500})):
            if i == 100:
                folder.rmdir()  # the folder went away (an unmounted stick): the next window has nowhere to go
            if i == 1400:
                folder.mkdir()  # it is back before the second event
            yield ev

    spec = CaptureSpec(trigger=TriggerSpec(("exc",), pre_s=5.0, post_s=3.0, windows=str(folder)))
    info = CaptureInfo(source="synthetic", baud=LINE.baud, parity=LINE.parity, stopbits=LINE.stopbits,
                       time_source="byte", t0_ns=0)
    everything, lines = ListSink(), []
    session = Session(spec, EventSource(info, events()), [everything])
    session.open()
    session.sinks[-1].report = lines.append
    session.run()
    assert session.error is None and len(everything.records) == 1200
    errors = [x for x in lines if x.startswith("error:")]
    assert len(errors) == 1 and "sniffer.trigger-0001.mcap not written" in errors[0]
    assert [f.name for f in folder.glob("*.mcap")] == ["sniffer.trigger-0002.mcap"]
    assert session.sinks[-1].status()["triggers"]["failed_windows"] == 1
