"""Byte CSV writer: every source event's bytes as `t_s,channel,byte_hex,flags` rows (reader.py beside it reads it).

Per-byte chunks write each byte's own time; per-read chunks give all their
bytes the read's time, which is how the reader tells the two apart.
"""

from __future__ import annotations

from sniffer.events import Chunk
from sniffer.sinks.base import Sink


class ByteCsvSink(Sink):
    def __init__(self, path: str) -> None:
        self._fh = open(path, "w", newline="", encoding="utf-8", buffering=1 << 16)
        self.rows = 0

    def start(self, info) -> None:
        self._fh.write("t_s,channel,byte_hex,flags\n")

    def raw(self, ev) -> None:
        if type(ev) is not Chunk:
            return
        flags = dict(ev.flags)
        bt = ev.byte_t_ns
        lines = []
        for k, b in enumerate(ev.data):
            t = bt[k] if bt is not None else ev.t_ns
            lines.append(f"{t // 1_000_000_000}.{t % 1_000_000_000:09d},{ev.channel},{b:02x},{flags.get(k, '')}\n")
        self._fh.write("".join(lines))
        self.rows += len(lines)

    def close(self) -> None:
        self._fh.close()


def open_sink(fmt: str, path: str, parts: list[str]) -> ByteCsvSink:
    """The ByteCsv sink writing its part files (named in the table of sniffer.formats)."""
    return ByteCsvSink(parts[0])
