"""JSONL: one sniffer.records frame record per line (the contract other tools use)."""

from __future__ import annotations

import sys
from typing import BinaryIO

from ..frame import Frame
from ..records import frame_json
from .text import StreamSink


class JsonlSink(StreamSink):
    def __init__(self, out: BinaryIO | None = None, flush: bool = False, own: bool = False) -> None:
        super().__init__(out or sys.stdout.buffer, flush, own)

    def frame(self, f: Frame) -> None:
        self.out.write(frame_json(f, self.t0) + b"\n")
        if self.flush_each:
            self.out.flush()
