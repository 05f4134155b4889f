"""One human line per frame, for a terminal or a log file."""

from __future__ import annotations

import sys
from typing import TextIO

from ..events import CaptureInfo
from ..frame import Frame
from .base import Sink

_MARK = {"error": "!!", "warning": "! ", "info": "  ", None: "  "}


def frame_line(f: Frame, t0_ns: int) -> str:
    t = (f.t_ns - t0_ns) / 1e9
    mark = _MARK[f.worst_severity()]
    if f.protocol == "noise":
        more = "..." if len(f.raw) > 24 else ""
        return f"{t:12.6f} {mark} NOISE   {len(f.raw):3d}B {f.raw[:24].hex(' ')}{more}  [{f.noise_reason}]"
    role = {"request": "REQ", "response": "RSP"}.get(f.role, "???")
    arrow = "->" if f.role == "request" else "<-"
    pair = f" #{f.pair}" if f.pair is not None else ""
    lat = f" {f.latency_ms:6.1f}ms" if f.latency_ms is not None else ""
    fc = f"{f.function:02X}" if f.function is not None else "--"
    unit = f"{f.unit:<3d}" if f.unit is not None else "?  "
    crc = "" if f.crc_ok else " CRC!"
    notes = [a.code for a in f.annotations if a.severity != "info"]
    tail = f"  [{', '.join(notes)}]" if notes else ""
    model = f" {f.model}" if f.model and f.model != "generic" else ""
    return (
        f"{t:12.6f} {mark} {arrow}{role} u{unit}{model} fc{fc}{crc} #{f.index}{pair}{lat}  "
        f"{f.summary}{tail}"
    )


class StreamSink(Sink):
    """A sink writing one line per frame to a stream; subclasses say how a frame reads."""

    def __init__(self, out, flush: bool = False, own: bool = False) -> None:
        self.out = out
        self.flush_each = flush
        self.own = own  # close the stream at the end (a file this sink opened)
        self.t0 = 0

    def start(self, info: CaptureInfo) -> None:
        self.t0 = info.t0_ns

    def close(self) -> None:
        if self.own:
            self.out.close()
        else:
            self.out.flush()


class TextSink(StreamSink):
    def __init__(self, out: TextIO | None = None, flush: bool = False, own: bool = False) -> None:
        super().__init__(out or sys.stdout, flush, own)

    def frame(self, f: Frame) -> None:
        self.out.write(frame_line(f, self.t0) + "\n")
        if self.flush_each:
            self.out.flush()
