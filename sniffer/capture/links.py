"""Several links on one timeline: one pipeline per link, one clock, one set of sinks.

A machine has two or three RS-485 links, or one 4-wire link tapped with two
receive-only adapters (--tap).  Each link is its own line: its own settings,
framer, pairer and decoders (a unit 1 on link A is not unit 1 on link B), so
a link's bytes never glue onto another's frames.  What they share:

* the clock: every event carries monotonic time (sources/serial_links.py stamps
  the reads of all ports under one lock, so the events come in time order);
* the frame numbers: one capture-wide sequence, given as a frame leaves its
  link's framer (Pipeline `numbering`), so `#N` and pairs name one frame;
* the sinks: one MCAP, one text/JSONL stream, one TUI.  Every event and frame
  carries its link's name (Chunk/Tick/Gap.link, Frame.link): the MCAP's
  /raw and /frames say which link (sniffer.formats.mcap.format), and a replay hands
  each link's events to that link's pipeline again, so it re-splits exactly.

`LinkPipelines` is what sniffer.capture.session drives when the capture's
CaptureInfo lists links (`info.links`): the same feed / flush / close as a
Pipeline.
"""

from __future__ import annotations

import itertools

from decoders.carry import of_info, record

from sniffer.events import CaptureInfo, Chunk
from sniffer.frame import CAN_REQ, CAN_RSP, Frame
from sniffer.capture.pipeline import Pipeline
from sniffer.capture.settings import MASTER, SLAVES, Resolved
from sniffer.events import CaptureError

TAP_ROLES = {MASTER: CAN_REQ, SLAVES: CAN_RSP}  # the master's pair carries requests, the slaves' pair responses


def link_names(info: CaptureInfo | None) -> list[str]:
    """The names of a capture's links, in order ([] for one line)."""
    return [str(x.get("name", "")) for x in (info.links if info is not None else ())]


class LinkPipelines:
    """One Pipeline per link of `info.links`, over the same sinks (see the module doc).

    `resolved` are the links' settings (name -> sniffer.capture.settings.Resolved);
    `registries` their decoder registries (each link decodes its own units).
    """

    def __init__(self, info: CaptureInfo, resolved: dict[str, Resolved], sinks) -> None:
        """`resolved`: every link's settings (CaptureSpec.resolve_link), by name, as `info.links` lists them."""
        self.info = info
        self.sinks = list(sinks)
        self.resolved = resolved
        self.registries = {}
        self.pipelines: dict[str, Pipeline] = {}
        for entry in info.links:
            resolved[str(entry.get("name", ""))].record_link(entry)
        first = self.resolved[link_names(info)[0]]
        first.record_in(info)  # the capture's own line fields: its first link's (tools that read one line)
        numbering = itertools.count()
        for entry in info.links:
            name = str(entry["name"])
            res = self.resolved[name]
            registry = self.registries[name] = res.registry(of_info(info, name))
            self.pipelines[name] = Pipeline(
                info, res.line, registry, self.sinks, protocol=res.protocol.name, timeout_ms=res.timeout_ms,
                unit_timeouts=res.unit_timeouts or None, link=name, numbering=numbering,
                directions=TAP_ROLES if entry.get("tap") else None, start=False)
        record(info, self.decoder_state())  # what the capture starts with (its first part, every copy)
        for s in self.sinks:
            s.start(info)

    @property
    def frames_out(self) -> int:
        return sum(p.frames_out for p in self.pipelines.values())

    @property
    def bytes_in(self) -> int:
        return sum(p.bytes_in for p in self.pipelines.values())

    @property
    def noise_bytes(self) -> int:
        return sum(p.noise_bytes for p in self.pipelines.values())

    def feed(self, ev) -> list[Frame]:
        p = self.pipelines.get(ev.link)
        if p is not None:
            return p.feed(ev)
        if type(ev) is Chunk or ev.link:
            raise CaptureError(f"bytes of a link {ev.link!r} the capture does not list "
                               f"(links: {', '.join(self.pipelines)})")
        # a Tick or Gap of no link (a file reader's gap over damage): every link's
        for s in self.sinks:
            s.raw(ev)
        out: list[Frame] = []
        for p in self.pipelines.values():
            out += p.feed(ev, record=False)
        return out

    def decoder_state(self) -> dict:
        """Every link's carried decoder state (Pipeline.decoder_state)."""
        return {name: reg.carried() for name, reg in self.registries.items()}

    def state_version(self) -> int:
        return sum(reg.version() for reg in self.registries.values())

    def settled(self, link: str | None = None) -> int:
        """Pipeline.settled of `link`, or of the least settled link (2: nothing pending on any link)."""
        p = self.pipelines.get(link) if link is not None else None
        return p.settled() if p is not None else min(p.settled() for p in self.pipelines.values())

    def flush(self) -> list[Frame]:
        out: list[Frame] = []
        for p in self.pipelines.values():
            out += p.flush()
        return out

    def close(self) -> None:
        next(iter(self.pipelines.values())).close()  # the sinks are shared: closed once

    def finish(self) -> list[Frame]:
        try:
            return self.flush()
        finally:
            self.close()
