"""JSONL: one sniffer.records frame record per line (the contract other tools use)."""

from __future__ import annotations

import sys
from typing import BinaryIO

from ..frame import Frame
from ..records import frame_json
from .text import BATCH, StreamSink

__all__ = ["BATCH", "JsonlSink"]


class JsonlSink(StreamSink):
    """Lines written in batches, or one by one with `flush` (StreamSink)."""

    newline = b"\n"

    def __init__(self, out: BinaryIO | None = None, flush: bool = False, own: bool = False) -> None:
        super().__init__(out or sys.stdout.buffer, flush, own)

    def line(self, f: Frame) -> bytes:
        return frame_json(f, self.t0)
