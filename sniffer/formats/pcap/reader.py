"""pcap / pcapng from other serial sniffers as a replay source, read record by record.

Accepted link types: 147 (LINKTYPE_USER0, the raw serial frame: what our own
pcap export and most serial-sniffer tools write) and 250 (SEL RTAC serial:
a 12-byte header - timestamp, event type, control lines, footer - then the
bytes).  A capture whose first packet has another link type is a
CaptureError naming the type; packets of other interfaces later in a
pcapng are skipped and reported.

A packet's time is when the sniffer emitted it, not a per-byte wire time, so
the events are per-read Chunks (`time_source` "read"), one per packet.  A
packet is a boundary the capturing tool already drew: each Chunk is marked
`packet`, and the framer cuts at its edges whatever the times say (a logger
that stamps a packet's start puts the next one "before" the end of the
last), so a packet cut off inside a frame is that frame truncated, as in any
other format.  A silence Tick still follows each packet up to the next one.
pcap does not say the baud rate: give it.

Damage (sniffer.formats.pcap.format says what is plausible): a record header that
cannot be right is reported in `damage`, the reader scans forward to the
next offset where a plausible record is followed by another plausible one
(pcapng: a block whose length is repeated at its end) and goes on from
there; a Gap marks the hole.  Inside an intact pcapng block, lengths and
options that do not read (pcap_format.pcapng_body_problem) and a packet
timed a year away from the one before are damage too: the block is
skipped, said, and a Gap marks it.  A packet captured shorter than it was
sent (pcap or pcapng) keeps its bytes, is said, and a Gap follows it.  A
file that ends inside a record (a killed capture) keeps every complete
record and says so in `damage`.  Fatal
(CaptureError from open()): not pcap/pcapng, a cut global header, a
non-serial link type, no packet at all.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator

from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.formats.pcap.format import (
    BLOCK_EPB, BLOCK_IDB, BLOCK_PB, BLOCK_SHB, BLOCK_SPB, BLOCKS_WITHOUT_PACKETS, GLOBAL_HEADER, LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0, MAX_BLOCK, MAX_JUMP_NS, PCAP_MAGIC, PCAPNG_BYTE_ORDER_LE, PCAPNG_SHB, RECORD_HEADER, RTAC_HEADER,
    SUPPORTED_LINKTYPES, cut_packet, packet_of, parse_global_header, pcap_record_problem, pcapng_block_problem,
    pcapng_body_problem, reads_as_packet, tsresol,
)
from sniffer.events import CaptureError
from sniffer.formats.reading import DamageLog, file_position, gap_before
from sniffer.inputs import open_regular

__all__ = ["LINKTYPE_RTAC_SERIAL", "LINKTYPE_USER0", "PcapSource", "open_pcap", "read_packets", "sniff"]

_SCAN_BLOCK = 1 << 16


def sniff(path: str | os.PathLike[str]) -> bool:
    try:
        with open_regular(path) as fh:
            head = fh.read(4)
    except (CaptureError, OSError):
        return False
    return head in PCAP_MAGIC or head == PCAPNG_SHB


class _Hole:
    """Bytes skipped between two readable records (a marker in the packet stream)."""

    __slots__ = ("reason",)

    def __init__(self, reason: str) -> None:
        self.reason = reason


class PcapSource:
    """One pcap or pcapng file: open() reads up to the first packet, events() goes on from there."""

    def __init__(self, path: str | os.PathLike[str], damage: list[str] | None = None) -> None:
        self.path = os.fspath(path)
        self.damage: list[str] = [] if damage is None else damage
        self._log = DamageLog(self.damage)
        self.info: CaptureInfo | None = None
        self._fh = None
        self._size = 0
        self._packets: Iterator | None = None
        self._first: tuple[int, int, bytes] | None = None
        self._hole_first: str | None = None
        self._foreign: dict[int, int] = {}  # link type -> packets skipped
        self._iface_types: tuple[int, ...] = ()  # link types declared (pcap: the global one)

    def position(self) -> tuple[int, int] | None:
        return file_position(self._fh, self._size)

    def open(self) -> CaptureInfo:
        if self.info is not None:
            return self.info
        fh = open_regular(self.path)
        self._fh = fh
        try:
            self._size = os.fstat(fh.fileno()).st_size
            head = fh.read(4)
            if head in PCAP_MAGIC:
                self._packets = self._pcap(head)
            elif head == PCAPNG_SHB:
                fh.seek(0)
                self._packets = self._pcapng()
            elif not head:
                raise CaptureError(f"{self.path}: empty file")
            else:
                raise CaptureError(f"{self.path}: not a pcap or pcapng file")
            self._first = self._next_packet(first=True)
        except OSError as e:
            self.close()
            raise CaptureError(f"{self.path}: {e.strerror or e}") from None
        except CaptureError:
            self.close()
            raise
        if self._first is None:
            self.close()
            why = f" ({self.damage[0]})" if self.damage else ""
            raise CaptureError(f"{self.path}: no serial packets in this capture{why}")
        lts = sorted({self._first[0], *self._iface_types} & set(SUPPORTED_LINKTYPES))
        self.info = CaptureInfo(source=f"pcap:{os.path.basename(self.path)}", time_source="read",
                                t0_ns=0, wall_anchor_ns=self._first[1], extra={"pcap_linktypes": lts})
        return self.info

    def _next_packet(self, first: bool = False) -> tuple[int, int, bytes] | None:
        """The next packet with serial bytes (link header stripped); holes before it noted in _hole_first."""
        assert self._packets is not None
        for item in self._packets:
            if isinstance(item, _Hole):
                self._hole_first = self._hole_first or item.reason
                continue
            lt, t, payload = item
            if lt == LINKTYPE_RTAC_SERIAL:
                payload = payload[RTAC_HEADER:]
            elif lt != LINKTYPE_USER0:
                if first:
                    raise CaptureError(f"{self.path}: link type {lt} is not a serial capture "
                                       f"(supported: 147 user DLT with raw frames, 250 RTAC serial)")
                self._foreign[lt] = self._foreign.get(lt, 0) + 1
                continue
            if payload:
                return lt, t, bytes(payload)
        return None

    def events(self) -> Iterator[Chunk | Tick | Gap]:
        """One per-read Chunk per packet, a Tick before the next one, a Gap where records were skipped."""
        self.open()
        try:
            assert self._first is not None
            t0 = self._first[1]
            last: int | None = None
            pkt: tuple[int, int, bytes] | None = self._first
            while pkt is not None:
                _lt, t, payload = pkt
                t_rel = max(t - t0, 0)
                chunk = Chunk(max(t_rel, last or 0), payload, packet=True)
                if self._hole_first is not None:
                    yield gap_before(last, chunk, self._hole_first)
                    self._hole_first = None
                if last is not None and t_rel > last + 1:
                    yield Tick(t_rel - 1)
                last = chunk.t_ns
                yield chunk
                pkt = self._next_packet()
            if self._hole_first is not None and last is not None:
                yield Gap(last, last, self._hole_first)
        except OSError as e:
            self._log.add("read errors", f"{self.path}: read error: {e.strerror or e}; the rest was not read")
        finally:
            for lt, n in self._foreign.items():
                self._log.add("foreign packets", f"{self.path}: {n} packets of link type {lt} skipped "
                                                 "(not a serial capture)")
            self._foreign.clear()
            self._log.finish(self.path)
            self.close()

    def close(self) -> None:
        fh, self._fh = self._fh, None
        if fh is not None:
            fh.close()

    # -- classic pcap -------------------------------------------------------------------------
    def _pcap(self, magic: bytes) -> Iterator:
        fh, size = self._fh, self._size
        try:
            end, mult, snaplen, linktype = parse_global_header(magic + fh.read(GLOBAL_HEADER - 4))
        except ValueError as e:
            raise CaptureError(f"{self.path}: {e}") from None
        self._iface_types = (linktype,)
        hdr = struct.Struct(end + "IIII")

        def problem(buf: bytes, at: int, last_t: int | None) -> str | None:
            return pcap_record_problem(*hdr.unpack_from(buf, at), mult=mult, snaplen=snaplen, last_t=last_t)

        def chained(q: int, last_t: int | None) -> bool:
            """A plausible record at q followed by a plausible record (or the end of the file)."""
            fh.seek(q)
            h = fh.read(RECORD_HEADER)
            if len(h) < RECORD_HEADER or problem(h, 0, last_t) is not None:
                return False
            sec, frac, incl, _orig = hdr.unpack(h)
            nxt = q + RECORD_HEADER + incl
            if nxt > size:
                return False
            if size - nxt < RECORD_HEADER:
                return True
            fh.seek(nxt)
            return problem(fh.read(RECORD_HEADER), 0, sec * 1_000_000_000 + frac * mult) is None

        pos, last_t = GLOBAL_HEADER, None
        fh.seek(pos)
        while True:
            h = fh.read(RECORD_HEADER)
            if not h:
                return
            if len(h) < RECORD_HEADER:
                self._log.add("cut", f"{self.path}: the file ends inside a record header at byte {pos} "
                                     f"({len(h)} bytes of a cut-off record not read)")
                return
            sec, frac, incl, orig = hdr.unpack(h)
            why = problem(h, 0, last_t)
            if why is None:
                body = fh.read(incl)
                if len(body) < incl:
                    self._log.add("cut", f"{self.path}: the last record (at byte {pos}) is cut off: "
                                         f"{len(body)} of its {incl} bytes are in the file; not read")
                    return
                last_t = sec * 1_000_000_000 + frac * mult
                yield linktype, last_t, body
                if incl < orig:
                    yield self._cut(f"pcap record at byte {pos}", incl, orig)
                pos += RECORD_HEADER + incl
                continue
            q = _scan(fh, pos + 1, size, lambda buf, i, lt=last_t: problem(buf, i, lt) is None,
                      lambda at, lt=last_t: chained(at, lt))
            yield self._hole(f"pcap record at byte {pos} {why}", pos, q)
            if q is None:
                return
            pos = q
            fh.seek(pos)

    def _cut(self, what: str, incl: int, orig: int) -> _Hole:
        """A packet that lost bytes (captured shorter than sent): said, and a hole after its bytes."""
        self._log.add("cut packets", f"{self.path}: {what} {cut_packet(incl, orig)}")
        return _Hole(f"{orig - incl} bytes of a packet not in the capture file")

    def _hole(self, what: str, pos: int, q: int | None) -> _Hole:
        if q is None:
            self._log.add("damaged records", f"{self.path}: {what}: no readable record after it; "
                                             f"the last {self._size - pos} bytes were skipped")
            return _Hole(f"damaged capture file: {self._size - pos} bytes skipped at byte {pos}")
        self._log.add("damaged records", f"{self.path}: {what}: skipped {q - pos} bytes to the next "
                                         "plausible record")
        return _Hole(f"damaged capture file: {q - pos} bytes skipped at byte {pos}")

    # -- pcapng -------------------------------------------------------------------------------
    def _pcapng(self) -> Iterator:
        fh, size = self._fh, self._size
        end = "<"
        ifaces: list[tuple[int, int]] = []  # (link type, ns per unit)

        def block_at(q: int, order: str | None) -> tuple[int, int, str] | str:
            """(type, length, byte order) of a plausible block at q, or why it is not one."""
            fh.seek(q)
            h = fh.read(12)
            if len(h) < 8:
                return "is cut off"
            o = order or end
            if h[:4] == PCAPNG_SHB:
                o = "<" if h[8:12] == PCAPNG_BYTE_ORDER_LE else ">"
            btype, blen = struct.unpack_from(o + "II", h)
            why = pcapng_block_problem(blen, size - q)
            if why is not None:
                return why
            fh.seek(q + blen - 4)
            if struct.unpack(o + "I", fh.read(4))[0] != blen:
                return f"claims {blen} bytes but does not end with that length"
            return btype, blen, o

        def chained(q: int) -> bool:
            b = block_at(q, None)
            if isinstance(b, str):
                return False
            nxt = q + b[1]
            return size - nxt < 12 or not isinstance(block_at(nxt, b[2]), str)

        def quick(buf: bytes, i: int) -> bool:
            if buf[i:i + 4] == PCAPNG_SHB:
                return True
            blen = struct.unpack_from(end + "I", buf, i + 4)[0]
            return blen >= 12 and blen % 4 == 0 and blen <= MAX_BLOCK

        pos = 0
        last_t: int | None = None  # the time of the last packet read
        stray: int | None = None  # the time of a packet skipped for being a year away from last_t
        while pos < size:
            b = block_at(pos, None)
            if isinstance(b, str):
                if size - pos < 12:
                    self._log.add("cut", f"{self.path}: the file ends inside a block header at byte {pos} "
                                         f"({size - pos} bytes not read)")
                    return
                q = _scan(fh, pos + 4, size, quick, chained, step=4)
                if q is None and b.endswith("past the end of the file") and pos > 0:
                    self._log.add("cut", f"{self.path}: the last block (at byte {pos}) is cut off: "
                                         f"{size - pos} bytes of it are in the file; not read")
                    return
                yield self._hole(f"pcapng block at byte {pos} {b}", pos, q)
                if q is None:
                    return
                pos = q
                continue
            btype, blen, end = b
            fh.seek(pos + 8)
            body = fh.read(blen - 12)
            at, pos = pos, pos + blen
            why = pcapng_body_problem(btype, body, end)
            if btype == BLOCK_SHB:
                ifaces = []
            elif btype == BLOCK_IDB:
                lt = struct.unpack_from(end + "H", body, 0)[0] if len(body) >= 8 else None
                ifaces.append((lt, tsresol(body[8:], end)))  # one too short keeps the interfaces' numbering
                if lt is not None:
                    self._iface_types = (*self._iface_types, lt)
                if why is not None:
                    self._log.add("damaged blocks", f"{self.path}: interface description at byte {at} {why}"
                                  + (": its packets cannot be read" if lt is None else
                                     ": the times of its packets may be wrong"))
                    yield _Hole(f"damaged interface description at byte {at}")
            elif btype in (BLOCK_EPB, BLOCK_PB, BLOCK_SPB):
                pkt = why or packet_of(btype, body, end, ifaces)
                if isinstance(pkt, str):
                    self._log.add("skipped blocks", f"{self.path}: packet block at byte {at} {pkt}: skipped")
                    yield _Hole(f"damaged packet block skipped at byte {at}")
                    continue
                lt, t, data, orig, note = pkt
                if note is not None:
                    self._log.add("damaged blocks", f"{self.path}: packet block at byte {at} {note}")
                    yield _Hole(f"damaged packet block at byte {at}")
                if btype != BLOCK_SPB and last_t is not None and abs(t - last_t) > MAX_JUMP_NS and (
                        stray is None or abs(t - stray) > MAX_JUMP_NS):  # two in a row: the times moved on
                    stray = t
                    self._log.add("skipped blocks", f"{self.path}: packet block at byte {at} is timed more than "
                                                    "a year away from the packet before it: skipped")
                    yield _Hole(f"damaged packet block skipped at byte {at}")
                    continue
                if btype != BLOCK_SPB:
                    last_t, stray = t, None
                yield lt, t, data
                if len(data) < orig:
                    yield self._cut(f"packet block at byte {at}", len(data), orig)
            elif why is not None or (btype in BLOCKS_WITHOUT_PACKETS and reads_as_packet(body, end, ifaces)):
                what = why or "reads as a packet block on a declared interface"  # a damaged packet block's type?
                self._log.add("skipped blocks", f"{self.path}: block of type 0x{btype:08x} at byte {at} {what}: "
                                                f"skipped ({blen} bytes; a packet block with a damaged type?)")
                yield _Hole(f"damaged pcapng block skipped at byte {at}")
            elif btype not in BLOCKS_WITHOUT_PACKETS:
                self._log.add("skipped blocks", f"{self.path}: block of unknown type 0x{btype:08x} at byte "
                                                f"{at} skipped ({blen} bytes)")
                yield _Hole(f"unknown pcapng block skipped at byte {at}")


def _scan(fh, start: int, size: int, quick, ok, step: int = 1) -> int | None:
    """The first offset >= start (in steps of `step`) where quick(buffer, i) and then ok(offset) hold.

    quick looks at the 16 bytes at buffer[i:] (a cheap check of one header); ok may read the file.
    """
    q = start
    while q + 12 <= size:
        fh.seek(q)
        buf = fh.read(_SCAN_BLOCK + RECORD_HEADER)
        n = len(buf) - RECORD_HEADER + 1 if len(buf) >= RECORD_HEADER else 1
        for i in range(0, max(min(n, _SCAN_BLOCK), 1), step):
            if len(buf) - i >= RECORD_HEADER and quick(buf, i) and ok(q + i):
                return q + i
        q += _SCAN_BLOCK
    return None


def open_pcap(path: str | os.PathLike[str]) -> tuple[CaptureInfo, Iterator[Chunk | Tick | Gap]]:
    """(CaptureInfo, events): one per-read Chunk per packet, a Tick before the next one."""
    src = PcapSource(path)
    return src.open(), src.events()


def read_packets(path: str | os.PathLike[str]) -> list[tuple[int, int, bytes]]:
    """[(linktype, t_ns since epoch, serial bytes)] with link-layer headers stripped (a list: small files)."""
    src = PcapSource(path)
    src.open()
    out = []
    try:
        pkt = src._first
        while pkt is not None:
            out.append(pkt)
            pkt = src._next_packet()
    finally:
        src.close()
    return out


SOURCE = PcapSource  # what sniffer.formats.files makes of a file of this format
