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
    try:
        with open(path, "rb") as fh:
            summary = _raw_summary(fh)
            if summary is None:
                return None
            channel, counted, chunk_indexes = summary
            chunks, total = [], 0
            for start, length, at in sorted(chunk_indexes):
                if at is None:
                    continue
                fh.seek(at)
                op, _length, cid, size = _INDEX_HEAD.unpack(fh.read(_INDEX_HEAD.size))
                if op != 0x07 or cid != channel or size % 16:
                    return None
                chunks.append((total, size // 16, start, length, at))
                total += size // 16
            if counted != total:
                return None  # a /raw message outside the chunks
            if not _between_chunks_intact(fh, {start: length for start, length, _at in chunk_indexes}):
                return None  # damage the reader skips and reports, where no worker looks
            return RawIndex(path, channel, total, tuple(chunks))
    except (OSError, ValueError, KeyError, struct.error, UnicodeDecodeError):
        return None
    except Exception:  # noqa: BLE001 - mcap's own errors on a record it cannot read: the reader says why
        return None


_FOOTER = struct.Struct("<BQQQI")  # opcode 0x02, length, summary start, summary offset start, summary CRC
_CHUNK_INDEX_HEAD = struct.Struct("<QQQQI")  # start and end time, chunk offset, chunk length, offsets' byte length
_CHANNEL_OFFSET = struct.Struct("<HQ")


def _raw_summary(fh) -> tuple | None:
    """(the /raw channel, its message count, [(chunk offset, chunk length, its /raw message index offset or
    None)]) from a finished file's summary section, its CRC checked; None without one (or no /raw channel).

    Read here record by record rather than by the mcap library's get_summary(), which builds every chunk
    index's map of every channel: a million-frame capture (3,576 chunks, 648 channels) held 50 MB of them in
    the coordinator, and its worker processes, forked from it, started with that heap."""
    size = fh.seek(0, 2)
    if size < _FOOTER.size + 8:
        return None
    fh.seek(size - 8 - _FOOTER.size)
    op, length, start, _offsets_at, crc = _FOOTER.unpack(fh.read(_FOOTER.size))
    if op != 0x02 or length != _FOOTER.size - 9 or not 0 < start < size - 8 - _FOOTER.size:
        return None
    fh.seek(start)
    body = fh.read(size - 8 - _FOOTER.size - start)
    if crc and zlib.crc32(body + bytes([0x02]) + struct.pack("<QQQ", length, start, _offsets_at)) != crc:
        return None
    channel = counted = None
    raw_ids: list[int] = []
    indexes: list[tuple] = []  # (offset, length, the offsets' map as its bytes)
    at, end = 0, len(body)
    while at < end:
        op, length = _RECORD.unpack_from(body, at)
        rec = at + _RECORD.size
        at = rec + length
        if at > end:
            return None
        if op == 0x04:  # a channel: id, schema id, topic, message encoding, metadata
            (cid, _schema, n) = struct.unpack_from("<HHI", body, rec)
            if body[rec + 8: rec + 8 + n].decode() == RAW_TOPIC:
                if _channel_format(body, rec + 8 + n, at) != RAW_FORMAT:
                    return None  # a compact file: several events a /raw message, read in order
                raw_ids.append(cid)
        elif op == 0x08:  # a chunk index
            _t0, _t1, offset, chunk_length, n = _CHUNK_INDEX_HEAD.unpack_from(body, rec)
            first = rec + _CHUNK_INDEX_HEAD.size
            if n % _CHANNEL_OFFSET.size or first + n > at:
                return None
            indexes.append((offset, chunk_length, body[first: first + n]))
        elif op == 0x0B:  # statistics: counts, then the per-channel message counts
            (n,) = struct.unpack_from("<I", body, rec + 8 + 2 + 4 + 4 + 4 + 4 + 8 + 8)
            counts = body[rec + 46: rec + 46 + n]
            counted = {cid: c for cid, c in _CHANNEL_OFFSET.iter_unpack(counts)}
    if len(raw_ids) != 1 or counted is None or not indexes:
        return None
    channel = raw_ids[0]
    chunks = [(offset, length, next((o for cid, o in _CHANNEL_OFFSET.iter_unpack(m) if cid == channel), None))
              for offset, length, m in indexes]
    return channel, counted.get(channel, 0), chunks


def _channel_format(body: bytes, at: int, end: int) -> str:
    """The `sniffer.format` of a channel record's metadata (what follows its topic: the message encoding, then a
    map of strings), RAW_FORMAT where it has none; "" where the record does not read so."""
    try:
        (n,) = struct.unpack_from("<I", body, at)
        at += 4 + n
        (size,) = struct.unpack_from("<I", body, at)
        at += 4
        stop = at + size
        if stop > end:
            return ""
        while at < stop:
            (k,) = struct.unpack_from("<I", body, at)
            key = body[at + 4: at + 4 + k]
            at += 4 + k
            (v,) = struct.unpack_from("<I", body, at)
            value = body[at + 4: at + 4 + v]
            at += 4 + v
            if key == b"sniffer.format":
                return value.decode("utf-8", "replace")
    except struct.error:
        return ""
    return RAW_FORMAT


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
