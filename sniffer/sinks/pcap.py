"""pcap export that Wireshark/tshark decode as Modbus/RTU.

One packet per frame (noise frames included, so every byte is in the file),
classic pcap with nanosecond timestamps (magic a1b23c4d) or, for an OUT
ending in .pcapng, pcapng (nanosecond if_tsresol, line settings in the
interface description); link type 147 (LINKTYPE_USER0).  Wireshark maps a user DLT to a dissector through its
"user_dlts" table; for Modbus/RTU that is the `mbrtu` dissector:

    tshark -r out.pcap -o 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""'

(in the GUI: Preferences > Protocols > DLT_USER > Edit, DLT 147, payload
protocol `mbrtu`).  `TSHARK_ARGS` holds those options.  Requests and
responses travel in the same direction on a bus: mbrtu tells them apart by
its own request tracking.  Timestamps: the capture's wall-clock anchor +
the frame's start time (t0 = Unix epoch when the capture has no anchor).
"""

from __future__ import annotations

import os
import struct

from ..events import CaptureInfo
from ..frame import Frame
from .base import Sink

LINKTYPE_USER0 = 147
LINKTYPE_RTAC_SERIAL = 250
MAGIC_NS = 0xA1B23C4D
MAGIC_US = 0xA1B2C3D4
SNAPLEN = 65535
TSHARK_ARGS = ["-o", 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""']


def global_header(linktype: int = LINKTYPE_USER0) -> bytes:
    return struct.pack("<IHHiIII", MAGIC_NS, 2, 4, 0, 0, SNAPLEN, linktype)


def packet(t_ns: int, data: bytes) -> bytes:
    sec, ns = divmod(max(t_ns, 0), 1_000_000_000)
    return struct.pack("<IIII", sec, ns, len(data), len(data)) + data


def _block(btype: int, body: bytes) -> bytes:
    body += b"\0" * (-len(body) % 4)
    return struct.pack("<II", btype, len(body) + 12) + body + struct.pack("<I", len(body) + 12)


def _opt(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def pcapng_header(info: CaptureInfo, linktype: int = LINKTYPE_USER0) -> bytes:
    """Section header + one interface (nanosecond timestamps, the capture's source as its name)."""
    shb = _block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1)
                 + _opt(4, b"rs485-sniffer") + _opt(0, b""))  # shb_userappl
    line = f"{info.baud or '?'} {8}{info.parity or 'N'}{info.stopbits or 1}"
    idb = _block(1, struct.pack("<HHI", linktype, 0, SNAPLEN)
                 + _opt(2, (info.source or "rs485").encode()[:200])  # if_name
                 + _opt(3, f"RS-485 {info.protocol} {line}".encode())  # if_description
                 + _opt(9, b"\x09") + _opt(0, b""))  # if_tsresol: 10^-9
    return shb + idb


def pcapng_packet(t_ns: int, data: bytes) -> bytes:
    t = max(t_ns, 0)
    return _block(6, struct.pack("<IIIII", 0, t >> 32, t & 0xFFFFFFFF, len(data), len(data)) + data)


class PcapSink(Sink):
    """Pipeline sink: one pcap (or pcapng) packet per frame."""

    def __init__(self, out: str | os.PathLike[str], include_noise: bool = True, ng: bool | None = None) -> None:
        self.path = os.fspath(out)
        self.ng = self.path.endswith(".pcapng") if ng is None else ng  # pcapng by extension
        self.include_noise = include_noise
        self._fh = open(self.path, "wb", buffering=1 << 16)
        self._t0 = 0
        self._anchor = 0
        self.frames = 0

    def start(self, info: CaptureInfo) -> None:
        self._t0 = info.t0_ns
        self._anchor = info.wall_anchor_ns or 0
        self._fh.write(pcapng_header(info) if self.ng else global_header())
        self._fh.flush()  # a disk that is full already fails now, before the input is read

    def frame(self, f: Frame) -> None:
        if f.is_noise and not self.include_noise:
            return
        t = self._anchor + (f.t_ns - self._t0)
        self._fh.write(pcapng_packet(t, f.raw) if self.ng else packet(t, f.raw))
        self.frames += 1

    def close(self) -> None:
        self._fh.close()
