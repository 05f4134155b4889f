"""Several serial ports captured at once, read-only: several links, or the two wires of a --tap.

Each port is a `SerialSource` (opened O_RDONLY, raw, nothing ever written:
serial_live.py) with its own reader thread; all of them hand their events to
one `Hub`, stamped under one lock, so `events()` is one stream in time order
on one clock.  `sniffer live` runs them all in one reader process
(processes/reader.py), whose pipe keeps that order.  Every event carries its link's name; a tapped link's two ports
carry their wire too (Chunk.channel: "master" for the master's pair, "slaves"
for the slaves' pair).

`open()` opens every port before anything is written anywhere: a port that
cannot be opened (a missing second adapter) closes the ones already open and
raises CaptureError naming it, so the command ends with one line and no file.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Protocol

from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.line import LineSettings
from sniffer.sources.serial_live import Hub, SerialSource


class LinkPlan(Protocol):
    """What the source reads of a link's plan (capture/settings.py's LinkPlan): its name, its ports and
    their channels, and its capture-info entry."""

    name: str
    ports: tuple[str, ...]

    @property
    def channels(self) -> tuple[str, ...]: ...

    def entry(self) -> dict: ...


class LinksSource:
    """The ports of several links (`plans`, each with the LineSettings it runs at) as one source."""

    def __init__(self, plans: list[tuple[LinkPlan, LineSettings]], hub: Hub | None = None, **serial_kw) -> None:
        self.plans = plans
        self.serial_kw = serial_kw
        self.hub = hub or Hub()
        self.readers: list[SerialSource] = []
        self.info: CaptureInfo | None = None

    @property
    def port(self) -> str:
        return " ".join(p for plan, _ in self.plans for p in plan.ports)

    def open(self) -> CaptureInfo:
        if self.info is not None:
            return self.info
        try:
            for plan, line in self.plans:
                for port, channel in zip(plan.ports, plan.channels):
                    reader = SerialSource(port, line, hub=self.hub, link=plan.name, channel=channel,
                                          **self.serial_kw)
                    reader.open()  # CaptureError("<port>: <why>") for a port that is not there
                    self.readers.append(reader)
        except BaseException:
            self.stop()
            raise
        first = self.readers[0].info  # opened first: every event is at or after its t0
        links = []
        for plan, line in self.plans:
            entry = plan.entry()  # and the settings its ports were opened at
            entry.update(baud=line.baud, parity=line.parity, stopbits=line.stopbits, databits=line.databits)
            entry["low_latency"] = {r.port: r.info.low_latency for r in self.readers if r.link == plan.name}
            ignored = {r.port: r.ignored for r in self.readers if r.link == plan.name and r.ignored}
            if ignored:
                entry["line_ignored"] = ignored
            links.append(entry)
        self.info = CaptureInfo(
            source="serial:" + ",".join(r.port for r in self.readers), port=self.port, baud=first.baud,
            parity=first.parity, stopbits=first.stopbits, databits=first.databits, time_source="read",
            t0_ns=first.t0_ns, wall_anchor_ns=first.wall_anchor_ns, low_latency=dict(first.low_latency), links=links,
        )
        return self.info

    def events(self) -> Iterator[Chunk | Tick | Gap]:
        """Every port's events, in time order, until stop() ended every reader."""
        self.open()
        yield from self.hub.events(len(self.readers))

    def stop(self) -> None:
        for r in self.readers:
            r._stop.set()  # all at once: each join below then takes one poll at most
        for r in self.readers:
            r.stop()
