"""File formats: each one's reader and writer side by side, and the one table of them (as python-can's
`can/io/logger.py` keeps one).

    sink = make_sink("parquet", "line3.parquet", inputs=["line3.mcap"])     # a writer, by format name
    fmt = format_of("line3.pcapng")                                          # a format, by suffix

    mcap/      the capture format: format.py, writer.py, sink.py, reader.py, scan.py, repair.py, foxglove.py,
               segments.py + rotating.py + segset.py (a rotated capture's folder)
    pcap/      format.py, reader.py, writer.py;   bytecsv/  reader.py, writer.py
    saleae.py  csvstream.py  timeparse.py  (readers);  jsonl.py  text.py  csvexport.py  parquet.py  rows.py
    tables.py  schemas.py  (exports);  junit.py  check results for CI;  records.py  the frame record every
    writer shares;  files.py  open any
    capture file;  reading.py  what readers share;  outputs.py  temporary name, then rename

Adding a format is a module here and a row in `TABLE`; nothing else lists formats or their suffixes.
Every file is written under a temporary name and renamed into place by the session (formats/outputs.py).
"""

from __future__ import annotations

import importlib
import os
from dataclasses import dataclass

from sniffer import need
from sniffer.formats.outputs import Output
from sniffer.sinks.base import Sink


@dataclass(frozen=True)
class Format:
    name: str
    suffixes: tuple[str, ...]  # the first is what a file of this format is given
    writer: str | None = None  # "module:function" making its sink: (fmt, path, part paths) -> Sink
    reader: str | None = None  # "module" with `sniff(path)` and its source class `SOURCE`
    export: bool = False  # offered by `sniffer export --to`
    extra: str | None = None  # the optional extra its writer needs (sniffer.EXTRAS)
    parts: bool = False  # written by parts (sniffer.parallel.outputs.file_output), else whole in the coordinator
    stream: int = 0  # its place among the formats of the frames on stdout (`--format`; 1 the default), 0: none
    tui: int = 0  # its place in the TUI's export dialog, 0: not offered there


TABLE: tuple[Format, ...] = (
    Format("mcap", (".mcap",), "sniffer.formats.mcap.sink:open_sink", "sniffer.formats.mcap.reader", True,
           parts=True, tui=1),
    Format("csv", (".csv",), "sniffer.formats.csvexport:open_sink", None, True, parts=True, tui=3),
    Format("parquet", (".parquet",), "sniffer.formats.parquet:open_sink", None, True, extra="fleet", parts=True),
    Format("pcap", (".pcap",), "sniffer.formats.pcap.writer:open_sink", "sniffer.formats.pcap.reader", True,
           parts=True, tui=2),
    Format("pcapng", (".pcapng",), "sniffer.formats.pcap.writer:open_sink", None, True, parts=True, stream=3),
    Format("jsonl", (".jsonl",), "sniffer.formats.jsonl:open_sink", None, True, parts=True, stream=2),
    Format("text", (".txt",), "sniffer.formats.text:open_sink", parts=True, stream=1),
    Format("bytecsv", (".csv",), "sniffer.formats.bytecsv.writer:open_sink", "sniffer.formats.bytecsv.reader"),
    Format("saleae", (".csv",), None, "sniffer.formats.saleae"),
    Format("sigrok", (".sr",), None, "sniffer.sources.srzip"),  # decoded by sigrok-cli (sources/sigrok_cli.py)
)
WRITERS = {f.name: f for f in TABLE if f.writer}
EXPORT_FORMATS = tuple(f.name for f in TABLE if f.export)
STREAM_FORMATS = tuple(f.name for f in sorted(TABLE, key=lambda f: f.stream) if f.stream)  # the first: default
TUI_FORMATS = {f.name: f.suffixes[0] for f in sorted(TABLE, key=lambda f: f.tui) if f.tui}  # -> its extension
FORMATS = tuple(WRITERS)
# what a capture file's name may end in, longest first (a window or dataset name drops it)
CAPTURE_SUFFIXES = (".part", ".mcap", ".csv", ".pcapng", ".pcap")


def _load(ref: str):
    module, _, name = ref.partition(":")
    mod = importlib.import_module(module)
    return getattr(mod, name) if name else mod


def reader_module(name: str):
    """The reader module of input format `name` (its `sniff(path)` and `SOURCE`)."""
    return _load(next(f.reader for f in TABLE if f.name == name and f.reader))


def stem_of(path: str) -> str:
    """A capture file's name without its capture suffixes (`cab3.mcap.part` -> `cab3`)."""
    stem = os.path.basename(path)
    for ext in CAPTURE_SUFFIXES:
        stem = stem.removesuffix(ext)
    return stem


class FileSink:
    """A file output planned before the capture opens: checked now, created by `open()`.

    `outputs` are the files it will write (sniffer.formats.outputs.Output), checked at
    construction: a missing folder, a folder, or an input of the command is an
    OutputError (one line) before anything is opened or created.
    """

    def __init__(self, fmt: str, out: str | os.PathLike[str], *, inputs=(), what: str = "--out",
                 timed_flush: bool = True) -> None:
        """`timed_flush=False`: a file made from another (an export) is written out as its writer fills it,
        never because wall time passed (an MCAP's chunks then depend on its messages alone)."""
        if fmt not in WRITERS:
            raise ValueError(f"unknown output format {fmt!r}")
        if WRITERS[fmt].extra:
            need(WRITERS[fmt].extra, f"--to {fmt}")
        self.fmt = fmt
        self.split = "file" if WRITERS[fmt].parts else None  # how it is written by parts (sniffer.sinks.base.Sink)
        self.timed_flush = timed_flush
        self.path = os.fspath(out)
        if fmt in ("csv", "parquet"):
            from sniffer.formats.rows import points_path

            second = points_path(self.path, ".csv" if fmt == "csv" else ".parquet")
            self.outputs = (Output(self.path, inputs=inputs, what=what), Output(second, inputs=inputs, what=what))
        else:
            self.outputs = (Output(self.path, inputs=inputs, what=what),)

    def open(self) -> Sink:
        """The sink, writing the part files."""
        fmt, parts = self.fmt, [o.part for o in self.outputs]
        sink: Sink = _load(WRITERS[fmt].writer)(fmt, self.path, parts)
        sink.outputs = self.outputs
        if not self.timed_flush and hasattr(sink, "flush_interval_s"):
            sink.flush_interval_s = float("inf")
        return sink


def make_sink(fmt: str, out: str | os.PathLike[str], *, inputs=(), what: str = "--out") -> Sink:
    """FileSink(...).open(): a sink writing `out` (part files; the caller commits `sink.outputs`)."""
    return FileSink(fmt, out, inputs=inputs, what=what).open()
