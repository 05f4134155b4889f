"""pcap / pcapng from other serial sniffers as a replay source.

Accepted link types: 147 (LINKTYPE_USER0, the raw serial frame: what our own
pcap export and most serial-sniffer tools write) and 250 (SEL RTAC serial:
a 12-byte header - timestamp, event type, control lines, footer - then the
bytes).  Other link types are a CaptureError naming the type.

A packet's time is when the sniffer emitted it, not a per-byte wire time, so
the events are per-read Chunks (`time_source` "read"), one per packet, each
followed by a silence Tick up to the next packet so the framer closes frames
as the original tool cut them.  pcap does not say the baud rate: give it.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator

from ..events import CaptureInfo, Chunk, Tick
from . import CaptureError

LINKTYPE_USER0 = 147
LINKTYPE_RTAC_SERIAL = 250
RTAC_HEADER = 12
SUPPORTED = (LINKTYPE_USER0, LINKTYPE_RTAC_SERIAL)

_PCAP_MAGIC = {
    b"\xd4\xc3\xb2\xa1": ("<", 1000), b"\xa1\xb2\xc3\xd4": (">", 1000),
    b"\x4d\x3c\xb2\xa1": ("<", 1), b"\xa1\xb2\x3c\x4d": (">", 1),
}
_PCAPNG_SHB = b"\x0a\x0d\x0d\x0a"


def sniff(path: str | os.PathLike[str]) -> bool:
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
    except OSError:
        return False
    return head in _PCAP_MAGIC or head == _PCAPNG_SHB


def _pcap_packets(data: bytes, path: str) -> Iterator[tuple[int, int, bytes]]:
    end, mult = _PCAP_MAGIC[data[:4]]
    if len(data) < 24:
        raise CaptureError(f"{path}: truncated pcap header")
    linktype = struct.unpack_from(end + "I", data, 20)[0] & 0x0FFFFFFF
    pos = 24
    while pos + 16 <= len(data):
        sec, frac, incl, _orig = struct.unpack_from(end + "IIII", data, pos)
        pos += 16
        if pos + incl > len(data):
            break  # a truncated last packet (killed capture): keep what is complete
        yield linktype, sec * 1_000_000_000 + frac * mult, data[pos:pos + incl]
        pos += incl


def _tsresol(opts: bytes, end: str) -> int:
    """ns per timestamp unit from an IDB's options (default microseconds)."""
    pos = 0
    while pos + 4 <= len(opts):
        code, length = struct.unpack_from(end + "HH", opts, pos)
        if code == 0:
            break
        if code == 9 and length >= 1:
            v = opts[pos + 4]
            units_per_s = 2 ** (v & 0x7F) if v & 0x80 else 10 ** v
            return max(1, 1_000_000_000 // units_per_s) if units_per_s <= 1_000_000_000 else 1
        pos += 4 + length + (-length % 4)
    return 1000


def _pcapng_packets(data: bytes, path: str) -> Iterator[tuple[int, int, bytes]]:
    pos, end = 0, "<"
    ifaces: list[tuple[int, int]] = []  # (linktype, ns per unit)
    while pos + 12 <= len(data):
        btype = struct.unpack_from(end + "I", data, pos)[0]
        if btype == 0x0A0D0D0A:
            end = "<" if data[pos + 8:pos + 12] == b"\x4d\x3c\x2b\x1a" else ">"
            ifaces = []
        blen = struct.unpack_from(end + "I", data, pos + 4)[0]
        if blen < 12 or pos + blen > len(data):
            break  # truncated tail
        body = data[pos + 8:pos + blen - 4]
        if btype == 1 and len(body) >= 8:  # interface description
            linktype = struct.unpack_from(end + "H", body, 0)[0]
            ifaces.append((linktype, _tsresol(body[8:], end)))
        elif btype == 6 and len(body) >= 20:  # enhanced packet
            iid, hi, lo, incl, _orig = struct.unpack_from(end + "IIIII", body, 0)
            if iid >= len(ifaces):
                raise CaptureError(f"{path}: packet on undeclared interface {iid}")
            lt, ns = ifaces[iid]
            yield lt, ((hi << 32) | lo) * ns, body[20:20 + incl]
        elif btype == 3 and len(body) >= 4 and ifaces:  # simple packet: no time
            lt, _ns = ifaces[0]
            yield lt, 0, body[4:4 + struct.unpack_from(end + "I", body, 0)[0]]
        pos += blen


def read_packets(path: str | os.PathLike[str]) -> list[tuple[int, int, bytes]]:
    """[(linktype, t_ns since epoch, serial bytes)] with link-layer headers stripped."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as e:
        raise CaptureError(f"{path}: {e.strerror or e}") from None
    if data[:4] in _PCAP_MAGIC:
        packets = _pcap_packets(data, path)
    elif data[:4] == _PCAPNG_SHB:
        packets = _pcapng_packets(data, path)
    else:
        raise CaptureError(f"{path}: not a pcap or pcapng file")
    out = []
    for lt, t, payload in packets:
        if lt == LINKTYPE_RTAC_SERIAL:
            payload = payload[RTAC_HEADER:]
        elif lt != LINKTYPE_USER0:
            raise CaptureError(f"{path}: link type {lt} is not a serial capture "
                               f"(supported: 147 user DLT with raw frames, 250 RTAC serial)")
        if payload:
            out.append((lt, t, bytes(payload)))
    return out


def open_pcap(path: str | os.PathLike[str]) -> tuple[CaptureInfo, Iterator[Chunk | Tick]]:
    """(CaptureInfo, events): one per-read Chunk per packet, a Tick before the next one."""
    packets = read_packets(path)
    t0 = packets[0][1] if packets else 0
    kinds = sorted({lt for lt, _t, _d in packets})
    info = CaptureInfo(source=f"pcap:{os.path.basename(os.fspath(path))}", time_source="read",
                       t0_ns=0, wall_anchor_ns=t0, extra={"pcap_linktypes": kinds})

    def events() -> Iterator[Chunk | Tick]:
        last = None
        for _lt, t, payload in packets:
            t_rel = max(t - t0, 0)
            if last is not None and t_rel > last + 1:
                yield Tick(t_rel - 1)
            last = max(t_rel, last or 0)
            yield Chunk(last, payload)

    return info, events()
