"""One trigger window as a capture file: an MCAP like any other (replayable alone), plus its trigger.

The file holds the capture's metadata (`/capture`, `sniffer.capture`, with `extra.trigger` naming
the first rule and frame: known even in a file cut short; `extra.decoder_state` what the decoders
knew where it starts, decoders/carry.py), the /raw events and /frames records of
the window, and, once complete, a `sniffer.trigger` metadata record (`read_trigger`): every rule
that fired in it with its frame (time, wall clock, index, one-line summary, JSON record), how many
frames matched each rule, the spans asked for and kept.  Written as NAME.part, renamed when done.
"""

from __future__ import annotations

import os
import re

import msgspec

from decoders.carry import record

from sniffer.events import CaptureInfo
from sniffer.formats.outputs import Output
from sniffer.formats.mcap.sink import McapSink

METADATA = "sniffer.trigger"
_NUMBERED = re.compile(r"\.trigger-(\d+)\.mcap\Z")


def next_number(folder: str, stem: str) -> int:
    """The number after the highest `STEM.trigger-N.mcap` in the folder (a restarted capture goes on)."""
    best = 0
    try:
        names = os.listdir(folder or ".")
    except OSError:
        return 1
    for name in names:
        if name.startswith(stem + ".trigger-"):
            m = _NUMBERED.search(name.removesuffix(".part"))
            if m and name[:m.start()] == stem:
                best = max(best, int(m.group(1)))
    return best + 1


def window_path(folder: str, stem: str, n: int) -> str:
    return os.path.join(folder, f"{stem}.trigger-{n:04d}.mcap")


class WindowFile:
    def __init__(self, path: str, info: CaptureInfo, first: dict, decoder_state: dict | None = None) -> None:
        self.output = Output(path, what="--windows")
        self.output.claim()
        self.path = path
        copy = CaptureInfo.from_dict(info.to_dict())
        copy.extra = {**copy.extra, "trigger": first}
        if decoder_state is not None:
            record(copy, decoder_state)
        self.sink = McapSink(self.output.part, compact=True)
        self.sink.start(copy)
        self.raw_events = self.frames = self.line_bytes = 0
        self.first_ns: int | None = None  # the first raw event's time
        self.last_ns: int | None = None
        self.tail_open = True  # past the window's end, the reads that finish a frame begun are still taken

    def raw(self, t_ns: int, log_ns: int, data: bytes, line_bytes: int = 0) -> None:
        """An encoded /raw event at t_ns (its first byte); `line_bytes`: the line's bytes it carries."""
        self.sink.encoded("raw", log_ns, data)
        self.raw_events += 1
        self.line_bytes += line_bytes
        if self.first_ns is None:
            self.first_ns = t_ns
        self.last_ns = t_ns

    def frame(self, t_ns: int, data: bytes) -> None:
        self.sink.encoded("frame", t_ns, data)
        self.frames += 1

    def finish(self, meta: dict) -> str:
        """Write the trigger record, close, rename into place; the path."""
        try:
            self.sink.add_metadata(METADATA, {k: msgspec.json.encode(v).decode() for k, v in meta.items()})
            self.sink.close()
        except BaseException:
            self.abandon()
            raise
        self.output.commit()
        return self.path

    def abandon(self) -> str | None:
        """It cannot be finished (a full disk): what reached the disk stays as the part file (its path), or
        nothing does (None).  Never under the window's name: that is for a complete window."""
        try:
            self.sink.close()
        except Exception:  # noqa: BLE001 - already failing
            pass
        return self.output.part if self.output.keep_part() else None

    def discard(self) -> None:
        try:
            self.sink.close()
        except Exception:  # noqa: BLE001 - already failing
            pass
        self.output.discard()


def read_trigger(path: str) -> dict:
    """The `sniffer.trigger` record of a window file (values decoded), {} if it has none."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        for m in make_reader(fh).iter_metadata():
            if m.name == METADATA:
                return {k: msgspec.json.decode(v) for k, v in m.metadata.items()}
    return {}


__all__ = ["METADATA", "WindowFile", "next_number", "read_trigger", "window_path"]
