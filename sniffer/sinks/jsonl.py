"""JSONL: one sniffer.records frame record per line (the contract other tools use)."""

from __future__ import annotations

import sys
from typing import BinaryIO

from ..events import CaptureInfo
from ..frame import Frame
from ..records import dumps, frame_record


class JsonlSink:
    def __init__(self, out: BinaryIO | None = None, flush: bool = False) -> None:
        self.out = out or sys.stdout.buffer
        self.flush_each = flush
        self.t0 = 0

    def start(self, info: CaptureInfo) -> None:
        self.t0 = info.t0_ns

    def raw(self, event) -> None:
        pass

    def frame(self, f: Frame) -> None:
        self.out.write(dumps(frame_record(f, self.t0)) + b"\n")
        if self.flush_each:
            self.out.flush()

    def close(self) -> None:
        self.out.flush()
