"""Live capture loop (`sniffer live`) and the simulated-bus demo (`sniffer demo`).

The capture owns the port and the MCAP file; viewers (text stream today,
the TUI later) are sinks.  Whatever stops the capture (Ctrl-C, --duration,
a full disk, an error) the pipeline is finished and the MCAP closed, so
nothing already captured is lost.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time

from . import __version__
from .line import LineSettings
from .sinks.mcap import CaptureStorageError, McapSink
from .pipeline import Pipeline
from .sources.serial_live import SerialSource


def _default_out() -> str:
    return time.strftime("sniffer-%Y%m%d-%H%M%S.mcap")


def capture(source: SerialSource, line: LineSettings, registry, sinks, *, duration_s: float = 0,
            stop: threading.Event | None = None, timeouts: dict | None = None, mcap: McapSink | None = None,
            on_open=None, publish=None):
    """Run a live source through a pipeline until duration, stop, or Ctrl-C. Returns (pipeline, error).

    `on_open(info)` runs once the port is open (the demo starts its bus then, so no byte is missed).
    `publish` (a PublishSink) comes after the MCAP, so the file is closed before viewers are let go.
    """
    info = source.open()
    info.devices = dict(registry.devices)
    info.protocol = (timeouts or {}).get("protocol", info.protocol)
    info.sniffer_version = __version__
    all_sinks = list(sinks) + ([mcap] if mcap else []) + ([publish] if publish else [])
    p = Pipeline(info, line, registry, all_sinks, **(timeouts or {}))
    stop = stop or threading.Event()
    deadline = time.monotonic() + duration_s if duration_s > 0 else None
    error = None

    def _watch():
        while not stop.wait(0.05):
            if deadline is not None and time.monotonic() >= deadline:
                break
        source.stop()

    watcher = threading.Thread(target=_watch, name="capture-deadline", daemon=True)
    watcher.start()
    if on_open is not None:
        on_open(info)
    try:
        for ev in source.events():
            p.feed(ev)
            if mcap is not None:
                mcap.maybe_flush()
    except CaptureStorageError as e:
        error = f"capture file: {e} (capture stopped; what was written is intact)"
    finally:
        stop.set()
        source.stop()
        try:
            p.finish()
        except CaptureStorageError as e:
            error = error or f"capture file: {e}"
    return p, error


def run_live(args, bus, line_fn, registry_fn, timeouts_fn, out_sink_fn) -> int:
    line = line_fn(args, None, bus, need=False)
    registry = registry_fn(args, bus)
    source = SerialSource(args.port, line)
    mcap = None
    path = None if args.no_out else (args.out or _default_out())
    publish = publisher(args, args.port, path)  # before the port opens: a bad address fails first
    with publish or contextlib.nullcontext():
        if path:
            mcap = McapSink(path)
            print(f"sniffer: capturing {args.port} at {line.label()} (read-only) -> {path}", file=sys.stderr)
        stop = threading.Event()
        _on_signals(stop)
        p, error = capture(source, line, registry, _out_sinks(args, out_sink_fn), duration_s=args.duration,
                           stop=stop, timeouts=timeouts_fn(args, bus), mcap=mcap, publish=publish)
    _summary(p, mcap)
    if error:
        print(f"sniffer: error: {error}", file=sys.stderr)
        return 1
    return 0


def publisher(args, label: str, capture_path: str | None):
    """The PublishSink for `--publish ADDRESS` (None without it); says where viewers attach."""
    if not getattr(args, "publish", None):
        return None
    from .publish import PublishSink

    sink = PublishSink(args.publish, label=label, capture_path=capture_path, backlog=args.publish_backlog)
    print(f"sniffer: publishing on {sink.address} (view: sniffer attach {sink.address})", file=sys.stderr)
    return sink


def _out_sinks(args, out_sink_fn) -> list:
    """The text/JSONL stream on stdout, unless --quiet."""
    return [] if getattr(args, "quiet", False) else [out_sink_fn(args, True)]


def run_demo(args, registry_fn, out_sink_fn) -> int:
    from .simulator.ptybus import PtyBus
    from .simulator.scenario import get_scenario
    from .simulator.bus import simulate

    try:
        scenario = get_scenario(args.scenario)
    except ValueError as e:
        print(f"sniffer: error: {e}", file=sys.stderr)
        return 2
    line = scenario.line
    protocol = getattr(args, "protocol", None) or scenario.protocol
    # decode the simulated drives with their models unless the user names the models
    args.device = getattr(args, "device", None) or [f"{u}={m}" for u, m in sorted(scenario.devices.items())]
    registry = registry_fn(args, None)
    duration = args.duration if args.duration > 0 else 24 * 3600.0
    stop = threading.Event()
    _on_signals(stop)
    publish = publisher(args, f"demo {scenario.name}", args.out)
    with PtyBus() as bus, publish or contextlib.nullcontext():
        models = ", ".join(f"{u}={m}" for u, m in sorted(registry.devices.items()))
        print(f"sniffer: demo '{scenario.name}' on simulated bus {bus.port} at {line.label()} {protocol}"
              f"{' (' + models + ')' if models else ''} -> {args.out}", file=sys.stderr)
        frames = simulate(scenario, line, duration, args.seed)
        stats = {}

        def _play():
            stats["play"] = bus.play(frames, stop_event=stop)
            time.sleep(0.3)  # let the last frames reach the sniffer, then close on silence
            stop.set()

        source = SerialSource(bus.port, line, reconnect=False, low_latency=False)
        player = threading.Thread(target=_play, name="simulated-bus", daemon=True)
        mcap = McapSink(args.out)
        p, error = capture(source, line, registry, _out_sinks(args, out_sink_fn), duration_s=duration + 5,
                           stop=stop, mcap=mcap, timeouts={"protocol": protocol},
                           on_open=lambda info: player.start(), publish=publish)
        stop.set()
        player.join(timeout=5)
        sent = stats.get("play")
        bus.drain()
        _summary(p, mcap)
        if sent is not None:
            print(f"sniffer: simulator sent {sent.frames} frames ({sent.bytes} bytes); "
                  f"sniffer wrote {bus.bytes_received_from_sniffer} bytes to the bus", file=sys.stderr)
    if error:
        print(f"sniffer: error: {error}", file=sys.stderr)
        return 1
    return 0


def _summary(p: Pipeline, mcap: McapSink | None) -> None:
    where = f"; MCAP {mcap.path} ({mcap.bytes_written} bytes)" if mcap else ""
    print(f"sniffer: {p.frames_out} frames, {p.bytes_in} bytes, {p.noise_bytes} noise bytes{where}",
          file=sys.stderr)


def _on_signals(stop: threading.Event) -> None:
    def handler(signum, frame):
        stop.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)
