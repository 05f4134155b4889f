"""What each output is in a capture decoded by parts: a plan (the worker's half) and a writer (the coordinator's).

A plan is a small picklable description sent to every worker.  For each part the
worker makes `plan.part_sink(info, first)`, a pipeline sink fed the part's raw
events (if `wants_raw`) and frames, already numbered as in the whole capture;
its `piece()` is what crosses back.  The coordinator's writer (`writer(...)`)
takes the pieces in capture order and writes the output, which is then byte for
byte what one process writes:

    text, jsonl     the lines of the part (a stream sink on a string)
    pcap, pcapng    the packets of the part (the first part with the file's header)
    csv             the rows of the part, per file (the first part with the header)
    golden          `sniffer check`'s lines of the part
    frames          the frames themselves, for a sink that must see every frame in one process
                    (the report's collector): it runs there, on them
    calls           the frames and raw events, in one process's order, fed to any sink there
                    (SinkWriter): the way to run a sink set the workers cannot split

MCAP and Parquet (formats/mcap, formats/parquet) need one writer over the whole
capture (chunks, indexes, row groups): their plans are in sniffer.parallel.whole.
"""

from __future__ import annotations

import io

from sniffer.sinks.base import Sink


class _Bytes(Sink):
    """A file sink of one format writing into memory; the piece is its bytes, less the file's header (what
    start() alone writes) unless `first`."""

    def __init__(self, make, first: bool, files: int = 1) -> None:
        self.bufs = [_Keep() for _ in range(files)]
        self.sink = make(*self.bufs)
        self.first = first
        self.heads = [0] * files

    def start(self, info) -> None:
        self.sink.start(info)
        self.heads = [len(b.getvalue()) for b in self.bufs]

    def frame(self, f) -> None:
        self.sink.frame(f)

    def close(self) -> None:
        self.sink.close()

    def piece(self):
        out = [b.getvalue()[0 if self.first else h:] for b, h in zip(self.bufs, self.heads)]
        return out[0] if len(out) == 1 else out


class _Keep(io.BytesIO):
    """BytesIO whose bytes outlive close() (a sink closes its file)."""

    saved = b""

    def close(self) -> None:
        if not self.closed:
            self.saved = self.getvalue()
        super().close()

    def getvalue(self) -> bytes:
        return self.saved if self.closed else super().getvalue()


class StreamPlan:
    """The text or JSONL lines (replay's stdout, or export --to jsonl / a .txt file)."""

    def __init__(self, kind: str) -> None:
        self.kind = kind

    def part_sink(self, info, first: bool):
        if self.kind == "jsonl":
            from sniffer.formats.jsonl import JsonlSink

            return _Stream(JsonlSink(_Keep()))
        from sniffer.formats.text import TextSink

        return _Stream(TextSink(io.StringIO()))


class _Stream(Sink):
    def __init__(self, sink) -> None:
        self.sink = sink
        self.start, self.frame = sink.start, sink.frame

    def close(self) -> None:
        self.sink.flush()  # the lines it holds, into the buffer (which stays open)

    def piece(self):
        return self.sink.out.getvalue()


class StreamWriter:
    """The lines, in order, to a stream (stdout: `flush` once per part, as a one-process replay would batch)."""

    outputs: tuple = ()

    def __init__(self, out) -> None:
        self.out = out

    def begin(self, info) -> None:
        pass

    def add(self, piece) -> None:
        if piece:
            self.out.write(piece)

    def close(self) -> None:
        self.out.flush()


class FilePlan:
    """A file format whose file is its header and then each frame's bytes: pcap, pcapng, csv (two files)."""

    def __init__(self, fmt: str, path: str) -> None:
        self.fmt, self.path = fmt, path

    def part_sink(self, info, first: bool, header: bool = False):
        """The part's bytes, without the file's header (the writer writes it first: `header`)."""
        fmt = self.fmt
        if fmt in ("pcap", "pcapng"):
            from sniffer.formats.pcap.writer import PcapSink

            return _Bytes(lambda b: PcapSink(b, ng=fmt == "pcapng" or self.path.endswith(".pcapng")), header)
        if fmt == "csv":
            from sniffer.formats.csvexport import CsvSink

            return _Bytes(lambda a, b: CsvSink(a, b), header, files=2)
        if fmt in ("jsonl", "text"):
            return StreamPlan(fmt).part_sink(info, first)
        raise ValueError(f"no part sink for {fmt}")

    def header(self, info) -> list:
        """What the file's sink writes before any frame (its start()), per file."""
        s = self.part_sink(info, True, header=True)
        s.start(info)
        s.close()
        got = s.piece()
        return got if isinstance(got, list) else [got]


class FileWriter:
    """The pieces of a FilePlan into the output's part files (sniffer.formats.outputs: renamed when complete)."""

    def __init__(self, file_sink, plan: FilePlan) -> None:
        self.outputs = file_sink.outputs
        self.plan = plan
        self.text = file_sink.fmt == "text"
        self._files: list = []

    def begin(self, info) -> None:
        """The part files made and the header written and flushed (a full disk fails now, as in one process)."""
        for o in self.outputs:
            self._files.append(open(o.part, "w" if self.text else "wb", encoding="utf-8" if self.text else None,
                                    buffering=1 << 16))
        if self.plan.fmt in ("pcap", "pcapng", "csv"):
            for fh, head in zip(self._files, self.plan.header(info)):
                fh.write(head)
                fh.flush()

    def add(self, piece) -> None:
        pieces = piece if isinstance(piece, list) else [piece]
        for fh, data in zip(self._files, pieces):
            if data:
                fh.write(data)

    def close(self) -> None:
        first = None
        for fh in self._files:
            try:
                fh.close()
            except OSError as e:
                first = first or e
        if first is not None:
            raise first


class GoldenPlan:
    """`sniffer check`'s golden lines of the part (analysis.check.golden_line), and the point names they
    hold (the anchors check's summary splits a changed line on)."""

    def __init__(self, version: int = 2) -> None:
        self.version = version

    def part_sink(self, info, first: bool):
        return _Golden(self.version)


class _Golden(Sink):
    def __init__(self, version: int) -> None:
        from sniffer.analysis.goldenfields import Names

        self.version = version
        self.lines: list[str] = []
        self.names = Names()
        self.t0 = 0

    def start(self, info) -> None:
        self.t0 = info.t0_ns

    def frame(self, f) -> None:
        from sniffer.analysis.check import golden_line

        self.names.add_frame(f)
        self.lines.append(golden_line(f, self.t0, self.version))

    def piece(self):
        return self.lines, sorted(self.names.names)


class FramesPlan:
    """The frames themselves, for a sink that must see them all in one process (it runs in the coordinator)."""

    def part_sink(self, info, first: bool):
        return _Frames()


class _Frames(Sink):
    def __init__(self) -> None:
        self.frames: list = []

    def frame(self, f) -> None:
        f.peer = None
        self.frames.append(f)

    def piece(self):
        return self.frames  # pickled as their slots (Frame.__reduce__)


class CallsPlan:
    """The part's sink calls themselves, for any sink run in the coordinator (SinkWriter): its frames, and with
    `raw` its raw events, in the order one process gives them."""

    def __init__(self, raw: bool = False) -> None:
        self.wants_raw = raw

    def part_sink(self, info, first: bool):
        return _Calls(self.wants_raw)


class _Calls(Sink):
    def __init__(self, raw: bool) -> None:
        self.wants_raw = raw
        self.calls: list = []
        self.trailer: list = []  # frames one process hands on after the next part's first event

    def raw(self, event) -> None:
        from sniffer.parallel.events import pack

        self.calls.append(pack(event))

    def frame(self, f) -> None:
        f.peer = None
        self.calls.append(f)

    def after(self, f) -> None:
        f.peer = None
        self.trailer.append(f)

    def piece(self):
        return self.calls, self.trailer


class SinkWriter:
    """Any pipeline sink (sniffer.sinks.base.Sink) fed a CallsPlan's pieces in order: start, every raw event and
    frame as one process calls them, close.  What a command runs in the coordinator when it must see every
    frame in one place (a diagnosis over the whole capture).  A planned file (sniffer.formats.FileSink) that
    does not split is opened at begin()."""

    def __init__(self, sink) -> None:
        self.sink = sink
        self.outputs = tuple(getattr(sink, "outputs", ()))  # a plain object with the four calls has none
        self.held: list = []

    def begin(self, info) -> None:
        from sniffer.formats import FileSink

        if isinstance(self.sink, FileSink):
            self.sink = self.sink.open()
        self.sink.start(info)

    def add(self, piece) -> None:
        from sniffer.parallel.events import unpack

        calls, trailer = piece
        held, self.held = self.held, trailer
        raw, frame = self.sink.raw, self.sink.frame
        for c in calls:
            if type(c) is tuple:
                raw(unpack(c))
                for f in held:  # the part before's last frames: after this part's first event
                    frame(f)
                held = []
            else:
                for f in held:  # (no raw events asked for: they simply follow)
                    frame(f)
                held = []
                frame(c)
        for f in held:
            frame(f)

    def close(self) -> None:
        for f in self.held:
            self.sink.frame(f)
        self.held = []
        self.sink.close()


class HealthPlan:
    """What the line warning counts of each frame (link, time, bytes, what made it bad: a few bytes a frame,
    not the frame): a replay by parts warns as one process does, without sending every frame here."""

    def part_sink(self, info, first: bool):
        return _Health()


class _Health(Sink):
    def __init__(self) -> None:
        from sniffer.analysis.linehealth import badness

        self.rows: list = []
        self.badness = badness

    def frame(self, f) -> None:
        self.rows.append((f.link or "", f.t_ns, len(f.raw), self.badness(f)))

    def piece(self):
        return self.rows


class HealthWriter:
    """The line warning (sniffer.analysis.linehealth.LineWarning) fed the parts' HealthPlan rows in order."""

    outputs: tuple = ()

    def __init__(self, warning) -> None:
        self.warning = warning

    def begin(self, info) -> None:
        self.warning.start(info)

    def add(self, piece) -> None:
        observe = self.warning.observe
        for row in piece:
            observe(*row)

    def close(self) -> None:
        pass


def file_output(file_sink) -> tuple:
    """(plan, writer) of a planned output file (sniffer.formats.FileSink) of any export format."""
    fmt = file_sink.fmt
    if fmt == "mcap":
        from sniffer.parallel.whole import McapPlan, McapWriter

        return McapPlan(), McapWriter(file_sink)
    if fmt == "parquet":
        from sniffer.parallel.whole import ParquetPlan, ParquetWriter

        return ParquetPlan(), ParquetWriter(file_sink)
    plan = FilePlan(fmt, file_sink.path)
    return plan, FileWriter(file_sink, plan)


def _stream_output(sink) -> tuple:
    """A text or JSONL stream sink (replay's stdout): the lines by parts, written in order to its stream."""
    return StreamPlan(sink.kind), StreamWriter(sink.out)


def _health_output(warning) -> tuple:
    return HealthPlan(), HealthWriter(warning)


# how a sink splits into parts, by the name it gives (`Sink.split`, `FileSink.split`): (plan, writer) of it
SPLITS = {"file": file_output, "stream": _stream_output, "health": _health_output}


def split(sink) -> tuple:
    """(plan, writer) of any sink or planned file: by its `split`, else it runs in the coordinator, fed every
    frame and raw event in one process's order (CallsPlan, SinkWriter)."""
    if isinstance(sink, tuple):  # split already: (plan, writer)
        return sink
    how = getattr(sink, "split", None)  # a FileSink plan is no Sink: it says it too
    if how is not None:
        return SPLITS[how](sink)
    return CallsPlan(raw=True), SinkWriter(sink)


def stdout_for(kind: str):
    import sys

    return sys.stdout.buffer if kind == "jsonl" else sys.stdout


__all__ = ["SPLITS", "CallsPlan", "FilePlan", "FileWriter", "FramesPlan", "GoldenPlan", "HealthPlan", "HealthWriter",
           "SinkWriter", "StreamPlan", "StreamWriter", "file_output", "split", "stdout_for"]
