"""The sink interface: where decoded frames (and the raw events) go.

A sink gets `start(info)` once, `raw(event)` for every source event, `frame(f)`
for every settled, decoded frame, and `close()` at the end (also after an
error).  The base class does nothing, so a sink overrides only what it uses.
A sink that writes files lists them in `outputs` (sniffer.formats.outputs.Output):
the session renames them into place when the capture ends well.
"""

from __future__ import annotations

from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.frame import Frame


class Sink:
    outputs: tuple = ()

    def start(self, info: CaptureInfo) -> None:
        pass

    def raw(self, event: Chunk | Tick | Gap) -> None:
        pass

    def frame(self, frame: Frame) -> None:
        pass

    def close(self) -> None:
        pass
