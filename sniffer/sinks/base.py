"""The sink interface: where decoded frames (and the raw events) go, and every hook the capture calls on one.

A sink gets `start(info)` once, `raw(event)` for every source event, `frame(f)`
for every settled, decoded frame, and `close()` at the end (also after an
error).  The base class does nothing, so a sink overrides only what it uses;
the session calls the optional hooks below only on the sinks that override them
(`overrides`), so a sink that has none costs nothing between two events:

    bind(pipeline)      once the pipeline exists: a sink that cuts parts later (segments, trigger windows,
                        dataset files) keeps its `decoder_state`, `state_version`, `waiting` readers
    maybe_flush()       between two events: write what wall time made due (an MCAP chunk, the status file)
    advance(t_ns)       the capture's time, every event (windows close, a quiet line is noticed)
    rotate_if(settled)  between two events, while `rotate_due`: cut the next segment if the pipeline settled
    status()            its section of the status file ({} : none)

What it leaves: `outputs` (sniffer.formats.outputs.Output; the session renames them
into place when the capture ends well), `kept_parts` (files cut short and kept as
parts), `written_text` (what it wrote, for the end-of-run line; "" : nothing to say).

How it runs in a capture decoded by parts: `split` names its part plan
(sniffer.parallel.outputs.SPLITS: the workers' half and the coordinator's writer);
None: it runs whole, in the coordinator.
"""

from __future__ import annotations

from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.frame import Frame


class Sink:
    outputs: tuple = ()
    kept_parts: tuple = ()
    written_text: str = ""
    rotate_due: bool = False
    split: str | None = None

    def start(self, info: CaptureInfo) -> None:
        pass

    def raw(self, event: Chunk | Tick | Gap) -> None:
        pass

    def frame(self, frame: Frame) -> None:
        pass

    def close(self) -> None:
        pass

    def bind(self, pipeline) -> None:
        pass

    def maybe_flush(self) -> None:
        pass

    def advance(self, t_ns: int) -> None:
        pass

    def rotate_if(self, settled: int) -> None:
        pass

    def status(self) -> dict:
        return {}


def overrides(sink, hook: str) -> bool:
    """Whether `sink` does something on `hook` (a Sink that overrides it; a plain object with the four calls
    start/raw/frame/close, a test's list, has no other hooks)."""
    return isinstance(sink, Sink) and getattr(type(sink), hook) is not getattr(Sink, hook)
