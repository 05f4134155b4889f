"""Export from the TUI: the filtered view or the bookmarks, as MCAP, pcap or CSV (Textual-free).

The files are written by the sinks `sniffer export` uses (sniffer.formats.FileSink:
McapSink, PcapSink, CsvSink), under a part name renamed into place when complete
(sniffer.formats.outputs), so a failed export leaves nothing under the name asked for.
What is written is the frames as the TUI holds them, decoded once by the
capture: an MCAP's `/frames` are the view's records exactly; its `/raw` holds
one read per frame (the frame's bytes, returned at the frame's end, as a
USB adapter would deliver them), so `sniffer replay` of the file frames the
same bytes again (start times and latencies are then estimated from the baud,
as for any per-read capture).  pcap: one packet per frame; CSV: the frames and
points tables of `sniffer export --to csv`.

`Export(...)` checks a path and creates its part files (OutputError: one line)
before anything runs; `Export.run` goes on a worker thread over frames read from a snapshot of the store
(FrameBlocks.reader), so the UI goes on while 200k frames are written.
"""

from __future__ import annotations

import dataclasses
import os
import threading
from collections.abc import Callable, Iterable

from sniffer.events import CaptureInfo, Chunk
from sniffer.frame import Frame
from sniffer.formats.outputs import OutputError, shown
from sniffer.formats.mcap.segments import INDEX_NAME
from sniffer.formats import TUI_FORMATS, FileSink
from sniffer.formats.mcap.sink import CaptureStorageError
from sniffer.formats.rows import points_path

FORMATS = TUI_FORMATS  # format -> extension, in the modal's order (the formats' table)
WHATS = {"view": "view", "bookmarks": "bookmarks"}  # what -> the default file name's tag


def files_of(fmt: str, path: str) -> list[str]:
    """Every file an export to `path` writes (CSV: the frames table and its points table)."""
    return [path, os.fspath(points_path(path, ".csv"))] if fmt == "csv" and path.strip() else [path]


def existing(fmt: str, path: str) -> list[str]:
    """The files of an export to `path` that are there already (asked about before they are replaced)."""
    return [p for p in files_of(fmt, path) if os.path.lexists(p)]


def default_path(capture_path: str | None, what: str, fmt: str, *, folder: str | None = None) -> str:
    """Next to the capture (a file, or a rotated capture's folder; without one in `folder`, the working folder):
    `<capture stem>-<what><ext>`, with -2, -3 ... added while a file of that name is there, so the default
    never replaces anything."""
    if capture_path:
        capture_path = os.path.abspath(capture_path)  # a folder named with a trailing / too
        if os.path.basename(capture_path) == INDEX_NAME:  # a rotated capture's index: beside its folder
            capture_path = os.path.dirname(capture_path)
        folder = os.path.dirname(capture_path)
        from sniffer.formats import stem_of

        stem = stem_of(capture_path) or os.path.basename(capture_path)
    else:
        folder, stem = folder or os.getcwd(), "capture"
    base = os.path.join(folder, f"{stem}-{WHATS[what]}")
    ext = FORMATS[fmt]
    path, n = base + ext, 2
    while existing(fmt, path):
        path, n = f"{base}-{n}{ext}", n + 1
    return path


def with_extension(path: str, fmt: str) -> str:
    """`path` with the format's extension in place of another export format's (a name the user typed stays)."""
    root, ext = os.path.splitext(path)
    return root + FORMATS[fmt] if ext in FORMATS.values() or ext == ".pcapng" else path


def exported_info(info: CaptureInfo | None, what: str, n: int) -> CaptureInfo:
    """The capture's info for the exported file: its reads are one per frame (per read), and it says so."""
    info = info or CaptureInfo(source="tui")
    extra = {**info.extra, "tui_export": {"what": what, "frames": n, "raw": "one read per frame, at its end"}}
    return dataclasses.replace(info, time_source="read" if info.time_source != "none" else "none", extra=extra,
                               low_latency=dict(info.low_latency), devices=dict(info.devices))


def frame_read(f: Frame) -> Chunk:
    """A frame's bytes as one read returned when its last byte ended (the MCAP export's /raw)."""
    return Chunk(f.t_end_ns, f.raw, None, (), f.channel, f.link)


class Export:
    """One export: checked and its part files created on the UI thread (any problem: OutputError, one line),
    then `run` on a worker thread.  Its files are renamed into place when every frame is written, and removed
    if anything fails (the error is raised: OSError, the sinks' CaptureStorageError) or `stop` is set."""

    def __init__(self, fmt: str, path: str, what: str, *, inputs: Iterable[str] = ()) -> None:
        self.fmt, self.what = fmt, what
        path = os.path.expanduser(path.strip())
        if not path:
            raise OutputError("no file name given")
        self.out = FileSink(fmt, path, inputs=[p for p in inputs if p], what="export")
        self.path = self.out.path
        try:
            self.sink = self.out.open()
        except (OSError, CaptureStorageError) as e:
            for o in self.out.outputs:
                o.discard()
            text = str(e) if isinstance(e, CaptureStorageError) else f"{self.path}: cannot write: {e.strerror or e}"
            for o in self.out.outputs:
                text = text.replace(o.part, o.path)
            raise OutputError(shown(text, 300)) from None

    def run(self, frames: Iterable[Frame], n: int, info: CaptureInfo | None, *,
            progress: Callable[[int], None] | None = None, stop: threading.Event | None = None) -> int:
        """Write the `n` frames; returns how many were written (-1: stopped, nothing kept)."""
        sink = self.sink
        raw = sink.raw if self.fmt == "mcap" else None
        done = 0
        ok = False
        try:
            sink.start(exported_info(info, self.what, n))
            for f in frames:
                if raw is not None:
                    raw(frame_read(f))
                sink.frame(f)
                done += 1
                if done % 2048 == 0:
                    if stop is not None and stop.is_set():
                        break
                    if progress is not None:
                        progress(done)
            else:
                ok = True
        finally:
            try:
                sink.close()
            except BaseException:
                ok = False
                raise
            finally:
                for o in self.out.outputs:
                    o.commit() if ok else o.discard()
        return done if ok else -1

    def describe(self, n: int) -> str:
        """`N frames -> path` (and the points table of a CSV export)."""
        paths = [shown(o.path, 120) for o in self.out.outputs]
        return f"{n} frames -> {paths[0]}" + (f" (+ {paths[1]})" if len(paths) > 1 else "")
