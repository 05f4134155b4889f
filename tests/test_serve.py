"""Capture in one process, viewers in others: --publish, `sniffer attach`, `sniffer serve`.

Real parts throughout: the simulated bus over a pty, Unix sockets, the TUI
under Pilot, `sniffer serve` as a subprocess with textual-serve's web server
and a websocket client.  Tests check what arrived, not when; the deadlines
only bound a hang.
"""

from __future__ import annotations

import asyncio
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request

import pytest
from helpers import ListSink
from serve_helpers import HANG_S, captures_of, processes_with, published, start_serve
from serve_helpers import wait as _wait
from terminal import stat_fields
from tui_helpers import SIM, demo_viewer, replay_frames

from decoders.registry import default_registry
from sniffer.processes.attach import Attachment, attach_feed
from sniffer.cli import main
from sniffer.events import CaptureInfo
from sniffer.line import LineSettings
from sniffer.capture.session import CaptureSpec, Session
from sniffer.formats.mcap.sink import McapSink
from sniffer.capture.pipeline import Pipeline
from sniffer.processes.publish_sink import PublishSink
from sniffer.processes.stream import CONTROL_PREFIX, PublishError
from sniffer.formats.records import loads
from sniffer.simulator import simulate, wire_chunks
from sniffer.simulator.ptybus import PtyBus
from sniffer.simulator.scenario import get_scenario
from sniffer.events import CaptureError
from sniffer.formats.mcap.reader import read_frames
from sniffer.sources.files import open_replay
from sniffer.sources.serial_live import SerialSource
from sniffer.tui.app import SnifferApp
from sniffer.tui.sink import TuiSink
from sniffer.tui.status import status_text

LINE = LineSettings(19200, "E", 1)


def read_stream(att: Attachment, *, start: threading.Event | None = None) -> list[dict]:
    """Every frame record a viewer gets until the capture ends (control lines go to `att`)."""
    if start is not None:
        start.wait(HANG_S)
    records = []
    for lines in att.batches():
        for line in lines:
            if line.startswith(CONTROL_PREFIX):
                att.control(line)
            elif line:
                records.append(loads(line))
    att.close()
    return records


def _publishing(sock) -> bool:
    try:
        Attachment(str(sock)).close()
    except CaptureError:  # not there yet, or bound and not listening yet
        return False
    return True


class Viewer(threading.Thread):
    def __init__(self, address: str, start: threading.Event | None = None) -> None:
        super().__init__(daemon=True)
        self.att = Attachment(address)  # connects and reads the header now
        self.go = start
        self.records: list[dict] = []

    def run(self) -> None:
        self.records = read_stream(self.att, start=self.go)


# ---------------------------------------------------------------- (a) two viewers of a live capture
def test_two_viewers_get_the_captures_frames(tmp_path):
    """Demo bus over a pty, published; one viewer from the start, one joining halfway with a short backlog."""
    sent = list(simulate(get_scenario("errors"), LINE, 2.0, seed=3))
    half = len(sent) // 2
    sock, out = str(tmp_path / "cap.sock"), tmp_path / "live.mcap"
    backlog = 20
    collector = ListSink()
    stop = threading.Event()
    viewers: dict[str, Viewer] = {}
    pub = PublishSink(sock, label="pty demo", capture_path=str(out), backlog=backlog)
    assert oct(os.stat(sock).st_mode & 0o777) == "0o600"
    with PtyBus() as bus:
        source = SerialSource(bus.port, LINE, reconnect=False, low_latency=False)

        def play():
            bus.play(sent[:half], speed=4.0, stop_event=stop)
            _wait(lambda: published(sock) > backlog + 5, "the first half to be published")
            viewers["late"] = Viewer(sock)
            viewers["late"].start()
            bus.play(sent[half:], speed=4.0, stop_event=stop)
            stop.wait(0.5)  # then let the capture see the line go quiet
            stop.set()

        p = Session(CaptureSpec(duration_s=HANG_S), source, [collector, McapSink(out), pub], stop=stop,
                    keep_partial=True)
        p.open()
        viewers["first"] = Viewer(sock)
        viewers["first"].start()
        threading.Thread(target=play, daemon=True).start()
        p.run()
        bus.drain()
        assert bus.bytes_received_from_sniffer == 0  # passive, publishing or not
    assert p.error is None
    first, late = viewers["first"], viewers["late"]
    first.join(HANG_S)
    late.join(HANG_S)
    assert not os.path.exists(sock)  # removed when the capture ended

    assert len(collector.records) == len(sent) > 50
    assert read_frames(str(out)) == collector.records
    assert first.records == collector.records
    assert first.att.earlier_frames == 0 and first.att.skipped == 0
    assert first.att.ended["frames"] == len(sent) and first.att.ended["bytes_in"] == p.bytes_in
    assert first.att.ended["noise_bytes"] == p.noise_bytes > 0
    assert first.att.capture_path == str(out) and first.att.label == "pty demo"
    assert first.att.info.baud == LINE.baud and first.att.info.time_source == "read"

    k = late.att.earlier_frames
    assert k > 0  # it joined after the backlog had dropped frames, and the header says how many
    assert late.att.header["backlog_frames"] == backlog
    assert late.records == collector.records[k:]
    assert late.att.ended == first.att.ended and late.att.skipped == 0


# ---------------------------------------------------------------- (b) the TUI attached
def _publish_replay(sock: str, name: str = "errors.mcap"):
    """A PublishSink fed by a replay through the pipeline; returns (pipeline, thread that feeds it)."""
    info, events = open_replay(str(SIM / name))
    pub = PublishSink(sock, label=name, capture_path=str(SIM / name))
    p = Pipeline(info, LineSettings(info.baud, info.parity or "N", info.stopbits or 1),
                 default_registry(info.devices), [pub], protocol=info.protocol)  # start: viewers may connect

    def run():
        for ev in events:
            p.feed(ev)
        p.finish()

    return p, threading.Thread(target=run, daemon=True)


def test_attach_tui_shows_the_published_frames(tmp_path):
    sock = str(tmp_path / "tui.sock")
    p, feeder = _publish_replay(sock)
    att = Attachment(sock)
    feeder.start()
    _, expected, _ = replay_frames("errors.mcap")

    async def go():  # as attach.attach_tui builds it (no registry: the decoders live in the capture)
        app = SnifferApp(TuiSink(), attach_feed(att), source_label=att.label, capture_path=att.capture_path,
                         clock=lambda: 0.0)
        async with app.run_test(size=(140, 45)) as pilot:
            deadline = time.monotonic() + HANG_S
            while not app.caught_up:
                assert time.monotonic() < deadline, "the attached TUI never caught up"
                await pilot.pause(0.05)
            app.poll()
            await pilot.pause()
            store = app.store
            assert [f.raw for f in store.frames] == [f.raw for f in expected]
            assert [(f.index, f.pair, f.summary) for f in store.frames] == \
                [(f.index, f.pair, f.summary) for f in expected]
            assert app.feed_error is None
            assert app.sink.bytes_in == p.bytes_in  # from the capture's status / end lines
            status = status_text(app).plain
            assert "[ended]" in status and "errors.mcap" in status and "not here" not in status
            await pilot.press("home", "down", "down")
            f = app.selected_frame
            assert f.role == "request" and f.pair is not None
            await pilot.press("p")  # pairs still link across the socket
            assert app.selected_frame.index == f.pair
            assert app.detail.frame is app.selected_frame
    asyncio.run(go())
    feeder.join(HANG_S)


def test_demo_tui_publishes_to_a_viewer(tmp_path):
    """`sniffer demo --publish SOCKET` on a terminal: the capture runs as a process of its own publishing there;
    its TUI and another attached viewer see the same frames, the MCAP holds them."""
    sock, out = str(tmp_path / "demo.sock"), tmp_path / "d.mcap"

    async def go(app):
        viewer = Viewer(sock)
        viewer.start()
        async with app.run_test(size=(140, 45)) as pilot:
            deadline = time.monotonic() + HANG_S
            while not (app.caught_up and len(app.store) == app.sink.frames_in):
                assert time.monotonic() < deadline, "the demo never ended"
                await pilot.pause(0.05)
            assert app.feed_error is None
        return viewer, [f.raw.hex() for f in app.store.frames]

    with demo_viewer(tmp_path, "errors", 1.5, publish=sock) as capture:
        viewer, shown = asyncio.run(go(capture.app))
    viewer.join(HANG_S)
    assert capture.app.feed_error is None, capture.app.feed_error
    assert capture.rc() == 0 and capture.sock == sock
    assert viewer.att.ended is not None and viewer.att.earlier_frames == 0
    assert viewer.records == read_frames(str(out))
    assert [r["raw"] for r in viewer.records] == shown and len(shown) > 20


# ---------------------------------------------------------------- (c) sniffer serve
def _listening(port: int) -> list[str]:
    """Local addresses (hex, as /proc/net/tcp* writes them) listening on `port`."""
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            with open(table) as f:
                rows = f.read().splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            local, state = row.split()[1], row.split()[3]
            addr, _, hexport = local.rpartition(":")
            if state == "0A" and int(hexport, 16) == port:
                out.append(addr)
    return out


async def _browser(port: int, want: list[bytes], proc: subprocess.Popen) -> bytes:
    """Open the app's websocket as the page does, read until `want` is on screen, then Ctrl-C the server."""
    import aiohttp

    got = b""
    async with aiohttp.ClientSession() as session, \
            session.ws_connect(f"http://127.0.0.1:{port}/ws?width=140&height=40") as ws:
        async with asyncio.timeout(HANG_S):
            async for msg in ws:
                if msg.type == aiohttp.WSMsgType.BINARY:
                    got += msg.data
                if all(w in got for w in want):
                    break
            proc.send_signal(signal.SIGINT)  # with the browser still connected
            async for _ in ws:  # the server closes it
                pass
    return got


def test_serve_demo_in_a_browser(tmp_path):
    pytest.importorskip("textual_serve")
    pytest.importorskip("aiohttp")
    sock, out = tmp_path / "serve.sock", tmp_path / "served.mcap"
    screen_seen = False
    proc, port = start_serve(tmp_path, "--demo", "--scenario", "errors", "--socket", str(sock), "--out", str(out),
                             log=tmp_path / "serve.log")
    try:
        assert _listening(port) == ["0100007F"]  # 127.0.0.1 only, no other address, no IPv6
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=HANG_S) as page:
            html = page.read()
        assert b"textual.js" in html and f"ws://127.0.0.1:{port}/ws".encode() in html
        # a terminal viewer attaches to the same capture alongside
        terminal = Attachment(str(sock))
        assert terminal.label == "demo errors"
        # a browser's websocket starts `sniffer attach SOCKET --tui`, which renders the capture
        screen = asyncio.run(_browser(port, [b"Frames", b"demo errors"], proc))
        screen_seen = True
        assert b"Frames" in screen and b"demo errors" in screen
        assert read_stream(terminal)  # the terminal viewer got frames, then the end of the capture
        assert terminal.ended is not None
    finally:
        if not screen_seen:  # the test failed before the browser pressed Ctrl-C: stop it all the same
            proc.send_signal(signal.SIGINT)
        rc = proc.wait(HANG_S)
    log = (tmp_path / "serve.log").read_text()
    assert rc == 0, log
    assert "Traceback" not in log and "sniffer: error" not in log
    frames = read_frames(str(out))  # the capture child closed its MCAP
    assert len(frames) > 0
    assert not sock.exists()


async def _visit(port: int, seen: threading.Event | None = None, stop: threading.Event | None = None) -> None:
    """A browser visit: open the app's websocket and read until the screen shows; with `stop`, stay
    (`seen` set once the screen shows) until it is set or the server closes; then the page closes."""
    import aiohttp

    got = b""
    async with aiohttp.ClientSession() as session, \
            session.ws_connect(f"http://127.0.0.1:{port}/ws?width=100&height=30") as ws:
        async with asyncio.timeout(HANG_S):
            async for msg in ws:
                if msg.type == aiohttp.WSMsgType.BINARY:
                    got += msg.data
                if b"Frames" in got:
                    if stop is None:
                        break
                    seen.set()
                if stop is not None and stop.is_set() or msg.type in (aiohttp.WSMsgType.CLOSED,
                                                                      aiohttp.WSMsgType.ERROR):
                    break


async def _visits(port: int, n: int) -> None:
    """n browser visits that each see the screen, then end (the page closed)."""
    for _ in range(n):
        await _visit(port)


def test_serve_leaves_no_viewer_or_capture_behind(tmp_path):
    """Issue 11: browser visits that end, and a server killed outright (SIGKILL, a crash), leave no
    `sniffer attach --tui` viewer and no capture running (each viewer is exec'd, not behind a shell;
    viewers and the capture end with the server: sniffer/processes/parent_death.py)."""
    pytest.importorskip("textual_serve")
    pytest.importorskip("aiohttp")
    sock = tmp_path / "leak.sock"
    proc, port = start_serve(tmp_path, "--demo", "--socket", str(sock), "--no-out", log=tmp_path / "serve.log")
    capture = None
    try:
        asyncio.run(_visits(port, 3))
        _wait(lambda: not processes_with(f"attach {sock} --tui"), "the ended visits' viewers to exit")
        # a visit still open when the server is killed outright
        seen, stop = threading.Event(), threading.Event()
        holder = threading.Thread(target=lambda: asyncio.run(_visit(port, seen, stop)), daemon=True)
        holder.start()
        _wait(seen.is_set, "the open visit's screen")
        viewers = processes_with(f"attach {sock} --tui")
        capture = captures_of(proc.pid)
        assert len(viewers) == 1 and len(capture) == 1
        publisher = [pid for pid in processes_with("sniffer.processes.publisher") if _parent(pid) == capture[0]]
        assert len(publisher) == 1  # the capture's viewers are served by a process of its own
        assert _parent(viewers[0]) == proc.pid  # exec'd by the server's shell: no shell in between
        proc.kill()
        proc.wait(HANG_S)
        stop.set()
        _wait(lambda: not processes_with(f"attach {sock} --tui"), "the viewer to end with the server")
        _wait(lambda: not os.path.exists(f"/proc/{capture[0]}"), "the capture to end with the server")
        _wait(lambda: not os.path.exists(f"/proc/{publisher[0]}"), "the publisher to end with the capture")
    finally:
        if proc.poll() is None:
            proc.kill()
        for pid in processes_with(str(sock)) + [p for p in (capture or ()) if os.path.exists(f"/proc/{p}")]:
            os.kill(pid, signal.SIGKILL)


def _parent(pid: int) -> int | None:
    fields = stat_fields(pid)
    return int(fields[1]) if fields is not None else None


def test_serve_usage_errors(capsys):
    pytest.importorskip("textual_serve")
    assert main(["serve"]) == 2
    assert main(["serve", "/dev/ttyUSB0", "--demo"]) == 2
    assert main(["serve", "--demo", "--baud", "9600"]) == 2
    with socket.socket() as busy:  # the HTTP port is taken: said before any capture starts
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        assert main(["serve", "--demo", "--http-port", str(busy.getsockname()[1])]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 4 and all(x.startswith("sniffer: error: ") for x in lines)
    assert "choose another --http-port" in lines[-1]


def test_cli_attach_prints_what_a_replay_of_the_mcap_prints(tmp_path):
    """`sniffer demo --publish` and `sniffer attach --headless` as processes; Ctrl-C ends both cleanly."""
    sn = [sys.executable, "-m", "sniffer"]
    sock, out = tmp_path / "cli.sock", tmp_path / "cli.mcap"
    with open(tmp_path / "demo.err", "w") as derr:
        demo = subprocess.Popen(sn + ["demo", "--scenario", "errors", "--duration", "0", "--quiet", "--out", str(out),
                                      "--publish", str(sock)], stderr=derr, stdin=subprocess.DEVNULL)
    try:
        _wait(lambda: _publishing(sock), "the demo to publish")
        with open(tmp_path / "attach.out", "w") as aout, open(tmp_path / "attach.err", "w") as aerr:
            viewer = subprocess.Popen(sn + ["attach", str(sock), "--headless"], stdout=aout, stderr=aerr)
        _wait(lambda: len((tmp_path / "attach.out").read_text().splitlines()) > 20, "frames in the viewer")
    finally:
        demo.send_signal(signal.SIGINT)
        assert demo.wait(HANG_S) == 0
    assert viewer.wait(HANG_S) == 0
    err = (tmp_path / "attach.err").read_text().splitlines()
    assert err[0].startswith(f"sniffer: attached to {sock}: demo errors at 19200 8E1 modbus-rtu")
    assert err[-1].startswith("sniffer: capture ended: ")
    replay = subprocess.run(sn + ["replay", str(out)], capture_output=True, text=True, check=True)
    assert (tmp_path / "attach.out").read_text() == replay.stdout


# ---------------------------------------------------------------- (d) nothing to attach to
def test_attach_missing_socket_one_line_exit_2(tmp_path, capsys):
    assert main(["attach", str(tmp_path / "nobody.sock")]) == 2
    assert main(["attach", "tcp:1"]) == 2  # nothing listens on port 1
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2 and all(x.startswith("sniffer: error: ") for x in lines)
    assert "nobody.sock" in lines[0]


def test_publish_refuses_busy_or_foreign_paths(tmp_path):
    busy = str(tmp_path / "busy.sock")
    with PublishSink(busy) as pub:
        pub.start(CaptureInfo(source="test", baud=9600))
        with pytest.raises(PublishError, match="another capture"):
            PublishSink(busy)
    assert not os.path.exists(busy)
    stale = socket.socket(socket.AF_UNIX)  # a killed capture's leftover: bound, nobody listening
    stale.bind(str(tmp_path / "stale.sock"))
    stale.close()
    PublishSink(str(tmp_path / "stale.sock")).close()
    (tmp_path / "file").write_text("mine")
    with pytest.raises(PublishError, match="not a socket"):
        PublishSink(str(tmp_path / "file"))
    assert (tmp_path / "file").read_text() == "mine"


# ---------------------------------------------------------------- (e) a viewer that stops reading
def test_stalled_viewer_does_not_stall_the_capture(tmp_path):
    sc = get_scenario("default")
    chunks = wire_chunks(list(simulate(sc, sc.line, 60.0, 2)))
    sock = str(tmp_path / "slow.sock")
    info = CaptureInfo(source="sim", baud=sc.line.baud, parity=sc.line.parity, stopbits=sc.line.stopbits)
    collector = ListSink()
    pub = PublishSink(sock, viewer_queue=200)
    p = Pipeline(info, sc.line, default_registry(sc.devices), [collector, pub], protocol=sc.protocol)
    go = threading.Event()
    stalled = Viewer(sock, start=go)  # header read, then it reads nothing until `go`
    stalled.start()

    def run():
        for ev in chunks:
            p.feed(ev)

    feeder = threading.Thread(target=run, daemon=True)
    feeder.start()
    feeder.join(HANG_S)
    assert not feeder.is_alive()  # every event went through while the viewer read nothing
    n = len(collector.records)
    assert p.frames_out == n > 3000
    _wait(lambda: published(sock) == n, "the publisher to take every frame")
    go.set()  # the viewer reads again: it gets what was queued, the skip, then the end
    p.finish()
    stalled.join(HANG_S)
    att, total = stalled.att, len(collector.records)
    assert att.ended is not None and att.ended["frames"] == total
    assert att.skipped > 0 and len(stalled.records) + att.skipped == total
    # what it got are the capture's own records, in the capture's order
    got = iter(collector.records)
    assert all(any(r == c for c in got) for r in stalled.records)


# ---------------------------------------------------------------- (f) the publisher process
def _replay_through(pub: PublishSink, collector: ListSink, name: str = "errors.mcap"):
    info, events = open_replay(str(SIM / name))
    p = Pipeline(info, LineSettings(info.baud, info.parity or "N", info.stopbits or 1),
                 default_registry(info.devices), [collector, pub], protocol=info.protocol)
    return p, list(events)


def _sockets(pid: str) -> set[str]:
    out = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:  # closed meanwhile
            continue
        if target.startswith("socket:"):
            out.add(target)
    return out


def _catches(pid: str, sig: int) -> bool:
    """Whether process `pid` has a handler installed for `sig` (SigCgt of /proc/PID/status)."""
    with open(f"/proc/{pid}/status") as f:
        mask = next(int(line.split()[1], 16) for line in f if line.startswith("SigCgt:"))
    return bool(mask >> (sig - 1) & 1)


def test_viewers_are_served_by_a_process_of_their_own(tmp_path):
    """The capture's process only hands records over: the listening socket and the viewers' connections
    are held by the publisher process."""
    sock = str(tmp_path / "own.sock")
    collector = ListSink()
    pub = PublishSink(sock, label="own")
    p, events = _replay_through(pub, collector)
    viewer = Viewer(sock)
    viewer.start()
    child = str(pub._proc.pid)
    theirs = _sockets(child)
    assert len(theirs) >= 2 and not theirs & _sockets("self")  # listening + the viewer's: in the child only
    # serving, it gives way as a viewer does (sniffer/processes/cpu_yield.py): its SIGALRM handled (by sched_yield)
    deadline = time.monotonic() + HANG_S
    while not _catches(child, signal.SIGALRM):
        assert time.monotonic() < deadline, "the publisher never installed its give-way"
        time.sleep(0.02)
    for ev in events:
        p.feed(ev)
    p.finish()
    viewer.join(HANG_S)
    assert viewer.records == collector.records and len(collector.records) > 50
    assert pub._proc.returncode == 0 and not os.path.exists(sock)


def test_a_publisher_that_dies_costs_the_viewers_not_the_capture(tmp_path, capfd):
    sock = str(tmp_path / "dies.sock")
    collector = ListSink()
    pub = PublishSink(sock, tick_s=0.01)
    p, events = _replay_through(pub, collector)
    half = len(events) // 2
    for ev in events[:half]:
        p.feed(ev)
    pub._proc.kill()
    pub._proc.wait()
    for ev in events[half:]:
        p.feed(ev)
    _wait(lambda: pub._cut, "the flusher to meet the closed pipe")
    p.finish()
    err = capfd.readouterr().err
    assert p.frames_out == len(collector.records) > 50  # every frame still went to the other sinks
    said = [x for x in err.splitlines() if "publisher process ended" in x]
    assert len(said) == 1 and "the capture goes on" in said[0], err
    assert "Traceback" not in err
    assert not os.path.exists(sock)


def test_a_publisher_far_behind_is_cut_off_and_the_capture_never_waits(tmp_path, capfd):
    """A publisher process that takes nothing (stopped) while the capture runs: the capture's sinks never
    wait for it; past max_pending frames its viewers are cut off, with one line, and the end still reaches
    them once it runs again."""
    sc = get_scenario("default")
    chunks = wire_chunks(list(simulate(sc, sc.line, 30.0, 2)))
    sock = str(tmp_path / "behind.sock")
    info = CaptureInfo(source="sim", baud=sc.line.baud, parity=sc.line.parity, stopbits=sc.line.stopbits)
    collector = ListSink()
    pub = PublishSink(sock, max_pending=300, linger_s=5.0)
    p = Pipeline(info, sc.line, default_registry(sc.devices), [collector, pub], protocol=sc.protocol)
    viewer = Viewer(sock)
    viewer.start()
    os.kill(pub._proc.pid, signal.SIGSTOP)
    try:
        feeder = threading.Thread(target=lambda: [p.feed(ev) for ev in chunks], daemon=True)
        feeder.start()
        feeder.join(HANG_S)
        assert not feeder.is_alive() and p.frames_out > 1000
    finally:
        os.kill(pub._proc.pid, signal.SIGCONT)
    p.finish()
    viewer.join(HANG_S)
    err = capfd.readouterr().err
    said = [x for x in err.splitlines() if "frames behind" in x]
    assert len(said) == 1 and "viewers get nothing more" in said[0], err
    assert len(collector.records) == p.frames_out
    assert viewer.att.ended is not None  # told the capture ended, not left hanging
    assert len(viewer.records) < len(collector.records)
    assert viewer.records == collector.records[:len(viewer.records)]
