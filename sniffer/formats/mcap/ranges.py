"""A finished capture's /raw messages by number, read straight from their chunks (sniffer.parallel's workers).

    index = raw_index("line3.mcap")          # None: read it in order (McapSource) instead
    datas = read_raw(index, 1000, 2000)      # the /raw payloads of messages 1000 .. 1999, in file order

Only for a finished file (its summary and footer) whose /raw messages are all in
chunks with a message index: `raw_index` reads the summary and the indexes' heads,
nothing else.  Then, as long as the chunks hold their CRC, message number n is the
n-th /raw message of the file and decode_event(payload) is the n-th event the reader
gives (None: a kind this sniffer does not know, which it skips too).  `read_raw`
checks the CRC of every chunk it reads and raises Damaged at the first that fails:
from there on the file is the reader's, which skips what is damaged and says so.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

from sniffer.formats.mcap.format import RAW_FORMAT, RAW_TOPIC

_RECORD = struct.Struct("<BQ")
_INDEX_HEAD = struct.Struct("<BQHI")  # opcode, length, channel id, records length
_CHUNK_HEAD = struct.Struct("<BQQQQI")  # opcode, length, start, end, uncompressed size, crc
_PAIR = struct.Struct("<QQ")
_MESSAGE_DATA = 9 + 22  # a message record's opcode and length, then channel, sequence, log and publish time


class Damaged(ValueError):
    """A chunk that fails its CRC (or a message index that does not fit it): `first` is the number of its first
    /raw message."""

    def __init__(self, text: str, first: int) -> None:
        super().__init__(text)
        self.first = first


@dataclass(frozen=True)
class RawIndex:
    path: str
    channel: int
    total: int  # /raw messages
    chunks: tuple  # (first message number, count, chunk offset, chunk length, message index offset)


def _chunk_data(fh, offset: int, length: int) -> bytes:
    """A chunk record's records, decompressed, its CRC checked (ValueError)."""
    fh.seek(offset)
    body = fh.read(length)
    _op, _length, _start, _end, size, crc = _CHUNK_HEAD.unpack_from(body, 0)
    at = _CHUNK_HEAD.size
    (n,) = struct.unpack_from("<I", body, at)
    compression = body[at + 4: at + 4 + n].decode()
    at += 4 + n
    (n,) = struct.unpack_from("<Q", body, at)
    data = body[at + 8: at + 8 + n]
    if compression == "zstd":
        import zstandard

        data = zstandard.decompress(data, size)
    elif compression == "lz4":
        import lz4.frame

        data = lz4.frame.decompress(data)
    elif compression:
        raise ValueError(f"chunk compressed with {compression}")
    if len(data) != size or (crc and zlib.crc32(data) != crc):
        raise ValueError("chunk fails its CRC")
    return data


def _offsets(fh, at: int, channel: int) -> list[int]:
    """The offsets in its chunk of a channel's messages (its message index), in file order."""
    fh.seek(at)
    head = fh.read(_INDEX_HEAD.size)
    op, _length, cid, size = _INDEX_HEAD.unpack(head)
    if op != 0x07 or cid != channel or size % 16:
        raise ValueError("not the message index it should be")
    body = fh.read(size)
    return sorted(off for _t, off in _PAIR.iter_unpack(body))


def raw_index(path: str) -> RawIndex | None:
    """The /raw messages' places in a finished capture, every chunk checked; None if it is not one to read so."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as fh:
            summary = make_reader(fh).get_summary()
            if summary is None or summary.statistics is None or not summary.chunk_indexes:
                return None
            raw = [c.id for c in summary.channels.values() if c.topic == RAW_TOPIC]
            if len(raw) != 1 or summary.channels[raw[0]].metadata.get("sniffer.format", RAW_FORMAT) != RAW_FORMAT:
                return None  # a compact file's /raw message holds several events: numbered by message, read in order
            channel = raw[0]
            chunks, total = [], 0
            for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
                at = ci.message_index_offsets.get(channel)
                if at is None:
                    continue
                fh.seek(at)
                op, _length, cid, size = _INDEX_HEAD.unpack(fh.read(_INDEX_HEAD.size))
                if op != 0x07 or cid != channel or size % 16:
                    return None
                chunks.append((total, size // 16, ci.chunk_start_offset, ci.chunk_length, at))
                total += size // 16
            if summary.statistics.channel_message_counts.get(channel, 0) != total:
                return None  # a /raw message outside the chunks
            if not _between_chunks_intact(fh, {c.chunk_start_offset: c.chunk_length for c in summary.chunk_indexes}):
                return None  # damage the reader skips and reports, where no worker looks
            return RawIndex(path, channel, total, tuple(chunks))
    except (OSError, ValueError, KeyError, struct.error, ImportError):
        return None
    except Exception:  # noqa: BLE001 - mcap's own errors on a file it cannot read: the reader says why
        return None


def _between_chunks_intact(fh, chunks: dict[int, int]) -> bool:
    """Do the data section's records outside the chunks (header, schemas, channels, metadata, message indexes)
    read as the reader reads them, and are the chunks where the summary puts them (`chunks`: offset -> record
    length)?  The workers read only the chunks: a damaged record elsewhere would go unsaid."""
    from sniffer.formats.mcap.format import MAGIC
    from sniffer.formats.mcap.scan import MAX_RECORD, record_reads

    size = fh.seek(0, 2)
    pos, first, met = len(MAGIC), True, 0
    while True:
        fh.seek(pos)
        head = fh.read(_INDEX_HEAD.size)
        if len(head) < _RECORD.size:
            return False
        op, length = _RECORD.unpack_from(head)
        if length > size - pos - _RECORD.size or length > MAX_RECORD or first != (op == 0x01):
            return False
        if op == 0x06:  # a chunk: its CRC is checked where it is read
            if chunks.get(pos) != _RECORD.size + length:
                return False
            met += 1
        elif op == 0x07:  # a message index: its shape
            if len(head) < _INDEX_HEAD.size or (length - 6) % 16 or _INDEX_HEAD.unpack(head)[3] != length - 6:
                return False
        else:
            fh.seek(pos + _RECORD.size)
            if not record_reads(op, fh.read(length)):
                return False
        if op == 0x0F:  # data end: every chunk the summary names was met
            return met == len(chunks)
        first = False
        pos += _RECORD.size + length


def read_raw(index: RawIndex, lo: int, hi: int) -> list[bytes]:
    """The payloads of /raw messages lo .. hi-1; Damaged at a chunk that fails its CRC (OSError: unreadable)."""
    out: list[bytes] = []
    with open(index.path, "rb") as fh:
        for first, count, offset, length, at in index.chunks:
            if first + count <= lo or first >= hi:
                continue
            try:
                data = _chunk_data(fh, offset, length)
                offs = _offsets(fh, at, index.channel)
                if len(offs) != count:
                    raise ValueError("its message index changed")
                for off in offs[max(0, lo - first): max(0, hi - first)]:
                    op, n = _RECORD.unpack_from(data, off)
                    if op != 0x05 or off + 9 + n > len(data):
                        raise ValueError("its message index points at no message")
                    out.append(data[off + _MESSAGE_DATA: off + 9 + n])
            except (ValueError, struct.error, Exception) as e:  # noqa: BLE001 - zstd's errors too
                if isinstance(e, OSError):
                    raise
                raise Damaged(f"{index.path}: chunk at byte {offset}: {e}", first) from None
    return out
