"""The byte view (tab 6) under Pilot: reads from a replay in this process and from a capture published on a real
socket, frame boundaries inside them, and the way between a frame in the list and its bytes."""

import asyncio
import threading
import time

from serve_helpers import published
from tui_helpers import SIM, demo_viewer, filled_sink, frames_from_reads, replay_frames, replay_reads

from decoders.registry import default_registry
from sniffer.processes.attach import Attachment, attach_feed
from sniffer.events import Chunk
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.analysis.reads import Read
from sniffer.capture.session import CaptureSpec, Session
from sniffer.processes.publish_sink import PublishSink
from sniffer.sources.files import FileSource, open_replay
from sniffer.processes.stream import CONTROL_PREFIX, parse_reads
from sniffer.tui.app import SnifferApp
from sniffer.tui.byteview import PREFIX, header
from sniffer.tui.run import session_app
from sniffer.tui.sink import TuiSink

SIZE = (140, 45)
HANG_S = 60  # a bound on waiting for something that should happen, never an assertion on speed


def make_app(name="errors.mcap") -> SnifferApp:
    return SnifferApp(filled_sink(name), None, source_label=name, registry=replay_frames(name)[2],
                      clock=lambda: 0.0)


async def until(pilot, cond) -> None:
    deadline = time.monotonic() + HANG_S
    while not cond():
        assert time.monotonic() < deadline, "gave up waiting"
        await pilot.pause(0.05)


def line_text(app, seq: int, part: int = 0) -> str:
    bv = app.byte_view
    return bv.format_line(seq, part, bv._layout[1]).plain


def test_a_frame_selected_in_the_list_shows_its_bytes_and_enter_goes_back():
    reads = replay_reads()
    # a frame that begins in one read and ends in the next (the USB adapter split it)
    split = next(r for r in reads if r.cont and r.marks[0][1] > 3)
    index = split.marks[0][1]

    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.pause()
            assert app.reads.reads == reads
            await pilot.press("home", *["down"] * index)
            f = app.selected_frame
            assert f.index == index
            await pilot.press("6")
            bv = app.byte_view
            assert app.tabs.active == "bytes" and app.focused is bv
            seq = bv.cursor
            r = app.reads.get(seq)
            assert bv.frame == index and app.reads.get(seq + 1) == split  # the read its first byte is in
            start, end = r.span_of(index)
            assert start in r.starts() and r.data[start:] + split.data[:split.span_of(index)[1]] == f.raw
            text = line_text(app, seq)
            assert "│" + r.data[start:start + 1].hex() in text and f"#{index}" in text.split("→")[1]
            assert f"frame #{index}: read {seq}" in str(app.query_one("#bytesnote").render())
            await pilot.press("right")  # the next frame
            assert bv.frame == index + 1 and app.reads.find(index + 1) == bv.cursor
            await pilot.press("y")  # copies the byte view's frame
            assert app.clipboard == app.store.frame(app.store.row_of[index + 1]).raw.hex()
            await pilot.press("enter")  # back to the list, on that frame
            assert app.tabs.active == "frames" and app.focused is app.frame_list
            assert app.selected_frame.index == index + 1
            await pilot.press("6", "down")  # the next read; its first frame that begins there is selected
            nxt = app.reads.get(bv.cursor)
            assert bv.cursor == app.reads.find(index + 1) + 1
            begins = [i for p, i in nxt.marks if p or not nxt.cont]
            assert bv.frame == (begins[0] if begins else nxt.marks[0][1])
            await pilot.press("end")  # the newest read, followed
            assert bv.cursor == app.reads.end_seq - 1 and bv.follow
            await pilot.press("1", "e", "home", "6")  # errors only: the byte view shows every read
            store = app.store
            chosen = next(i for i in app.reads.get(bv.cursor).frames if store.pos_of_row(store.row_of[i]) is None)
            bv.show_frame(chosen)
            await pilot.press("enter")
            assert app.tabs.active == "bytes" and "filtered out" in str(list(app._notifications)[-1].message)
    asyncio.run(go())


def test_a_byte_csv_replay_shows_each_read_its_gap_and_where_frames_begin(tmp_path):
    """A known capture through the real path (Session on the feed thread, the TuiSink marks the reads): a
    request split across two USB reads, a response and the next request glued into one."""
    reads = [(0.010, "01030000"), (0.012, "0002c40b"), (0.030, "010304000100022a32" "010300000002c40b"),
             (0.050, "010304000100022a32")]
    path = tmp_path / "line.bytes.csv"
    path.write_text("t_s,channel,byte_hex,flags\n" + "".join(
        f"{t:.6f},,{h[k:k + 2]},\n" for t, h in reads for k in range(0, len(h), 2)))
    sink = TuiSink()
    session = Session(CaptureSpec.of(baud=9600, parity="N"), FileSource(str(path)), [sink])
    session.open()

    async def go():
        app = session_app(session, sink)
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: app.caught_up and len(app.reads) == 4)
            app.poll()
            await pilot.press("6")
            got = app.reads.reads
            assert [(r.data.hex(), r.marks, r.cont) for r in got] == [
                ("01030000", ((0, 0),), False), ("0002c40b", ((0, 0),), True),
                ("010304000100022a32010300000002c40b", ((0, 1), (9, 2)), False),
                ("010304000100022a32", ((0, 3),), False)]
            assert [f.role for f in app.store.frames] == ["request", "response", "request", "response"]
            # 9600 8N1: a character is 10 bits, 1.0417 ms
            assert "   2.000ms    1.9ch    4" in line_text(app, 1)
            assert "  18.000ms   17.3ch   17" in line_text(app, 2)
            assert line_text(app, 2).count("│") == 2  # two frames begin in the glued read
            assert "│01 03 04" in line_text(app, 2) and "│01 03 00 00" in line_text(app, 2)
            assert "→ #1 #2" in line_text(app, 2) and "→ #0" in line_text(app, 1)
            await pilot.press("up", "up", "enter")  # the split read: Enter goes to the request it belongs to
            assert app.tabs.active == "frames" and app.selected_frame.index == 0
            await pilot.press("q")
    asyncio.run(go())


def reads_of(att: Attachment) -> list:
    """Every read a viewer gets until the capture ends."""
    out = []
    for lines in att.batches():
        for line in lines:
            if line.startswith(CONTROL_PREFIX):
                msg = att.control(line)
                if msg.get("sniffer") == "reads":
                    out += parse_reads(msg, att.info.t0_ns)
    att.close()
    return out


def test_an_attached_viewer_gets_the_reads_through_the_socket(tmp_path):
    """`sniffer attach --tui` as it builds its App: the reads come marked on the stream; a viewer joining late
    gets the reads kept so far, then the rest."""
    sock = str(tmp_path / "bytes.sock")
    info, events = open_replay(str(SIM / "errors.mcap"))
    events = list(events)
    pub = PublishSink(sock, label="errors.mcap", backlog=50)
    p = Pipeline(info, LineSettings(info.baud, info.parity or "N", info.stopbits or 1),
                 default_registry(info.devices), [pub], protocol=info.protocol)
    early = Attachment(sock)
    late: dict = {}

    def feed():
        half = len(events) // 2
        for ev in events[:half]:
            p.feed(ev)
        deadline = time.monotonic() + HANG_S
        while published(sock) < p.frames_out and time.monotonic() < deadline:  # published so far
            time.sleep(0.02)
        late["att"] = att = Attachment(sock)
        late["thread"] = t = threading.Thread(target=lambda: late.setdefault("reads", reads_of(att)), daemon=True)
        t.start()
        for ev in events[half:]:
            p.feed(ev)
        p.finish()

    feeder = threading.Thread(target=feed, daemon=True)
    expected = replay_reads("errors.mcap")

    async def go():
        app = SnifferApp(TuiSink(), attach_feed(early), source_label=early.label, clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            feeder.start()
            await until(pilot, lambda: app.caught_up and app.sink.info is not None)
            app.poll()
            await pilot.pause()
            assert app.reads.reads == expected  # the same reads, marks and times as in this process
            await pilot.press("home", "down", "down", "6")
            assert app.byte_view.frame == 2 and 2 in app.reads.get(app.byte_view.cursor).frames
            assert "│" in line_text(app, app.byte_view.cursor)
            await pilot.press("enter")
            assert app.selected_frame.index == 2
    asyncio.run(go())
    feeder.join(HANG_S)
    late["thread"].join(HANG_S)
    att = late["att"]
    assert att.earlier_frames > 0 and 0 < att.header["backlog_reads"] < len(expected)
    assert late["reads"] == expected  # the reads kept (all of them: fewer than RING_READS), then the rest


def test_reads_a_viewer_never_got_are_said_lost_not_a_gap():
    async def go():
        sink = filled_sink()
        reads = sink.drain_reads()
        sink.reads(reads[:10] + reads[12:])  # a viewer that fell behind had two reads dropped
        app = SnifferApp(sink, None, clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.press("6")
            lost = len(reads[10].data) + len(reads[11].data)
            assert f"{lost}B lost" in line_text(app, 10) and "ms" not in line_text(app, 10).split("B lost")[0]
            assert "ms" in line_text(app, 9) and "ms" in line_text(app, 11)
    asyncio.run(go())


def test_a_read_after_the_reader_stalled_is_marked_in_the_gap_columns():
    async def go():
        sink = filled_sink()
        reads = sink.drain_reads()
        r = reads[10]
        reads[10] = Read(r.t_ns, r.offset, r.data, r.marks, r.cont, r.last_ns, r.channel, r.link, 60_000_000)
        sink.reads(reads)
        app = SnifferApp(sink, None, clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.press("6")
            chars = slice(27, 35)  # "   time(12) gap(10) chars(8) len(4)  bytes"
            stalled, normal = line_text(app, 10), line_text(app, 11)
            assert stalled[chars].strip() == "stall" and stalled[17:27].strip().endswith("ms")
            assert normal[chars].strip().endswith("ch") and line_text(app, 9)[chars].strip().endswith("ch")
            assert header(app.byte_view._layout[1]).index("bytes") == PREFIX  # the columns line up, stall or not
            for seq in (9, 10, 11):
                assert int(line_text(app, seq)[PREFIX + 1:PREFIX + 3], 16) == reads[seq].data[0]
    asyncio.run(go())


def test_the_live_demo_sends_its_reads_from_the_capture_process(tmp_path):
    """`sniffer demo` on a terminal: the capture a process of its own (a pty bus, the MCAP), the TUI attached;
    the byte view's reads are the reads the capture recorded, each byte marked with the frame it went to."""
    async def go(app):
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: app.caught_up and len(app.store) == app.sink.frames_in)
            app.poll()
            await pilot.press("6")
            assert app.feed_error is None and len(app.reads) > 20
            await pilot.press("q")

    with demo_viewer(tmp_path, "errors", 1.5) as viewer:
        asyncio.run(go(viewer.app))
    assert viewer.rc() == 0
    app = viewer.app
    _, events = open_replay(str(tmp_path / "d.mcap"))
    recorded = [ev for ev in events if type(ev) is Chunk]
    assert [(r.t_ns, r.data) for r in app.reads.reads] == [(c.t_ns, c.data) for c in recorded]
    assert frames_from_reads(app.reads.reads) == {f.index: f.raw for f in app.store.frames}
