"""One human line per frame, for a terminal or a log file.

A capture of several links has a link column after the time (the link's
name); a one-line capture has none, so its lines (and golden files) are as
they always were.
"""

from __future__ import annotations

import sys
from typing import TextIO

from sniffer.events import CaptureInfo
from sniffer.frame import Frame
from sniffer.hot import HOT
from sniffer.sinks.base import Sink

_MARK = {"error": "!!", "warning": "! ", "info": "  ", None: "  "}
_DIRECTION = {"request": "->REQ", "response": "<-RSP"}  # any other role: "<-???"
_FC = [f"{i:02X}" for i in range(256)]
_UNIT = [f"{i:<3d}" for i in range(256)]
_NO_TIME = f"{'-':>12}"  # the time column of a frame without a time


# the common frame's line written in C (sniffer/_hot.c frame_line); None: by frame_line_py, the reference
_FRAME_LINE = None if HOT is None else HOT.frame_line


def frame_line(f: Frame, t0_ns: int, link_width: int = 0) -> str:
    """The frame's line; `link_width` > 0: with a link column that wide (several links)."""
    if _FRAME_LINE is not None and not link_width:
        line = _FRAME_LINE(f, t0_ns)
        if line is not None:  # None: a frame of another kind (noise, annotations, no time, DE ...)
            return line
    return frame_line_py(f, t0_ns, link_width)


def frame_line_py(f: Frame, t0_ns: int, link_width: int = 0) -> str:
    """frame_line in Python: the reference, and the writer of every line the compiled one leaves."""
    # frames typed in (`sniffer decode`) have no time: their column says so, not a made-up figure
    t = f"{(f.t_ns - t0_ns) / 1e9:12.6f}" if f.time_source != "none" else _NO_TIME
    if link_width:
        t = f"{t} {f.link:<{link_width}}"
    mark = _MARK[f.worst_severity()] if f.annotations else "  "
    if f.protocol == "noise":
        more = "..." if len(f.raw) > 24 else ""
        return f"{t} {mark} NOISE   {len(f.raw):3d}B {f.raw[:24].hex(' ')}{more}  [{f.noise_reason}]"
    direction = _DIRECTION.get(f.role, "<-???")
    pair = f" #{f.pair}" if f.pair is not None else ""
    lat = f" {f.latency_ms:6.1f}ms" if f.latency_ms is not None else ""
    if f.de_on_ns is not None or f.de_off_ns is not None:  # a logic capture's driver enable (--de)
        lat += f" DE {_us(f.de_on_ns)}/{_us(f.de_off_ns)}us"
    fc = "--" if f.function is None else _FC[f.function] if 0 <= f.function < 256 else f"{f.function:02X}"
    unit = "?  " if f.unit is None else _UNIT[f.unit] if 0 <= f.unit < 256 else f"{f.unit:<3d}"
    crc = "" if f.crc_ok else " CRC!"
    notes = [a.code for a in f.annotations if a.severity != "info"] if f.annotations else None
    tail = f"  [{', '.join(notes)}]" if notes else ""
    model = f" {f.model}" if f.model and f.model != "generic" else ""
    return (
        f"{t} {mark} {direction} u{unit}{model} fc{fc}{crc} #{f.index}{pair}{lat}  "
        f"{f.summary}{tail}"
    )


def _us(ns: int | None) -> str:
    return "?" if ns is None else f"{ns / 1000:+.1f}"


BATCH = 256  # lines joined into one write when lines need not reach the reader one by one


class StreamSink(Sink):
    """A sink writing one line per frame to a stream; subclasses say how a frame reads (`line`).

    With `flush` (a live capture on a terminal or pipe) each line is written and flushed as
    its frame settles; otherwise lines are joined BATCH at a time: one write call instead of
    256 (a buffered write costs 0.1-0.5 us a call, a tenth of what a frame costs end to end).
    """

    newline = "\n"

    def __init__(self, out, flush: bool = False, own: bool = False) -> None:
        self.out = out
        self.flush_each = flush
        self.own = own  # close the stream at the end (a file this sink opened)
        self.t0 = 0
        self._lines: list = []

    def start(self, info: CaptureInfo) -> None:
        self.t0 = info.t0_ns

    def line(self, f: Frame):  # pragma: no cover - each format says how a frame reads
        raise NotImplementedError

    def frame(self, f: Frame) -> None:
        if self.flush_each:
            self.out.write(self.line(f) + self.newline)
            self.out.flush()
            return
        lines = self._lines
        lines.append(self.line(f))
        if len(lines) >= BATCH:
            self._write()

    def _write(self) -> None:
        lines, self._lines = self._lines, []
        if lines:
            lines.append(self.newline[:0])
            self.out.write(self.newline.join(lines))

    def flush(self) -> None:
        """Write the lines held so far and flush the stream (a viewer's batch is complete)."""
        self._write()
        self.out.flush()

    def close(self) -> None:
        try:
            self._write()
        finally:
            if self.own:
                self.out.close()
            else:
                self.out.flush()


def link_width(info: CaptureInfo | None) -> int:
    """How wide a frame line's link column is: 0 (none) unless the capture has several links."""
    names = [str(x.get("name", "")) for x in (info.links if info is not None else ())]
    return max(map(len, names)) if len(names) > 1 else 0


class TextSink(StreamSink):
    kind = "text"
    split = "stream"  # by parts: its lines, written in order (sniffer.parallel.outputs)

    def __init__(self, out: TextIO | None = None, flush: bool = False, own: bool = False) -> None:
        super().__init__(out or sys.stdout, flush, own)
        self.link_width = 0

    def start(self, info: CaptureInfo) -> None:
        super().start(info)
        self.link_width = link_width(info)

    def line(self, f: Frame) -> str:
        return frame_line(f, self.t0, self.link_width)


def open_sink(fmt: str, path: str, parts: list[str]) -> TextSink:
    """The Text sink writing its part files (named in the table of sniffer.formats)."""
    return TextSink(open(parts[0], "w", encoding="utf-8", buffering=1 << 16), own=True)
