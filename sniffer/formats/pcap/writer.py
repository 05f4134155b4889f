"""pcap export that Wireshark/tshark decode as Modbus/RTU.

One packet per frame (noise frames included, so every byte is in the file),
classic pcap with nanosecond timestamps (magic a1b23c4d) or, for an OUT
ending in .pcapng, pcapng (nanosecond if_tsresol, line settings in the
interface description); link type 147 (LINKTYPE_USER0); the format itself is
sniffer/formats/pcap/format.py.  Wireshark maps a user DLT to a dissector through its
"user_dlts" table; for Modbus/RTU that is the `mbrtu` dissector:

    tshark -r out.pcap -o 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""'

(in the GUI: Preferences > Protocols > DLT_USER > Edit, DLT 147, payload
protocol `mbrtu`).  `TSHARK_ARGS` holds those options.  Requests and
responses travel in the same direction on a bus: mbrtu tells them apart by
its own request tracking.  Timestamps: the capture's wall-clock anchor +
the frame's start time (t0 = Unix epoch when the capture has no anchor).
A capture of several links: in pcapng each link is an interface of its own
(named for the link); classic pcap has one, and holds every link's frames.
"""

from __future__ import annotations

import os

from sniffer.events import CaptureInfo
from sniffer.frame import Frame
from sniffer.formats.pcap.comments import frame_comment
from sniffer.formats.pcap.format import TSHARK_ARGS, global_header, packet, pcapng_header, pcapng_packet
from sniffer.sinks.base import Sink

__all__ = ["PcapSink", "TSHARK_ARGS", "global_header", "packet"]


class PcapSink(Sink):
    """Pipeline sink: one pcap (or pcapng) packet per frame."""

    def __init__(self, out, include_noise: bool = True, ng: bool | None = None, *, comments: bool = False,
                 flush: bool = False) -> None:
        """`out`: a path, or a binary file (closed with the sink).  `comments` (pcapng): each packet with a
        comment of what the sniffer knows of it (formats/pcap/comments.py); `flush`: after every packet (a
        live stream: Wireshark reading a pipe)."""
        if isinstance(out, (str, os.PathLike)):
            self.path = os.fspath(out)
            self._fh = open(self.path, "wb", buffering=1 << 16)
        else:
            self.path, self._fh = getattr(out, "name", ""), out
        self.ng = self.path.endswith(".pcapng") if ng is None else ng  # pcapng by extension
        self.include_noise = include_noise
        self.comments = comments and self.ng
        self.flush = flush
        self._t0 = 0
        self._anchor = 0
        self._interface: dict[str, int] = {}  # link -> pcapng interface
        self.frames = 0

    def start(self, info: CaptureInfo) -> None:
        self._t0 = info.t0_ns
        self._anchor = info.wall_anchor_ns or 0
        self._interface = {str(x.get("name")): k for k, x in enumerate(info.links)}
        self._fh.write(pcapng_header(info) if self.ng else global_header())
        self._fh.flush()  # a disk that is full already fails now, before the input is read

    def frame(self, f: Frame) -> None:
        if f.is_noise and not self.include_noise:
            return
        t = self._anchor + (f.t_ns - self._t0)
        if self.ng:
            note = frame_comment(f) if self.comments else ""
            self._fh.write(pcapng_packet(t, f.raw, self._interface.get(f.link, 0), note))
        else:
            self._fh.write(packet(t, f.raw))
        self.frames += 1
        if self.flush:
            self._fh.flush()

    def close(self) -> None:
        self._fh.close()


def open_sink(fmt: str, path: str, parts: list[str]) -> PcapSink:
    """The Pcap sink writing its part files (named in the table of sniffer.formats)."""
    return PcapSink(parts[0], ng=fmt == "pcapng" or path.endswith(".pcapng"))
