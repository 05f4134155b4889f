"""Several links on one timeline, in time order (sniffer.capture.links: the merge), on synthetic events.

Three simulated lines at their own speeds, read as a USB adapter delivers them (per read, ticks between
the reads as the live reader sends them), merged by time into one event stream as the live source hands
it.  Every view gets the frames of all links in time order, numbered in that order; each link's frames
are what that link alone gives; the MCAP written on the way replays to the same records in the same
order.  A link that stalls holds the others no longer than the hold bound.
"""

from __future__ import annotations

import pytest
from helpers import ListSink, fr

from decoders.registry import default_registry
from sniffer.events import CaptureInfo, Chunk, Tick
from sniffer.line import LineSettings
from sniffer.capture.links import LinkPipelines
from sniffer.capture.pipeline import Pipeline
from sniffer.capture.session import CaptureSpec, EventSource, Session
from sniffer.simulator import get_scenario, simulate, usb_chunks, wire_chunks
from sniffer.formats.mcap.sink import McapSink
from sniffer.formats.mcap.reader import read_frames
from sniffer.sources.files import FileSource

LINES = {"drives": LineSettings(9600, "E", 1), "pumps": LineSettings(19200, "N", 2),
         "fans": LineSettings(38400, "N", 1)}
TICK_NS = 5_000_000  # the live reader's tick
MS = 1_000_000


def _link_events(name: str, line: LineSettings, seed: int, seconds: float, per_read: bool) -> list:
    """One link's events as its reader hands them: reads (or per-byte runs), a tick every TICK_NS between."""
    sent = list(simulate(get_scenario("default"), line, seconds, seed))
    if per_read:  # an adapter at latency 1 ms read on time (the pty simulator's and a tuned FTDI's)
        chunks = list(usb_chunks(sent, latency_timer_ms=1, seed=seed, hiccup_prob=0))
    else:
        chunks = list(wire_chunks(sent))
    out = []
    last = 0
    for c in chunks:
        out += [Tick(t, name) for t in range(last + TICK_NS, c.t_ns, TICK_NS)]
        out.append(Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, c.channel, name))
        last = c.t_ns
    return out + [Tick(last + k * TICK_NS, name) for k in range(1, 400)]


def _merged(per_read: bool, seconds: float = 4.0) -> tuple[CaptureInfo, list]:
    events = []
    for seed, (name, line) in enumerate(LINES.items(), 1):
        events += _link_events(name, line, seed, seconds, per_read)
    events.sort(key=lambda e: e.t_ns)  # one queue, stamped under one lock: the live source's order
    info = CaptureInfo(time_source="read" if per_read else "byte", links=[
        {"name": n, "ports": [f"/dev/{n}"], "baud": ln.baud, "parity": ln.parity, "stopbits": ln.stopbits}
        for n, ln in LINES.items()])
    return info, events


def _alone(name: str, info: CaptureInfo, events: list) -> list:
    """The frames one link gives when its events run through a pipeline of their own."""
    line = LINES[name]
    p = Pipeline(CaptureInfo(baud=line.baud, parity=line.parity, stopbits=line.stopbits,
                             time_source=info.time_source), line, default_registry())
    out = []
    for ev in events:
        if ev.link == name:
            out += p.feed(ev)
    return out + p.finish()


def _view(records):
    """A link's frames as a list of what they say, pairs as positions within the link (numbers differ)."""
    pos = {r["index"]: k for k, r in enumerate(records)}
    return [(r["t"], r["raw"], r["role"], r["latency_ms"], pos.get(r["pair"]),
             [a["code"] for a in r["annotations"]]) for r in records]


@pytest.mark.parametrize("per_read", [True, False], ids=["per-read", "per-byte"])
def test_frames_of_every_link_go_out_in_time_order_in_every_view(tmp_path, per_read):
    info, events = _merged(per_read)
    sink = ListSink()
    out = tmp_path / "three.mcap"
    session = Session(CaptureSpec(), EventSource(info, events), [sink, McapSink(out)])
    yielded = list(session)
    recs = sink.records
    assert session.error is None and len(recs) > 600 and {r["link"] for r in recs} == set(LINES)
    times = [r["t"] for r in recs]
    assert times == sorted(times)  # never a step back: no negative Δt between two frames of any links
    assert [r["index"] for r in recs] == list(range(len(recs)))  # numbers follow the order out
    assert [f.index for f in yielded] == [r["index"] for r in recs]  # the session's stream is the sinks' order
    by_index = {r["index"]: r for r in recs}
    assert all(by_index[r["pair"]]["link"] == r["link"] for r in recs if r["pair"] is not None)
    # each link's frames are what that link alone gives (the merge delays, it never changes a frame)
    from sniffer.formats.records import frame_record

    for name in LINES:
        alone = [frame_record(f, 0) for f in _alone(name, info, events)]
        assert _view([r for r in recs if r["link"] == name]) == _view(alone)
    # the MCAP has them in the same order, and replays to the same records in the same order
    assert read_frames(str(out)) == recs
    replay = ListSink()
    Session(CaptureSpec(), FileSource(str(out)), [replay]).run()
    assert replay.records == recs


def test_a_rotated_capture_replays_from_its_folder_in_the_order_it_went_out(tmp_path):
    """`live ... --rotate` then `replay FOLDER`: the JSONL written live, the segments replayed one after the other
    and the folder's replay are the same frames in the same (time) order."""
    import io
    import json

    from sniffer.formats.mcap.segments import Rotate, read_index
    from sniffer.formats.jsonl import JsonlSink
    from sniffer.formats.mcap.rotating import SegmentPlan
    from sniffer.sources.segset import capture_source

    info, events = _merged(per_read=True, seconds=6.0)
    folder, rotate, jsonl = tmp_path / "three", Rotate(2 * 10**9), io.BytesIO()
    spec = CaptureSpec(out=str(folder), rotate=rotate)
    live = Session(spec, EventSource(info, events), [JsonlSink(jsonl), SegmentPlan(str(folder), rotate)])
    live.run()
    recs = [json.loads(line) for line in jsonl.getvalue().splitlines()]
    assert live.error is None and len(recs) > 900
    assert [r["t"] for r in recs] == sorted(r["t"] for r in recs)
    assert [r["index"] for r in recs] == list(range(len(recs)))
    segments = read_index(str(folder))
    assert len(segments) >= 3
    # a segment is compact (no /frames: sniffer.formats.mcap.sink): each replays alone to its share of the frames,
    # in order (numbered from its own first frame)
    assert all(read_frames(str(folder / s.file)) == [] for s in segments)
    alone = []
    for s in segments:
        one = ListSink()
        Session(CaptureSpec(), FileSource(str(folder / s.file)), [one]).run()
        alone += one.records
    key = [(r["t"], r["raw"], r.get("channel")) for r in recs]
    assert [(r["t"], r["raw"], r.get("channel")) for r in alone] == key
    replay = ListSink()
    Session(CaptureSpec(), capture_source(str(folder)), [replay]).run()
    assert replay.records == recs


def _drive(lp: LinkPipelines, events) -> list[tuple[int, object]]:
    """(capture clock when it went out, frame) of every frame, the flush's at the last event's time."""
    out = []
    for ev in events:
        out += [(ev.t_ns, f) for f in lp.feed(ev)]
    return out + [(events[-1].t_ns, f) for f in lp.flush()]


def _two_links(line: LineSettings):
    from sniffer.capture.settings import CaptureSpec as Spec

    info = CaptureInfo(time_source="byte", links=[{"name": n, "ports": [f"/dev/{n}"], "baud": line.baud,
                                                   "parity": line.parity} for n in ("a", "b")])
    resolved = {n: Spec().resolve_link(n, info) for n in ("a", "b")}
    return info, resolved


def _per_byte(t: int, hexstr: str, link: str, line: LineSettings) -> Chunk:
    data = bytes.fromhex(hexstr)
    return Chunk(t, data, tuple(t + i * line.char_ns for i in range(len(data))), (), "", link)


def test_a_link_that_stalls_holds_the_others_no_longer_than_the_hold_bound():
    """Link a's reader stops in the middle of a frame (no byte, no tick comes any more): link b's frames wait
    for it at most hold_ns of capture time, then go on without waiting; a's frame goes out when it comes."""
    line = LineSettings(19200, "E", 1)
    info, resolved = _two_links(line)
    sink = ListSink()
    lp = LinkPipelines(info, resolved, [sink])
    req, rsp = fr("010300000002"), fr("01030400010002")
    events = [_per_byte(0, req[:8], "a", line)]  # half a request, then a's reader is gone
    t = 1 * MS
    while t < 3 * lp.hold_ns:  # b polls every 50 ms, answered after 10 ms, ticks between
        events += [_per_byte(t, req, "b", line), Tick(t + 6 * MS, "b"), _per_byte(t + 10 * MS, rsp, "b", line),
                   Tick(t + 16 * MS, "b")]
        t += 50 * MS
    sent = _drive(lp, events)
    b = [(when, f) for when, f in sent if f.link == "b"]
    assert len(b) == len(events) // 2 and all(f.crc_ok for _, f in b)
    waits = [when - f.t_ns for when, f in b]
    assert max(waits) <= lp.hold_ns + 50 * MS  # held until the bound, never longer
    assert max(waits[len(waits) // 2:]) < 50 * MS  # and once a is stalled, b no longer waits for it
    assert [f.link for _, f in sent][-1] == "a"  # a's bytes, flushed at the end, go out last (late)
    assert lp.hold_ns <= 10 * 10**9


def test_the_hold_bound_covers_a_healthy_links_longest_wait():
    """A request that waits its whole response timeout for an answer that never comes holds the other link's
    frames in order: a healthy link never meets the bound."""
    line = LineSettings(19200, "E", 1)
    info, resolved = _two_links(line)
    sink = ListSink()
    lp = LinkPipelines(info, resolved, [sink])
    timeout_ns = int(resolved["a"].timeout_ms * MS)
    events = [_per_byte(0, fr("050300000002"), "a", line)]  # to a unit that never answers
    t = 1 * MS
    while t < timeout_ns + 500 * MS:
        events += [_per_byte(t, fr("010300000002"), "b", line), Tick(t + 6 * MS, "b"),
                   _per_byte(t + 10 * MS, fr("01030400010002"), "b", line), Tick(t + 16 * MS, "b")]
        if t > 20 * MS:
            events.append(Tick(t + 17 * MS, "a"))  # a's reader ticks on: the timeout settles the request
        t += 50 * MS
    events.sort(key=lambda e: e.t_ns)
    sent = _drive(lp, events)
    frames = [f for _, f in sent]
    assert [f.t_ns for f in frames] == sorted(f.t_ns for f in frames)
    assert frames[0].link == "a" and "pair.timeout" in [a.code for a in frames[0].annotations]
    assert [f.index for f in frames] == list(range(len(frames)))
