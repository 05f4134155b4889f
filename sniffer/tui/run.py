"""Run the App over a feed: a capture session (live, demo, replay) or a viewer attached to one.

The session is built and opened by the command (sniffer.commands), so a bad
port or file fails with one line before the UI starts; its sinks include the
TuiSink, and its `run()` goes on a worker thread while the App (main thread)
only views the store.  Quitting the App sets the session's stop event, which
ends the capture cleanly (files closed and kept).
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable

from .app import SnifferApp
from .sink import TuiSink


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


def run_tui(feed: Callable[[TuiSink, threading.Event], object], **kw) -> int:
    """Run the App until the user quits; `feed(sink, stop)` runs on a worker thread (make_app's arguments).

    A feed that returns a session gets the capture's summary line printed after the App closes.
    """
    return _run(make_app(feed, **kw))


def _run(app: SnifferApp) -> int:
    app.run()
    app.stop_feed()
    result = app.feed_result
    if hasattr(result, "frames_out"):
        from ..commands.common import summary_line

        print(summary_line(result), file=sys.stderr)
        if getattr(result, "error", None):
            print(f"sniffer: error: {result.error}", file=sys.stderr)
            return 1
    if app.feed_error is not None:
        print(f"sniffer: error: {app.feed_error}", file=sys.stderr)
        return 1
    return 0


def run_session_tui(session, sink: TuiSink, *, source_label: str, capture_path: str | None = None,
                    live: bool = False) -> int:
    """Run the App over an opened session whose sinks include `sink`, until the user quits (`live`: a
    capture running here, so quitting asks first)."""
    return _run(session_app(session, sink, source_label=source_label, capture_path=capture_path, live=live))
