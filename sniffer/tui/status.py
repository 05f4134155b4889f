"""The status bar line: source, serial settings, low latency, capture file, rates."""

from __future__ import annotations

from rich.text import Text


def _size(n: int | None) -> str:
    if n is None:
        return "-"
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1024 or unit == "GB":
            return f"{n:.0f}{unit}" if unit == "B" else f"{n:.1f}{unit}"
        n /= 1024
    return str(n)


def _low_latency(ll: dict) -> str:
    if not ll:
        return "low-latency ?"
    if ll.get("simulated"):
        return "low-latency sim"
    ok = [k for k, v in ll.items() if v is True]
    return "low-latency " + (",".join(ok) if ok else "off")


def status_text(app) -> Text:
    sink, store = app.sink, app.store
    info = sink.info
    parts = []
    if info is not None:
        src = app.source_label or info.port or info.source
        line = f"{info.baud or '?'} {info.databits}{info.parity or 'N'}{info.stopbits or 1}"
        parts.append(f"{src} {line} {info.protocol}")
        parts.append(_low_latency(info.low_latency))
    else:
        parts.append(app.source_label or "waiting for source")
    path = app.capture_path or sink.capture_path
    if path:
        parts.append(f"{path} {_size(app.capture_size())}")
    parts.append(f"{len(store)} fr {app.frames_per_s:.0f} fr/s {_size(int(app.bytes_per_s))}/s")
    parts.append(f"noise {store.noise_bytes}B")
    missing = [f"{n} {what}" for n, what in ((sink.earlier_frames, "earlier (in the MCAP)"),
                                              (sink.skipped_frames, "skipped")) if n]
    if missing:
        parts.append("not here: " + ", ".join(missing))
    parts.append(f"{app.clock() - app.t_start:.0f}s")
    if getattr(app, "export_status", None):  # an export on its worker thread
        parts.append(app.export_status)
    if store.filter.active:
        parts.append(f"filter: {store.filter.describe()} ({len(store.view)})")
    text = Text(" │ ".join(parts))
    if store.paused:
        text.append("  PAUSED", "bold black on yellow")
    elif not getattr(app.frame_list, "follow", True) and not sink.closed.is_set():
        # new frames arrive below the view (a filter or a move up stopped following the tail)
        text.append("  [not following the tail: End]", "bold")
    if sink.error:
        text.append(f"  [error: {sink.error}]", "bold")
    elif sink.closed.is_set():  # the feed is done; the view may still be taking in what it read
        text.append("  [ended]" if not sink.backlog else f"  [loading: {sink.backlog} frames to show]", "bold")
    return text
