"""Where decoded frames go: one module per sink, one `make_sink` for the file formats.

    sink = make_sink("parquet", "line3.parquet", inputs=["line3.mcap"])

text / jsonl (stdout or a file), mcap, csv, parquet, pcap / pcapng (Wireshark),
bytecsv (the raw bytes, replayable), publish (viewers on a socket), and the
TUI's sink (sniffer/tui/sink.py).  Every file is written under a temporary
name and renamed into place by the session (sniffer.outputs).
"""

from __future__ import annotations

import os

from ..outputs import Output
from .base import Sink

EXPORT_FORMATS = ("csv", "parquet", "pcap", "pcapng", "mcap", "jsonl")
FORMATS = (*EXPORT_FORMATS, "text", "bytecsv")


class FileSink:
    """A file output planned before the capture opens: checked now, created by `open()`.

    `outputs` are the files it will write (sniffer.outputs.Output), checked at
    construction: a missing folder, a folder, or an input of the command is an
    OutputError (one line) before anything is opened or created.
    """

    def __init__(self, fmt: str, out: str | os.PathLike[str], *, inputs=(), what: str = "--out") -> None:
        if fmt not in FORMATS:
            raise ValueError(f"unknown output format {fmt!r}")
        self.fmt = fmt
        self.path = os.fspath(out)
        if fmt in ("csv", "parquet"):
            from .rows import points_path

            second = points_path(self.path, ".csv" if fmt == "csv" else ".parquet")
            self.outputs = (Output(self.path, inputs=inputs, what=what), Output(second, inputs=inputs, what=what))
        else:
            self.outputs = (Output(self.path, inputs=inputs, what=what),)

    def open(self) -> Sink:
        """The sink, writing the part files."""
        fmt, parts = self.fmt, [o.part for o in self.outputs]
        if fmt == "csv":
            from .csvfile import CsvSink

            sink: Sink = CsvSink(*parts)
        elif fmt == "parquet":
            from .parquet import ParquetSink

            sink = ParquetSink(*parts)
        elif fmt in ("pcap", "pcapng"):
            from .pcap import PcapSink

            sink = PcapSink(parts[0], ng=fmt == "pcapng" or self.path.endswith(".pcapng"))
        elif fmt == "mcap":
            from .mcap import McapSink

            sink = McapSink(parts[0])
        elif fmt == "jsonl":
            from .jsonl import JsonlSink

            sink = JsonlSink(open(parts[0], "wb", buffering=1 << 16), own=True)
        elif fmt == "text":
            from .text import TextSink

            sink = TextSink(open(parts[0], "w", encoding="utf-8", buffering=1 << 16), own=True)
        else:
            from .bytecsv import ByteCsvSink

            sink = ByteCsvSink(parts[0])
        sink.outputs = self.outputs
        return sink


def make_sink(fmt: str, out: str | os.PathLike[str], *, inputs=(), what: str = "--out") -> Sink:
    """FileSink(...).open(): a sink writing `out` (part files; the caller commits `sink.outputs`)."""
    return FileSink(fmt, out, inputs=inputs, what=what).open()
