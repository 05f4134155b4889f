"""Entry points the CLI calls: the TUI over a replay, a live capture or the demo.

In every case the pipeline runs on a worker thread with a TuiSink among its
sinks and the App (main thread) only views the store.  Quitting the App sets
the stop event, which ends the capture cleanly (MCAP closed).
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable

from ..pipeline import Pipeline
from .app import SnifferApp
from .sink import TuiSink


def replay_feed(info, events, line, registry, pipeline_kw: dict | None = None, *, pace: float = 0.0):
    """A feed(sink, stop) that runs a replay through a pipeline; pace > 0 sleeps between chunks of time."""

    def feed(sink: TuiSink, stop: threading.Event):
        p = Pipeline(info, line, registry, [sink], **(pipeline_kw or {}))
        try:
            for ev in events:
                if stop.is_set():
                    break
                p.feed(ev)
                if pace:
                    time.sleep(pace)
        finally:
            p.finish()
        return p

    return feed


def run_tui(feed: Callable[[TuiSink, threading.Event], object], *, source_label: str = "",
            capture_path: str | None = None, registry=None) -> int:
    """Run the App until the user quits; `feed(sink, stop)` runs on a worker thread."""
    sink = TuiSink()
    sink.capture_path = capture_path
    app = SnifferApp(sink, feed, source_label=source_label, capture_path=capture_path, registry=registry)
    app.run()
    app.stop_feed()
    p = app.feed_result
    if isinstance(p, Pipeline):  # the same summary line as the text stream's
        size = app.capture_size()
        where = f"; MCAP {capture_path} ({size} bytes)" if capture_path and size is not None else ""
        print(f"sniffer: {p.frames_out} frames, {p.bytes_in} bytes, {p.noise_bytes} noise bytes{where}",
              file=sys.stderr)
    if app.feed_error is not None:
        print(f"sniffer: error: {app.feed_error}", file=sys.stderr)
        return 1
    return 0


def replay_tui(path: str, info, events, line, registry, **pipeline_kw) -> int:
    """`sniffer replay FILE --tui`: decode the file in the background, browse as it fills."""
    return run_tui(replay_feed(info, events, line, registry, pipeline_kw), source_label=path,
                   registry=registry)


def live_tui(args, bus, line_fn, registry_fn, timeouts_fn) -> int:
    """`sniffer live PORT` on a tty: as live.run_live, the TUI instead of the text stream."""
    feed, label, path, registry = live_feed(args, bus, line_fn, registry_fn, timeouts_fn)
    return run_tui(feed, source_label=label, capture_path=path, registry=registry)


def live_feed(args, bus, line_fn, registry_fn, timeouts_fn):
    """(feed, source label, capture path, registry) for a live capture of args.port."""
    from ..live import _default_out, capture, publisher
    from ..sinks.mcap import McapSink
    from ..sources.serial_live import SerialSource

    line = line_fn(args, None, bus, need=False)
    registry = registry_fn(args, bus)
    source = SerialSource(args.port, line)
    path = None if args.no_out else (args.out or _default_out())
    publish = publisher(args, args.port, path)
    mcap = McapSink(path) if path else None

    def feed(sink: TuiSink, stop: threading.Event):
        with publish or contextlib.nullcontext():
            p, error = capture(source, line, registry, [sink], duration_s=args.duration, stop=stop,
                               timeouts=timeouts_fn(args, bus), mcap=mcap, publish=publish)
        if error:
            raise RuntimeError(error)
        return p

    return feed, args.port, path, registry


def demo_tui(args, registry_fn) -> int:
    """`sniffer demo` on a tty: as live.run_demo, the TUI instead of the text stream."""
    try:
        feed, label, path, registry = demo_feed(args, registry_fn)
    except ValueError as e:  # unknown scenario: one line, as run_demo
        print(f"sniffer: error: {e}", file=sys.stderr)
        return 2
    return run_tui(feed, source_label=label, capture_path=path, registry=registry)


def demo_feed(args, registry_fn):
    """(feed, source label, capture path, registry) for the simulated-bus demo."""
    from ..live import capture, publisher
    from ..sinks.mcap import McapSink
    from ..simulator.bus import simulate
    from ..simulator.ptybus import PtyBus
    from ..simulator.scenario import get_scenario
    from ..sources.serial_live import SerialSource

    scenario = get_scenario(args.scenario)  # ValueError: the caller reports it
    line = scenario.line
    protocol = getattr(args, "protocol", None) or scenario.protocol
    args.device = getattr(args, "device", None) or [f"{u}={m}" for u, m in sorted(scenario.devices.items())]
    registry = registry_fn(args, None)
    duration = args.duration if args.duration > 0 else 24 * 3600.0
    publish = publisher(args, f"demo {scenario.name}", args.out)

    def feed(sink: TuiSink, stop: threading.Event):
        with PtyBus() as bus, publish or contextlib.nullcontext():
            frames = simulate(scenario, line, duration, args.seed)
            source = SerialSource(bus.port, line, reconnect=False, low_latency=False)

            def _play():
                bus.play(frames, stop_event=stop)
                time.sleep(0.3)
                stop.set()

            player = threading.Thread(target=_play, name="simulated-bus", daemon=True)
            p, error = capture(source, line, registry, [sink], duration_s=duration + 5, stop=stop,
                               mcap=McapSink(args.out), timeouts={"protocol": protocol},
                               on_open=lambda info: player.start(), publish=publish)
            stop.set()
            player.join(timeout=5)
            bus.drain()
        if error:
            raise RuntimeError(error)
        return p

    return feed, f"demo {scenario.name}", args.out, registry
