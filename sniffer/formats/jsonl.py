"""JSONL: one sniffer.formats.records frame record per line (the contract other tools use)."""

from __future__ import annotations

import sys
from typing import BinaryIO

from sniffer.frame import Frame
from sniffer.formats.records import frame_json
from sniffer.formats.text import BATCH, StreamSink

__all__ = ["BATCH", "JsonlSink"]


class JsonlSink(StreamSink):
    """Lines written in batches, or one by one with `flush` (StreamSink)."""

    newline = b"\n"
    kind = "jsonl"
    split = "stream"  # by parts: its lines, written in order (sniffer.parallel.outputs)

    def __init__(self, out: BinaryIO | None = None, flush: bool = False, own: bool = False) -> None:
        super().__init__(out or sys.stdout.buffer, flush, own)

    def line(self, f: Frame) -> bytes:
        return frame_json(f, self.t0)


def open_sink(fmt: str, path: str, parts: list[str]) -> JsonlSink:
    """The Jsonl sink writing its part files (named in the table of sniffer.formats)."""
    return JsonlSink(open(parts[0], "wb", buffering=1 << 16), own=True)
