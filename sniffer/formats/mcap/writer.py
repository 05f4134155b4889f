"""A small chunked MCAP writer: what McapSink needs, at a fraction of the mcap library's cost per message.

The mcap package's Writer builds a dataclass and several stream calls per
message (about 6 us); a capture writes one message per frame and one per
source event, so on a fast replay or export the Writer took a third of the
run.  This one packs a message record with one struct call into the current
chunk and keeps the chunk's message index as flat lists.  The file is plain
MCAP (https://mcap.dev/spec): magic, Header, Metadata, Schemas, Channels,
zstd Chunks each followed by their Message Index records, Attachments, Data
End, and a summary (Schemas, Channels, Statistics, Chunk Indexes, Attachment
Indexes, Metadata Indexes, Summary Offsets) with the Footer.  A channel may be
registered at any time (it is written before the chunk holding its first
message).  Chunk and attachment CRCs are written; the data-section
and summary CRCs are 0 ("not computed", as the spec allows).  The mcap
library reads it back in the tests (tests/test_mcap.py).

`out` is a stream with write() and tell(); every write() call carries whole
records (a chunk and its message indexes in one call), which is what
sinks.mcap._AppendFile relies on to cut a failed file back cleanly.

A live capture keeps one chunk open for many seconds and writes it out every
second all the same: `flush(seal=False)` writes the open chunk as it is (a
whole chunk record with its message indexes, readable as any other) in place
of the copy the last such flush wrote (`out.rewrite(offset, data)`), and the
messages stay open; `flush()` seals it (its chunk index goes to the summary).
A short chunk every second costs its own index records and its compression's
start (a live capture's file was 13.6 times the line's bytes with one a
second; benchmarks/bench_segment_bytes.py).  Any other record (a channel
registered late, metadata, an attachment, the end) seals the open chunk first,
so the rewritten copy is always the file's last records.
"""

from __future__ import annotations

import struct
import zlib

import zstandard

from sniffer.formats.mcap.format import MAGIC

OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_ATTACHMENT, OP_ATTACHMENT_INDEX = 0x07, 0x08, 0x09, 0x0A
OP_STATISTICS, OP_METADATA, OP_METADATA_INDEX = 0x0B, 0x0C, 0x0D
OP_SUMMARY_OFFSET, OP_DATA_END = 0x0E, 0x0F

_RECORD = struct.Struct("<BQ")
_MESSAGE = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, log time, publish time
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")


def _str(s: str) -> bytes:
    b = s.encode()
    return _U32.pack(len(b)) + b


def _map_str(d: dict[str, str]) -> bytes:
    body = b"".join(_str(k) + _str(v) for k, v in d.items())
    return _U32.pack(len(body)) + body


def _record(opcode: int, body: bytes) -> bytes:
    return _RECORD.pack(opcode, len(body)) + body


class McapWriter:
    def __init__(self, out, *, chunk_size: int = 1 << 20, compression: str = "zstd",
                 packing: tuple[int, int] = (0, 0), level: int = 3) -> None:
        if compression not in ("zstd", ""):
            raise ValueError(f"compression {compression!r}: zstd or none")
        self._out = out
        self.chunk_size = chunk_size
        self.compression = compression
        self._zstd = zstandard.ZstdCompressor(level=level) if compression == "zstd" else None
        self._schemas: list[bytes] = []  # schema records, for the summary
        self._channels: list[bytes] = []
        self._channel_ids: list[int] = []
        self._metadata_index: list[bytes] = []
        self._attachment_index: list[bytes] = []
        self.summary_bytes = 0  # what the summary will repeat or index so far (schemas, channels, indexes)
        self._chunk_indexes: list[bytes] = []
        self._counts: dict[int, int] = {}
        self._messages = 0
        self._start = self._end = None
        self._chunk = bytearray()
        self._index: dict[int, list[int]] = {}  # channel -> [log time, offset, log time, offset, ...]
        self._c_start = self._c_end = 0
        self._open_messages = 0  # in the open chunk
        # of the chunks written, their compression so far (`packing`: a segment starts from the last one's)
        self._raw_bytes, self._packed_bytes = packing
        self.chunk_bytes = 0  # compressed message bytes of this file's chunks written so far
        self._finished = False
        # the open chunk's copy on disk (flush(seal=False)): where it starts, its bytes, (raw, compressed) sizes
        self._copy_at: int | None = None
        self.copy_bytes = 0
        self._copy_packing = (0, 0)

    # ------------------------------------------------------------ definitions
    def start(self, profile: str = "", library: str = "") -> None:
        self._out.write(MAGIC + _record(OP_HEADER, _str(profile) + _str(library)))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        self._seal_copy()
        sid = len(self._schemas) + 1
        rec = _record(OP_SCHEMA, _U16.pack(sid) + _str(name) + _str(encoding) + _U32.pack(len(data)) + data)
        self._schemas.append(rec)
        self.summary_bytes += len(rec)
        self._out.write(rec)
        return sid

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str] | None = None) -> int:
        self._seal_copy()
        cid = len(self._channels)
        rec = _record(OP_CHANNEL, _U16.pack(cid) + _U16.pack(schema_id) + _str(topic) + _str(message_encoding)
                      + _map_str(metadata or {}))
        self._channels.append(rec)
        self.summary_bytes += len(rec)
        self._channel_ids.append(cid)
        self._counts[cid] = 0
        self._out.write(rec)
        return cid

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self._seal_copy()
        offset = self._out.tell()
        rec = _record(OP_METADATA, _str(name) + _map_str(data))
        self._out.write(rec)
        self._metadata_index.append(_record(OP_METADATA_INDEX, _U64.pack(offset) + _U64.pack(len(rec)) + _str(name)))
        self.summary_bytes += len(self._metadata_index[-1])

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time: int, create_time: int = 0) -> None:
        """A file carried in the capture (outside the chunks, indexed in the summary)."""
        self._seal_copy()
        offset = self._out.tell()
        body = (_U64.pack(log_time) + _U64.pack(create_time) + _str(name) + _str(media_type)
                + _U64.pack(len(data)) + data)
        rec = _record(OP_ATTACHMENT, body + _U32.pack(zlib.crc32(body)))
        self._out.write(rec)
        self._attachment_index.append(_record(OP_ATTACHMENT_INDEX, (
            _U64.pack(offset) + _U64.pack(len(rec)) + _U64.pack(log_time) + _U64.pack(create_time)
            + _U64.pack(len(data)) + _str(name) + _str(media_type))))
        self.summary_bytes += len(self._attachment_index[-1])

    # ------------------------------------------------------------ messages
    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int, sequence: int = 0) -> None:
        chunk = self._chunk
        if not chunk:
            self._c_start = self._c_end = log_time
        elif log_time < self._c_start:
            self._c_start = log_time
        elif log_time > self._c_end:
            self._c_end = log_time
        idx = self._index.get(channel_id)
        if idx is None:
            idx = self._index[channel_id] = []
        idx += (log_time, len(chunk))
        chunk += _MESSAGE.pack(OP_MESSAGE, 22 + len(data), channel_id, sequence, log_time, publish_time)
        chunk += data
        self._counts[channel_id] += 1
        self._open_messages += 1
        if len(chunk) >= self.chunk_size:
            self.flush()

    def _seal_copy(self) -> None:
        """Seal the open chunk if a copy of it is on disk: a record written after it must not be overwritten."""
        if self._copy_at is not None:
            self.flush()

    def flush(self, seal: bool = True) -> None:
        """Write the open chunk (and its message indexes) in one call.

        seal=True finishes it: its chunk index is kept for the summary and the next message opens a new chunk.
        seal=False writes a copy of it and keeps it open: the next flush writes it again, over this copy."""
        chunk = self._chunk
        if not chunk:
            return
        raw = bytes(chunk)
        data = self._zstd.compress(raw) if self._zstd is not None else raw
        body = (_U64.pack(self._c_start) + _U64.pack(self._c_end) + _U64.pack(len(raw))
                + _U32.pack(zlib.crc32(raw)) + _str(self.compression) + _U64.pack(len(data)) + data)
        chunk_rec = _record(OP_CHUNK, body)
        chunk_offset = self._out.tell() if self._copy_at is None else self._copy_at
        pieces = [chunk_rec]
        index_offsets = {}
        pos = chunk_offset + len(chunk_rec)
        for cid, flat in self._index.items():
            entries = struct.pack(f"<{len(flat)}Q", *flat)
            rec = _record(OP_MESSAGE_INDEX, _U16.pack(cid) + _U32.pack(len(entries)) + entries)
            index_offsets[cid] = pos
            pos += len(rec)
            pieces.append(rec)
        blob = b"".join(pieces)
        if self._copy_at is None:
            self._out.write(blob)
        else:
            self._out.rewrite(chunk_offset, blob)
        if not seal:
            self._copy_at, self.copy_bytes, self._copy_packing = chunk_offset, len(blob), (len(raw), len(data))
            return
        self._copy_at, self.copy_bytes, self._copy_packing = None, 0, (0, 0)
        offsets = b"".join(_U16.pack(c) + _U64.pack(o) for c, o in index_offsets.items())
        self._chunk_indexes.append(_record(OP_CHUNK_INDEX, (
            _U64.pack(self._c_start) + _U64.pack(self._c_end) + _U64.pack(chunk_offset) + _U64.pack(len(chunk_rec))
            + _U32.pack(len(offsets)) + offsets + _U64.pack(pos - chunk_offset - len(chunk_rec))
            + _str(self.compression) + _U64.pack(len(data)) + _U64.pack(len(raw)))))
        self.summary_bytes += len(self._chunk_indexes[-1])
        self._raw_bytes += len(raw)
        self._packed_bytes += len(data)
        self.chunk_bytes += len(data)
        n = self._open_messages
        if n:
            self._start = self._c_start if self._start is None else min(self._start, self._c_start)
            self._end = self._c_end if self._end is None else max(self._end, self._c_end)
            self._messages += n
        self._chunk = bytearray()
        self._index = {}
        self._open_messages = 0

    @property
    def packing(self) -> tuple[int, int]:
        """(bytes, compressed bytes) of the messages in the chunks written so far."""
        return self._raw_bytes, self._packed_bytes

    def open_chunk_bytes(self) -> int:
        """What the open chunk will add to the file once written, estimated: its messages at the compression
        of the chunks before it, their index entries (16 bytes each), the records around them and the
        chunk's index in the summary.  0 before a chunk was written (no compression known: a guess would
        close a segment early, under its size).  A copy of the open chunk on disk gives its own compression."""
        n = len(self._chunk)
        raw, packed = self._copy_packing if self._copy_at is not None else (self._raw_bytes, self._packed_bytes)
        if not n or not raw:
            return 0
        return n * packed // raw + 16 * self._open_messages + 25 * len(self._index) + 140

    def message_bytes(self) -> int:
        """The messages' compressed bytes in this file: its chunks written, and the open one estimated at the
        compression so far (as it is, before a chunk was written)."""
        n = len(self._chunk)
        return self.chunk_bytes + (n * self._packed_bytes // self._raw_bytes if self._raw_bytes else n)

    # ------------------------------------------------------------ the end
    def finish(self) -> None:
        """Last chunk, Data End, summary and footer: the file any MCAP reader opens with its index."""
        if self._finished:
            return
        self._finished = True
        self.flush()
        out = self._out
        out.write(_record(OP_DATA_END, _U32.pack(0)))
        summary_start = out.tell()
        groups = []  # (opcode, start, length)
        pos = summary_start
        parts = []
        counts = b"".join(_U16.pack(c) + _U64.pack(n) for c, n in self._counts.items())
        stats = _record(OP_STATISTICS, (
            _U64.pack(self._messages) + _U16.pack(len(self._schemas)) + _U32.pack(len(self._channels))
            + _U32.pack(len(self._attachment_index)) + _U32.pack(len(self._metadata_index))
            + _U32.pack(len(self._chunk_indexes))
            + _U64.pack(self._start or 0) + _U64.pack(self._end or 0) + _U32.pack(len(counts)) + counts))
        for opcode, recs in ((OP_SCHEMA, self._schemas), (OP_CHANNEL, self._channels), (OP_STATISTICS, [stats]),
                             (OP_CHUNK_INDEX, self._chunk_indexes), (OP_ATTACHMENT_INDEX, self._attachment_index),
                             (OP_METADATA_INDEX, self._metadata_index)):
            if recs:
                blob = b"".join(recs)
                groups.append((opcode, pos, len(blob)))
                parts.append(blob)
                pos += len(blob)
        offset_start = pos
        parts += [_record(OP_SUMMARY_OFFSET, bytes([op]) + _U64.pack(s) + _U64.pack(n)) for op, s, n in groups]
        parts.append(_record(OP_FOOTER, _U64.pack(summary_start) + _U64.pack(offset_start) + _U32.pack(0)))
        out.write(b"".join(parts) + MAGIC)
