"""pcap / pcapng as this project writes and reads it: constants, header builders, record checks.

Shared by the writer (formats/pcap/writer.py) and the reader (formats/pcap/reader.py);
neither imports the other.  Writer side: classic pcap with nanosecond
timestamps (magic a1b23c4d), or pcapng with a nanosecond if_tsresol; link
type 147 (LINKTYPE_USER0), which Wireshark decodes as Modbus/RTU with
`TSHARK_ARGS`.  Reader side: both byte orders, micro- and nanosecond pcap,
any pcapng if_tsresol; link types 147 and 250 (SEL RTAC serial: a 12-byte
header, then the bytes).

A record header is *plausible* (`pcap_record_problem` returns None) when its
length fits the snap length and MAX_RECORD, the original length is not
shorter than the captured one, the sub-second part is below one second and
its time is within MAX_JUMP_NS of the previous record's.  A pcapng block is
plausible (`pcapng_block_problem`) when its length is a multiple of 4,
between 12 bytes and MAX_BLOCK, and repeated at its end.  The reader uses
these to refuse damaged records and to find the next intact one.

Inside an intact pcapng block (`pcapng_body_problem`): a packet's captured
length must leave the rest of its block to a well-formed option list (a
captured length damaged smaller leaves packet bytes there, which do not
read as options), and must not exceed its original length; the option
lists of interface descriptions, name resolution and statistics blocks
must read too (a packet block whose type was damaged into one of those
does not).  A packet captured shorter than it was sent (captured length
below the original) lost bytes: the reader says so (`cut_packet`).
"""

from __future__ import annotations

import struct

from sniffer.events import CaptureInfo

LINKTYPE_USER0 = 147
LINKTYPE_RTAC_SERIAL = 250
SUPPORTED_LINKTYPES = (LINKTYPE_USER0, LINKTYPE_RTAC_SERIAL)
RTAC_HEADER = 12
MAGIC_NS = 0xA1B23C4D
MAGIC_US = 0xA1B2C3D4
SNAPLEN = 65535
MAX_COMMENT = 4000  # bytes of a packet comment (an option's length is 16 bits; Wireshark shows one line of it)
TSHARK_ARGS = ["-o", 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""']

# -- reading -------------------------------------------------------------------------------------
PCAP_MAGIC = {  # first 4 bytes -> (struct byte order, ns per sub-second unit)
    b"\xd4\xc3\xb2\xa1": ("<", 1000), b"\xa1\xb2\xc3\xd4": (">", 1000),
    b"\x4d\x3c\xb2\xa1": ("<", 1), b"\xa1\xb2\x3c\x4d": (">", 1),
}
PCAPNG_SHB = b"\x0a\x0d\x0d\x0a"
PCAPNG_BYTE_ORDER_LE = b"\x4d\x3c\x2b\x1a"
BLOCK_SHB, BLOCK_IDB, BLOCK_PB, BLOCK_SPB, BLOCK_EPB = 0x0A0D0D0A, 1, 2, 3, 6
# blocks a reader skips quietly: name resolution, interface statistics, systemd journal, decryption
# secrets, custom blocks (and the hex codes of a few more the pcapng draft assigns).  Not IRIG and AFDX
# (7, 8), which no serial tool writes: an enhanced packet block (6) whose type lost one bit reads as 7
BLOCKS_WITHOUT_PACKETS = frozenset({4, 5, 9, 0x0A, 0x0B, 0x0BAD, 0x40000BAD})
GLOBAL_HEADER = 24
RECORD_HEADER = 16
MAX_RECORD = 262_144  # Wireshark's largest snap length: a longer record is a damaged length field
MAX_BLOCK = 16 << 20  # a pcapng block longer than this is a damaged length field
MAX_JUMP_NS = 366 * 86_400 * 1_000_000_000  # a record a year away from the previous one is damage


def parse_global_header(head: bytes) -> tuple[str, int, int, int]:
    """(byte order, ns per unit, snap length, link type) of a classic pcap header; ValueError if short."""
    if len(head) < GLOBAL_HEADER:
        raise ValueError("truncated pcap header")
    end, mult = PCAP_MAGIC[head[:4]]
    snaplen, linktype = struct.unpack_from(end + "II", head, 16)
    return end, mult, snaplen, linktype & 0x0FFFFFFF


def pcap_record_problem(sec: int, frac: int, incl: int, orig: int, *, mult: int, snaplen: int,
                        last_t: int | None) -> str | None:
    """Why this record header cannot be right, or None if it is plausible."""
    limit = min(snaplen, MAX_RECORD) if snaplen else MAX_RECORD
    if incl > limit:
        return f"claims {incl} bytes (snaplen {snaplen})"
    if orig < incl:
        return f"claims {incl} bytes of a {orig}-byte packet"
    if frac * mult >= 1_000_000_000:
        return f"has a sub-second part of {frac} (not below one second)"
    if last_t is not None and abs(sec * 1_000_000_000 + frac * mult - last_t) > MAX_JUMP_NS:
        return "is timed more than a year away from the record before it"
    return None


def tsresol(opts: bytes, end: str) -> int:
    """ns per timestamp unit from a pcapng interface description's options (default microseconds)."""
    pos = 0
    while pos + 4 <= len(opts):
        code, length = struct.unpack_from(end + "HH", opts, pos)
        if code == 0:
            break
        if code == 9 and length >= 1 and pos + 4 < len(opts):
            v = opts[pos + 4]
            units_per_s = 2 ** (v & 0x7F) if v & 0x80 else 10 ** min(v, 30)
            return max(1, 1_000_000_000 // units_per_s) if units_per_s <= 1_000_000_000 else 1
        pos += 4 + length + (-length % 4)
    return 1000


def cut_packet(incl: int, orig: int) -> str:
    """How a packet that lost bytes is described (its captured length below its original one)."""
    return (f"holds {incl} of the packet's {orig} bytes (cut by the capturing tool's snap length, "
            "or a damaged length): the rest is not in the file")


def options_problem(buf: bytes, pos: int, end: str) -> str | None:
    """Why the pcapng option list in buf[pos:] does not read (each option's length within the block,
    nothing but padding after opt_endofopt), or None."""
    n = len(buf)
    while pos + 4 <= n:
        code, length = struct.unpack_from(end + "HH", buf, pos)
        if code == 0:
            return None if length == 0 and not any(buf[pos + 4:]) else "has bytes after its end of options"
        pos += 4 + length + (-length % 4)
        if pos > n:
            return f"has an option (code {code}) running past its end"
    return None if pos == n or not any(buf[pos:]) else "ends inside an option"


def pcapng_body_problem(btype: int, body: bytes, end: str) -> str | None:
    """Why the body of an intact pcapng block of type `btype` cannot be right (see the module doc), or None.
    Packet blocks: the captured length against the block and the original length, then the options."""
    if btype == 1:  # interface description: link type, reserved, snap length, options
        return "is too short" if len(body) < 8 else options_problem(body, 8, end)
    if btype == 5:  # interface statistics: interface, time, options
        return "is too short" if len(body) < 12 else options_problem(body, 12, end)
    if btype == 4:  # name resolution: records up to nrb_record_end, then options
        pos = 0
        while pos + 4 <= len(body):
            rtype, length = struct.unpack_from(end + "HH", body, pos)
            pos += 4 + length + (-length % 4)
            if rtype == 0:
                return options_problem(body, pos, end) if pos <= len(body) else "has a record past its end"
        return "has no end of records"
    if btype == 3:  # simple packet: original length, the bytes (min(original, snap length)), no options
        if len(body) < 4:
            return "is too short"
        orig = struct.unpack_from(end + "I", body, 0)[0]
        room = len(body) - 4
        if orig < room - 3:
            return f"claims a {orig}-byte packet in {room} bytes of packet data"
        return None
    if btype in (2, 6):  # obsolete and enhanced packet: 20 bytes of header, the bytes, options
        got = packet_extent(body, end)
        return got if isinstance(got, str) else None
    return None


def packet_extent(body: bytes, end: str) -> tuple[int, int, str | None] | str:
    """(captured bytes to read, original length, what was wrong with the captured length or None) of an
    enhanced or obsolete packet block's body, or why it cannot be read.  A captured length whose options do
    not read, where the original length's do and its bytes are in the block, was damaged: the original
    length is read instead (and said)."""
    if len(body) < 20:
        return "is too short"
    incl, orig = struct.unpack_from(end + "II", body, 12)
    room = len(body) - 20
    if incl > room:
        return f"claims {incl} captured bytes in a {room}-byte block"
    if incl > orig:
        return f"claims {incl} captured bytes of a {orig}-byte packet"
    why = options_problem(body, 20 + incl + (-incl % 4), end)
    if why is None:
        return incl, orig, None
    if incl < orig <= room and options_problem(body, 20 + orig + (-orig % 4), end) is None:
        return orig, orig, (f"claims {incl} captured bytes, but its options start after the packet's {orig}: "
                            f"its {orig} bytes were read")
    return f"{why} (its captured length of {incl} bytes leaves what is not options)"


def packet_of(btype: int, body: bytes, end: str, ifaces: list[tuple[int | None, int]]) \
        -> tuple[int, int, bytes, int, str | None] | str:
    """(link type, t_ns, captured bytes, the packet's original length, what was wrong with its captured
    length) of an enhanced / obsolete / simple packet block whose lengths pcap_format.pcapng_body_problem
    found readable, or why it cannot be read."""
    if not ifaces:
        return "comes before any interface description"
    if btype == BLOCK_SPB:  # simple packet: no time, always interface 0; min(original, snap length) bytes
        lt, _ns = ifaces[0]
        orig = struct.unpack_from(end + "I", body, 0)[0]
        data, iid, t, note = body[4:4 + orig], 0, 0, None
    else:
        if btype == BLOCK_EPB:
            iid, hi, lo = struct.unpack_from(end + "III", body, 0)
        else:  # obsolete packet block: 16-bit interface id, drops count
            iid, _drops, hi, lo = struct.unpack_from(end + "HHII", body, 0)
        if iid >= len(ifaces):
            return f"is on undeclared interface {iid}"
        incl, orig, note = packet_extent(body, end)  # its problems were found before: a tuple here
        lt, ns = ifaces[iid]
        data, t = body[20:20 + incl], ((hi << 32) | lo) * ns
    if lt is None:
        return f"is on interface {iid}, whose description is damaged"
    return lt, t, data, orig, note


def reads_as_packet(body: bytes, end: str, ifaces: list) -> bool:
    """A block of a type without packets whose body is an enhanced packet block's, lengths and options and
    all, on an interface the section declared: a packet block whose type was damaged (a journal entry,
    secrets or a custom block start with text, a secrets type or an enterprise number, never that)."""
    if len(body) < 20 or struct.unpack_from(end + "I", body, 0)[0] >= len(ifaces):
        return False
    got = packet_extent(body, end)
    return not isinstance(got, str) and got[2] is None and got[1] > 0


def pcapng_block_problem(blen: int, room: int) -> str | None:
    """Why a block of claimed length `blen` cannot be right (`room`: bytes left in the file), or None."""
    if blen < 12 or blen % 4:
        return f"claims a length of {blen} bytes (not a multiple of 4 of at least 12)"
    if blen > MAX_BLOCK:
        return f"claims {blen} bytes (over {MAX_BLOCK})"
    if blen > room:
        return f"claims {blen} bytes, past the end of the file"
    return None


# -- writing (formats/pcap/writer.py) ------------------------------------------------------------------------
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
    """Section header + one interface (nanosecond timestamps, the capture's source as its name); a capture
    of several links: one interface per link, in the order of `info.links`, named for the link."""
    shb = _block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1)
                 + _opt(4, b"rs485-sniffer") + _opt(0, b""))  # shb_userappl
    lines = [(info.source or "rs485", info)] if not info.links else [
        (f"{x.get('name')} ({' + '.join(x.get('ports') or ())})", CaptureInfo.from_dict({**info.to_dict(), **x}))
        for x in info.links]
    idbs = b""
    for name, li in lines:
        line = f"{li.baud or '?'} {8}{li.parity or 'N'}{li.stopbits or 1}"
        idbs += _block(1, struct.pack("<HHI", linktype, 0, SNAPLEN)
                       + _opt(2, name.encode()[:200])  # if_name
                       + _opt(3, f"RS-485 {li.protocol} {line}".encode())  # if_description
                       + _opt(9, b"\x09") + _opt(0, b""))  # if_tsresol: 10^-9
    return shb + idbs


def pcapng_packet(t_ns: int, data: bytes, interface: int = 0, comment: str = "") -> bytes:
    """An enhanced packet block; `comment`: its opt_comment (UTF-8, what Wireshark shows as the packet's comment)."""
    t = max(t_ns, 0)
    body = struct.pack("<IIIII", interface, t >> 32, t & 0xFFFFFFFF, len(data), len(data)) + data
    if comment:
        body += b"\0" * (-len(body) % 4) + _opt(1, comment.encode()[:MAX_COMMENT]) + _opt(0, b"")
    return _block(6, body)
