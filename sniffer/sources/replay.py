"""Open any capture file for replay: MCAP, byte CSV or Saleae CSV."""

from __future__ import annotations

import os

from . import CaptureError

FORMATS = ("auto", "mcap", "csv", "saleae", "pcap")


def open_replay(path: str, fmt: str = "auto"):
    """(CaptureInfo, events iterator) or CaptureError with one clear line."""
    from . import bytecsv, mcapsrc, pcapsrc, saleae

    if not os.path.exists(path):
        raise CaptureError(f"{path}: no such file")
    if os.path.isdir(path):
        raise CaptureError(f"{path}: is a directory, not a capture file")
    if fmt == "auto":
        if mcapsrc.sniff(path):
            fmt = "mcap"
        elif bytecsv.sniff(path):
            fmt = "csv"
        elif pcapsrc.sniff(path):
            fmt = "pcap"
        elif saleae.sniff(path):
            fmt = "saleae"
        else:
            raise CaptureError(
                f"{path}: unknown capture format (expected MCAP from this tool, a byte CSV "
                "t_s,channel,byte_hex,flags, a Saleae async-serial CSV export, or pcap/pcapng)"
            )
    if fmt == "mcap":
        return mcapsrc.open_mcap(path)
    if fmt == "csv":
        return bytecsv.open_byte_csv(path)
    if fmt == "saleae":
        return saleae.open_saleae_csv(path)
    if fmt == "pcap":
        return pcapsrc.open_pcap(path)
    raise CaptureError(f"unknown input format {fmt!r} (one of {', '.join(FORMATS)})")


class FileSource:
    """A capture file as a session source (TEMPORARY: wraps open_replay until the streaming readers land)."""

    def __init__(self, path: str, fmt: str = "auto") -> None:
        self.path = path
        self.format = fmt
        self.damage: list[str] = []
        self._info = None
        self._events = None
        self._stop = False

    def open(self):
        if self._info is None:
            self._info, self._events = open_replay(self.path, self.format)
        return self._info

    def events(self):
        self.open()
        for ev in self._events:
            if self._stop:
                return
            yield ev

    def stop(self) -> None:
        self._stop = True

    def close(self) -> None:
        close = getattr(self._events, "close", None)
        if close is not None:
            close()

    def position(self):
        return None
