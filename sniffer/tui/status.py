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


def _line(d) -> str:
    """A line's settings as the bar shows them: `19200 8E1` (a CaptureInfo or a CaptureInfo.links entry)."""
    get = d.get if isinstance(d, dict) else lambda k: getattr(d, k, None)
    return f"{get('baud') or '?'} {get('databits') or 8}{get('parity') or 'N'}{get('stopbits') or 1}"


def line_settings(info) -> str:
    """Every line's settings and protocol: `19200 8E1 modbus-rtu`; several links each by name:
    `a 9600 8N1, b 19200 8E1 modbus-rtu` (the protocol once when every link has the same)."""
    links = info.links
    if not links:
        return f"{_line(info)} {info.protocol}"
    protocols = {x.get("protocol") or info.protocol for x in links}
    if len(protocols) == 1:
        return ", ".join(f"{x.get('name', '')} {_line(x)}" for x in links) + f" {protocols.pop()}"
    return ", ".join(f"{x.get('name', '')} {_line(x)} {x.get('protocol') or info.protocol}" for x in links)


def links_low_latency(info) -> dict:
    """The low-latency state of every port: one port's dict, or with several links what every port got."""
    if not info.links:
        return info.low_latency
    ports = [ll for x in info.links for ll in (x.get("low_latency") or {}).values() if isinstance(ll, dict)]
    if not ports:
        return {}
    if all(ll.get("simulated") for ll in ports):
        return {"simulated": True}
    keys = {k for ll in ports for k in ll}
    return {k: all(ll.get(k) is True for ll in ports) for k in sorted(keys)}


def status_text(app, width: int | None = None) -> Text:
    """The status line, fitted to `width` (default: the status bar's): the view's state (paused, not
    following the tail, ended, an error) and the filter always show; the least useful parts go first
    (low latency, noise, elapsed time, rates, the source's line settings)."""
    sink, store = app.sink, app.store
    info = sink.info
    parts = []  # (keep: higher stays longer, text)
    if info is not None:
        src = app.source_label or info.port or info.source
        parts.append((5, f"{src} {line_settings(info)}"))
        parts.append((1, _low_latency(links_low_latency(info))))
    else:
        parts.append((5, app.source_label or "waiting for source"))
    path = app.capture_path or sink.capture_path
    if path:
        parts.append((6, f"{path} {_size(app.capture_size())}"))
    parts.append((8, f"{len(store)} fr"))
    parts.append((4, f"{app.frames_per_s:.0f} fr/s {_size(int(app.bytes_per_s))}/s"))
    parts.append((2, f"noise {store.noise_bytes}B"))
    missing = [f"{n} {what}" for n, what in ((sink.earlier_frames, "earlier (in the MCAP)"),
                                              (sink.skipped_frames, "skipped")) if n]
    if missing:
        parts.append((7, "not here: " + ", ".join(missing)))
    if store.books_behind:  # a replay loading: the list first, the register book and the diagnosis after it
        parts.append((7, f"registers, verdicts {100 * store.booked // len(store)}%"))
    parts.append((3, f"{app.clock() - app.t_start:.0f}s"))
    if getattr(app, "export_status", None):  # an export on its worker thread
        parts.append((8, app.export_status))
    if store.filter.active:
        parts.append((9, f"filter: {store.filter.describe()} ({len(store.view)})"))
    flags = Text()
    if store.paused:
        flags.append("  PAUSED", "bold black on yellow")
    elif not getattr(app.frame_list, "follow", True) and not app.caught_up:
        # new frames arrive below the view (a filter, a move up or a go-to stopped following the tail)
        flags.append("  [not following the tail: End]", "bold")
    mark = app.line_notice.mark() if getattr(app, "line_notice", None) is not None else ""
    if mark:  # most frames bad (linenotice.py): always shown, as the view's state is
        flags.append(mark, "bold white on red")
    if sink.error:
        flags.append(f"  [error: {sink.error}]", "bold")
    elif sink.closed.is_set():  # the feed is done; the view may still be taking in what it read
        flags.append("  [ended]" if not sink.backlog else f"  [loading: {sink.backlog} frames to show]", "bold")
    if width is None:
        bar = getattr(app, "status", None)
        width = bar.content_size.width if bar is not None and bar.content_size.width else None
    sep = " │ "
    while width is not None and len(parts) > 1 \
            and sum(len(t) for _, t in parts) + len(sep) * (len(parts) - 1) + len(flags) > width:
        parts.remove(min(parts, key=lambda p: p[0]))
    text = Text(sep.join(t for _, t in parts))
    text.append_text(flags)
    return text
