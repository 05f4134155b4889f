"""Damage inside pcap records and pcapng blocks is announced, never a silent loss.

A pcapng block carries its own length twice, so a damaged field inside an intact block (a
captured length, an original length, a time, a block type, an interface description) was read
without a word before: a captured length damaged to 0 dropped the packet and exited 0.  Each
class below is built by hand; then every single-bit flip of a packet's header (and of the
interface description) is tried: the bytes replayed are the clean file's, or `damage` says what
was lost, a Gap marks it, and the command line says it in one line with exit code 2.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from sniffer.cli import main
from sniffer.framing.crc import crc_bytes
from sniffer.events import CaptureInfo, Chunk, Gap
from sniffer.formats.pcap.format import global_header, packet, pcapng_header, pcapng_packet
from sniffer.events import CaptureError
from sniffer.sources.files import FileSource

T0 = 1_700_000_000_000_000_000


def _frames() -> list[bytes]:
    req = bytes.fromhex("010300000002")
    rsp = bytes.fromhex("01030400010002")
    return [req + crc_bytes(req), rsp + crc_bytes(rsp)] * 3


def pcapng_file(payloads=None) -> tuple[bytes, list[int]]:
    """A pcapng of our writer's: the file and the offset of each packet block."""
    data = pcapng_header(CaptureInfo(source="test", baud=9600))
    offsets = []
    for i, p in enumerate(payloads or _frames()):
        offsets.append(len(data))
        data += pcapng_packet(T0 + i * 50_000_000, p)
    return data, offsets


def pcap_file() -> tuple[bytes, list[int]]:
    data = global_header()
    offsets = []
    for i, p in enumerate(_frames()):
        offsets.append(len(data))
        data += packet(T0 + i * 50_000_000, p)
    return data, offsets


def read(path: Path) -> tuple[bytes, list[str], int]:
    """(the bytes replayed, the damage said, how many Gaps); a file refused at open: its one line said."""
    src = FileSource(path)
    try:
        src.open()
    except CaptureError as e:
        return b"", [str(e)], 1
    events = list(src.events())
    return (b"".join(e.data for e in events if type(e) is Chunk), list(src.damage),
            sum(type(e) is Gap for e in events))


def put(data: bytes, at: int, fmt: str, *values) -> bytes:
    d = bytearray(data)
    struct.pack_into(fmt, d, at, *values)
    return bytes(d)


def _epb_lengths(incl: int, orig: int):
    return lambda data, off: put(data, off[2] + 20, "<II", incl, orig)


def _epb_type(btype: int):
    return lambda data, off: put(data, off[2], "<I", btype)


def _idb_cut(data: bytes, off: list[int]) -> bytes:
    """The interface description shortened to 4 bytes of body (its link type and snap length gone)."""
    shb_len = struct.unpack_from("<I", data, 4)[0]
    idb_len = struct.unpack_from("<I", data, shb_len + 4)[0]
    idb = struct.pack("<II", 1, 16) + b"\x93\0\0\0" + struct.pack("<I", 16)
    return data[:shb_len] + idb + data[shb_len + idb_len:]


def _idb_options(data: bytes, off: list[int]) -> bytes:
    shb_len = struct.unpack_from("<I", data, 4)[0]
    return put(data, shb_len + 16, "<HH", 2, 0x7FF0)  # if_name claims 32 kB in a block of a few bytes


def _spb(data: bytes, off: list[int]) -> bytes:
    """Packet 2 as a simple packet block whose original length was damaged smaller (bytes left over)."""
    p = _frames()[2]
    body = struct.pack("<I", 1) + p + b"\0" * (-len(p) % 4)
    spb = struct.pack("<II", 3, len(body) + 12) + body + struct.pack("<I", len(body) + 12)
    return data[:off[2]] + spb + data[off[3]:]


def _epb_snapped(data: bytes, off: list[int]) -> bytes:
    """Packet 2 written by a tool with a snap length of 3: 3 of its 8 bytes in the block."""
    p = _frames()[2]
    t = T0 + 2 * 50_000_000
    body = struct.pack("<IIIII", 0, t >> 32, t & 0xFFFFFFFF, 3, len(p)) + p[:3] + b"\0"
    epb = struct.pack("<II", 6, len(body) + 12) + body + struct.pack("<I", len(body) + 12)
    return data[:off[2]] + epb + data[off[3]:]


# what is damaged -> (how, what the line says, whether every byte of the file is still replayed)
PCAPNG_CLASSES = {
    "captured length damaged to 0": (_epb_lengths(0, 8), "claims 0 captured bytes, but its options start after "
                                                         "the packet's 8: its 8 bytes were read", True),
    "captured length damaged smaller": (_epb_lengths(3, 8), "claims 3 captured bytes", True),
    "packet captured shorter than sent": (_epb_snapped, "holds 3 of the packet's 8 bytes", False),
    "both lengths damaged smaller": (_epb_lengths(4, 4), "leaves what is not options", False),
    "original length damaged smaller": (_epb_lengths(8, 2), "claims 8 captured bytes of a 2-byte packet", False),
    "packet type damaged into a name resolution block": (_epb_type(4), "a packet block with a damaged type?",
                                                         False),
    "packet type damaged into a statistics block": (_epb_type(5), "a packet block with a damaged type?", False),
    "packet type damaged into a journal block": (_epb_type(9), "reads as a packet block on a declared interface",
                                                 False),
    "packet type damaged into a custom block": (_epb_type(0xBAD), "reads as a packet block on a declared",
                                                False),
    "time damaged a year away": (lambda d, off: put(d, off[2] + 12, "<I", 0x7FFFFFFF),
                                 "timed more than a year away", False),
    "interface description cut short": (_idb_cut, "its packets cannot be read", False),
    "interface options damaged": (_idb_options, "the times of its packets may be wrong", True),
    "simple packet's original length damaged": (_spb, "claims a 1-byte packet", False),
}


@pytest.mark.parametrize("damage", list(PCAPNG_CLASSES))
def test_each_class_of_pcapng_damage_is_announced(tmp_path, capsys, damage):
    make, says, kept = PCAPNG_CLASSES[damage]
    clean, off = pcapng_file()
    p = tmp_path / "x.pcapng"
    p.write_bytes(make(clean, off))
    got, said, gaps = read(p)
    assert said and any(says in line for line in said), said
    assert gaps >= 1
    assert (got == b"".join(_frames())) == kept
    code = main(["replay", str(p), "--baud", "9600"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and err[-1].startswith("sniffer: error: ") and says in err[-1], err


def test_a_packet_captured_shorter_than_sent_is_announced_in_pcap_too(tmp_path):
    clean, off = pcap_file()
    p = tmp_path / "x.pcap"
    p.write_bytes(put(clean, off[2] + 12, "<I", 200))  # the original length: 200 bytes on the wire
    got, said, gaps = read(p)
    assert got == b"".join(_frames())  # every byte in the file is replayed
    assert said == [f"{p}: pcap record at byte {off[2]} holds 8 of the packet's 200 bytes (cut by the capturing "
                    "tool's snap length, or a damaged length): the rest is not in the file"]
    assert gaps == 1


def test_an_intact_pcapng_with_options_and_other_blocks_is_clean(tmp_path):
    """What real tools write beside packets (comments, statistics, name resolution) is not damage."""
    clean, off = pcapng_file()

    def block(btype: int, body: bytes) -> bytes:
        body += b"\0" * (-len(body) % 4)
        return struct.pack("<II", btype, len(body) + 12) + body + struct.pack("<I", len(body) + 12)

    comment = struct.pack("<HH", 1, 5) + b"hello\0\0\0" + struct.pack("<HH", 0, 0)
    p0 = _frames()[0]
    epb = block(6, struct.pack("<IIIII", 0, T0 >> 32, T0 & 0xFFFFFFFF, len(p0), len(p0)) + p0
                + b"\0" * (-len(p0) % 4) + comment)
    nrb = block(4, struct.pack("<HH", 1, 8) + b"\x7f\0\0\1ab\0\0" + struct.pack("<HH", 0, 0))
    isb = block(5, struct.pack("<III", 0, 0, 0) + comment)
    journal = block(9, b"__CURSOR=s=0a1b;i=1\nMESSAGE=hello\n")
    secrets = block(0x0A, b"TLSK" + struct.pack("<I", 8) + b"12345678" + struct.pack("<HH", 0, 0))
    custom = block(0xBAD, struct.pack("<I", 32473) + b"vendor data")
    p = tmp_path / "ok.pcapng"
    p.write_bytes(clean[:off[0]] + epb + nrb + journal + clean[off[1]:] + isb + secrets + custom)
    got, said, gaps = read(p)
    assert said == [] and gaps == 0 and got == b"".join(_frames())


def _no_silent_loss(tmp_path, data: bytes, ext: str, spans) -> dict:
    """Flip every bit of the byte spans; each result replays the clean bytes or says what it lost."""
    p = tmp_path / f"flip.{ext}"
    p.write_bytes(data)
    clean, said, _ = read(p)
    assert said == []
    seen = {"same": 0, "said": 0}
    for lo, hi in spans:
        for i in range(lo, hi):
            for bit in range(8):
                d = bytearray(data)
                d[i] ^= 1 << bit
                p.write_bytes(bytes(d))
                got, said, gaps = read(p)
                if said:
                    assert gaps or all("cut off" in x or "ends inside" in x or "not a serial" in x for x in said)
                    seen["said"] += 1
                else:
                    assert got == clean, f"byte {i} bit {bit}: bytes lost without a word"
                    seen["same"] += 1
    return seen


def test_no_bit_flip_of_a_pcapng_packet_header_or_interface_loses_bytes_silently(tmp_path):
    data, off = pcapng_file()
    shb_len = struct.unpack_from("<I", data, 4)[0]
    seen = _no_silent_loss(tmp_path, data, "pcapng", [(shb_len, off[0]), (off[2], off[2] + 28)])
    assert seen["said"] > 0 and seen["same"] > 0


def test_no_bit_flip_of_a_pcap_record_header_loses_bytes_silently(tmp_path):
    data, off = pcap_file()
    seen = _no_silent_loss(tmp_path, data, "pcap", [(off[2], off[2] + 16)])
    assert seen["said"] > 0 and seen["same"] > 0
