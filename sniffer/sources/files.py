"""Open any capture file for replay: MCAP, byte CSV, Saleae CSV, pcap/pcapng, a sigrok logic capture (.sr).

`FileSource` is the one object every file capture goes through:

    src = FileSource(path, fmt)
    info = src.open()            # CaptureError: one line, nothing to replay
    for ev in src.events():      # lazy; memory does not grow with the file
        ...
    src.damage                   # what was skipped or lost on the way, one sentence each

Refused at open(): a missing or unreadable path, a directory, a FIFO,
device or socket (replaying one would block or never end), an empty file,
an unknown format.  Damage found while reading does not stop the replay:
the reader skips what it cannot read, yields a Gap there and says so in
`damage` (see each reader's docstring for what is damage and what is fatal).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator

from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.events import CaptureError
from sniffer.formats.reading import EmptyCapture
from sniffer.formats.reading import quote
from sniffer.inputs import not_regular

FORMATS = ("auto", "mcap", "csv", "saleae", "pcap", "sigrok")
# --input-format NAME -> the format table's name (a "csv" input is the byte CSV)
INPUT_NAMES = {"mcap": "mcap", "csv": "bytecsv", "saleae": "saleae", "pcap": "pcap", "sigrok": "sigrok"}


def _reader(path: str, fmt: str, damage: list[str], logic=None):
    from sniffer.formats import reader_module

    if fmt == "auto":
        for name in ("mcap", "sigrok", "csv", "pcap", "saleae"):  # the order matters: a Saleae export is a CSV too
            if reader_module(INPUT_NAMES[name]).sniff(path):
                fmt = name
                break
        else:
            raise CaptureError(
                f"{path}: unknown capture format (expected MCAP from this tool, a byte CSV "
                "t_s,channel,byte_hex,flags, a Saleae async-serial CSV export, pcap/pcapng, or a sigrok .sr)"
            )
    if fmt == "sigrok":
        from sniffer.sources.sigrok_cli import file_source

        return fmt, file_source(path, logic, damage)
    if fmt not in INPUT_NAMES:
        raise CaptureError(f"unknown input format {quote(fmt, 40)} (one of {', '.join(FORMATS)})")
    return fmt, reader_module(INPUT_NAMES[fmt]).SOURCE(path, damage)


class FileSource:
    """A capture file as a stream of events (see the module docstring)."""

    def __init__(self, path: str | os.PathLike[str], fmt: str = "auto", logic=None) -> None:
        self.path = os.fspath(path)
        self.format = fmt
        self.logic = logic  # a sigrok .sr capture's channels (sources.logic_options.LogicSpec)
        self.damage: list[str] = []
        self._requested = fmt
        self._reader = None
        self._info: CaptureInfo | None = None
        self._stop = threading.Event()
        self._started = False
        self._closed = False

    def open(self) -> CaptureInfo:
        """The capture's CaptureInfo; CaptureError (one line) if it cannot be replayed.  Idempotent."""
        if self._info is not None:
            return self._info
        if self._requested not in FORMATS:
            raise CaptureError(f"unknown input format {quote(str(self._requested), 40)} (one of {', '.join(FORMATS)})")
        p = self.path
        try:
            st = os.stat(p)
        except OSError as e:
            raise CaptureError(f"{p}: {'no such file' if isinstance(e, FileNotFoundError) else e.strerror or e}") \
                from None
        why = not_regular(p, st.st_mode)
        if why is not None:
            raise CaptureError(why)
        if st.st_size == 0:
            raise EmptyCapture(f"{p}: empty file")
        self.format, reader = _reader(p, self._requested, self.damage, self.logic)
        if self.logic is not None and self.format != "sigrok":
            raise CaptureError(f"{p}: --rx/--tx/--de are for a sigrok logic capture (.sr); this is {self.format}")
        self._info = reader.open()
        self._reader = reader
        return self._info

    def events(self) -> Iterator[Chunk | Tick | Gap]:
        """The events, read lazily; ends early after stop().  May be called once."""
        if self._started:
            raise RuntimeError("FileSource.events() may be called once")
        self._started = True
        self.open()
        return self._events()

    def _events(self) -> Iterator[Chunk | Tick | Gap]:
        stopped = self._stop.is_set
        it = self._reader.events()
        try:
            for ev in it:
                if stopped() or self._closed:
                    return
                yield ev
        except ValueError:
            if not self._closed:  # the file was closed under a read in progress: that is the end
                raise
        finally:
            it.close()
            self.close()

    def stop(self) -> None:
        """Ask events() to end (from any thread): it checks before every event."""
        self._stop.set()

    def close(self) -> None:
        """Release the file (events() then ends).  Safe to call twice."""
        self._closed = True
        r = self._reader
        if r is not None:
            r.close()

    def position(self) -> tuple[int, int] | None:
        """(bytes read so far, file size) for a progress bar, or None before open()."""
        r = self._reader
        return None if r is None else r.position()


def open_replay(path: str, fmt: str = "auto", logic=None) -> tuple[CaptureInfo, Iterator[Chunk | Tick | Gap]]:
    """(CaptureInfo, events iterator) or CaptureError with one clear line (FileSource.damage is not seen here)."""
    src = FileSource(path, fmt, logic)
    return src.open(), src.events()
