"""Run the App over a feed: a live capture in a process of its own, a replay, or a viewer attached to one.

A live capture (`sniffer live`, `sniffer demo` on a terminal) is never run in
the App's interpreter: `run_capture_tui` starts it as a process of its own
(processes/capture.py) and the App views it over the capture's socket, as
`sniffer attach` does, so nothing the UI does can delay a read.  A bad port
or setting fails with the capture's one line before the UI starts; quitting
asks, then stops the capture as Ctrl-C would (its MCAP closed and kept).

A replay's session is built and opened by the command (sniffer.commands);
its sinks include the TuiSink, and its `run()` goes on a worker thread while
the App (main thread) only views the store.  Quitting the App sets the
session's stop event.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Callable

from sniffer.tui.app import SnifferApp
from sniffer.processes.cpu_yield import GiveWay, give_cpu
from sniffer.tui.sink import TuiSink

VIEWER_NICE = 19  # the viewer of a capture on this machine: the lowest priority (yield_to_capture)
# the longest the UI thread waits for the interpreter while a feed thread (a replay's decoding, an attached
# capture's records) holds it: CPython's default, 5 ms, is paid at every hand-over of a key's way to the screen
UI_SWITCH_S = 0.001
GC_YOUNG = 10_000  # allocations between young collections in the App's process (CPython's default: 700)


def _ready_interpreter() -> None:
    """The process is about to run the App for the rest of its life: keys first.

    The garbage collector: frames pass through the UI by the thousand (the sink's backlog, the store's newest
    frames and caches) and nearly all are freed by their reference counts; with the default thresholds they
    were scanned young every 700 allocations, survived, and set off a full collection every 2 s (40-70 ms of
    the UI thread each, a key's p99; 0.8-3 s of every 200k-frame replay's 20-30 s).  Young collections every
    GC_YOUNG objects leave them time to die first: no full collection in a 25 s stress run."""
    import gc

    sys.setswitchinterval(min(sys.getswitchinterval(), UI_SWITCH_S))
    gc.freeze()  # what the imports made lives until exit: the full collections need not walk it every time
    gc.set_threshold(GC_YOUNG, *gc.get_threshold()[1:])


def make_app(feed: Callable[[TuiSink, threading.Event], object], *, sink: TuiSink | None = None,
             stop: threading.Event | None = None, source_label: str = "", capture_path: str | None = None,
             registry=None, **kw) -> SnifferApp:
    """The App over a feed; with `stop`, quitting the App sets it (the session sharing it ends)."""
    sink = sink or TuiSink()
    sink.capture_path = capture_path
    app = SnifferApp(sink, feed, source_label=source_label, capture_path=capture_path, registry=registry, **kw)
    if stop is not None:
        app.stop_event = stop
    return app


def session_app(session, sink: TuiSink, *, source_label: str = "", capture_path: str | None = None,
                **kw) -> SnifferApp:
    """The App over an opened session whose sinks include `sink` (its run() is the feed)."""
    return make_app(lambda _sink, _stop: session.run(), sink=sink, stop=session.stop, source_label=source_label,
                    capture_path=capture_path, registry=session.registry, **kw)


def run_tui(feed: Callable[[TuiSink, threading.Event], object], *, attached: bool = False, **kw) -> int:
    """Run the App until the user quits; `feed(sink, stop)` runs on a worker thread (make_app's arguments).
    `attached`: the feed is a capture running now on this machine (the App gives way to it, give_way).

    A feed that returns a session gets the capture's summary line printed after the App closes.
    """
    return _run(make_app(feed, **kw), attached=attached)


def _run(app: SnifferApp, *, attached: bool = False) -> int:
    _ready_interpreter()
    with give_way(app) if attached else contextlib.nullcontext():
        app.run()
    app.stop_feed()
    result = app.feed_result
    if hasattr(result, "frames_out"):
        from sniffer.capture.summary import summary_line

        print(summary_line(result), file=sys.stderr)
        if getattr(result, "error", None):
            print(f"sniffer: error: {result.error}", file=sys.stderr)
            return 1
    if app.feed_error is not None:
        print(f"sniffer: error: {app.feed_error}", file=sys.stderr)
        return 1
    return 0


def run_session_tui(session, sink: TuiSink, *, source_label: str, capture_path: str | None = None,
                    source_path: str | None = None) -> int:
    """Run the App over an opened session whose sinks include `sink`, until the user quits (`source_path`: the
    capture a replay reads, which exports are proposed beside)."""
    return _run(session_app(session, sink, source_label=source_label, capture_path=capture_path,
                            source_path=source_path))


def give_way(app: SnifferApp) -> GiveWay:
    """The App's process hands its CPU back every GIVE_WAY_S while the capture it views records frames
    (processes/cpu_yield.py: how a redraw's burst delays the capture's reads although the viewer runs at nice 19)."""
    app.give_way = GiveWay(lambda: app.sink.frames_in)
    return app.give_way


def local_capture_feed(att):
    """The feed of a viewer of a capture on this machine (`sniffer live|demo`'s TUI, `attach --tui` to a local
    socket): this process leaves the CPU to the capture (yield_to_capture, now: the App's threads inherit it)
    and the feed gives way between two records (sniffer/processes/cpu_yield.py).  Run the App with give_way as well."""
    from sniffer.processes.attach import attach_feed

    yield_to_capture()
    return attach_feed(att, pause=give_cpu)


def yield_to_capture() -> None:
    """This process (the viewer of a capture on this machine) leaves the CPU to the capture.

    On a busy machine a read that waits for a CPU holds the request and its answer together (the answer
    loses its latency); the view can wait.  The lowest nice level (19): the viewer gets a CPU only in
    proportion, and a normal task is placed on another CPU rather than behind it.  Not SCHED_IDLE, although
    it sounds right: the scheduler counts a CPU running only SCHED_IDLE work as idle and puts the tty's flush
    work and the capture's threads there, where (on a kernel that does not preempt on wakeup) they wait for
    the viewer's burst to end; on the stress line SCHED_IDLE glued more answers than nice 19 in the same
    runs (benchmarks/bench_capture_timing.py).  Set
    before threads start (Linux applies it to the calling thread; new threads inherit it)."""
    try:
        os.nice(VIEWER_NICE - os.nice(0))
    except OSError:
        pass


class CaptureViewer:
    """A capture started as a process of its own and this process's App attached to it (`with` ends both:
    the capture stopped as Ctrl-C would, its stderr printed, its private socket removed).

    `start()` returns False when the capture never published (a missing port, a bad setting): it said why
    in one line, and `rc()` is its exit status."""

    def __init__(self, spec, command: str, label: str) -> None:
        from sniffer.processes.capture import CaptureProcess, private_socket

        self.label = label
        self.sock, self._cleanup = (spec.publish, lambda: None) if spec.publish else private_socket()
        self.capture = CaptureProcess(spec, command, self.sock, relay_stderr=True)
        self.app: SnifferApp | None = None
        self.attachment = None

    def start(self) -> bool:
        from sniffer.processes.attach import Attachment
        from sniffer.events import CaptureError

        if not self.capture.wait_publishing():
            self.capture.stderr.release(wait_eof=True)  # its one line
            return False
        try:
            att = Attachment(self.sock)
        except CaptureError as e:
            print(f"sniffer: error: {e}", file=sys.stderr)
            return False
        self.attachment = att
        self.app = make_app(local_capture_feed(att), source_label=self.label, capture_path=att.capture_path,
                            live=True)
        self.capture.stderr.hold(self.app.notices.append)  # the terminal is the App's: notifications meanwhile
        return True

    def rc(self) -> int:
        app = self.app
        if app is not None and app.feed_error is not None and self.capture.rc() == 0:
            print(f"sniffer: error: {app.feed_error}", file=sys.stderr)
            return 1
        return self.capture.rc()  # 1 while it has not exited (CaptureProcess.rc)

    def close(self) -> None:
        if self.app is not None:
            self.app.stop_feed()
        self.capture.stop(ending=self.attachment is not None and self.attachment.ended is not None)
        self.capture.stderr.release(wait_eof=True)  # its summary line, its errors
        self._cleanup()

    def __enter__(self) -> "CaptureViewer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def run_capture_tui(spec, command: str, label: str) -> int:
    """`sniffer live|demo` with the TUI: the capture as a process of its own (publishing on a private
    socket, or on --publish's), the App attached to it; the capture's exit status is the command's."""
    import signal

    with CaptureViewer(spec, command, label) as viewer:
        if not viewer.start():
            return viewer.rc()
        app = viewer.app
        previous = {sig: signal.signal(sig, lambda *_: app.exit()) for sig in (signal.SIGTERM, signal.SIGHUP)}
        _ready_interpreter()
        try:
            with give_way(app):
                app.run()
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
    return viewer.rc()


def attach_tui(att) -> int:
    """The App over the capture; a capture on this machine gets the CPU first, as under the TUI of `sniffer
    live` (yield_to_capture here, processes/cpu_yield.py)."""
    from sniffer.processes.attach import attach_feed

    here = att.on_this_machine
    return run_tui(local_capture_feed(att) if here else attach_feed(att), source_label=att.label,
                   capture_path=att.capture_path, attached=here)
