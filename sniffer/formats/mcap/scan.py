"""Walk the records of an MCAP file, even a cut-off or damaged one (for the reader and `sniffer repair`).

Capture files are often not closed properly: the sniffer was killed, the
laptop lost power, the disk filled.  mcap's seeking reader needs the footer
and rejects such files, so `Scan` walks the records from the start itself.
A file that just stops is read to its last complete record (McapSink writes
whole chunks about once a second, so at most the last second is lost): that
is expected, not damage.  Damage in the middle (a chunk failing its CRC, a
record that does not parse, a length field that cannot be right) is skipped:
the scan finds the next intact record, reports the hole and goes on.
"""

from __future__ import annotations

import io
import os
import re
import struct
from collections.abc import Iterator
from typing import BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Message,
    Metadata,
    Schema,
)
from mcap.stream_reader import breakup_chunk, get_chunk_data_stream

from sniffer.formats.mcap.format import MAGIC
from sniffer.events import CaptureError
from sniffer.inputs import open_regular
from sniffer.hot import HOT

_READERS = {
    Opcode.HEADER: Header.read,
    Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read,
    Opcode.METADATA: Metadata.read,
    Opcode.ATTACHMENT: Attachment.read,
    Opcode.DATA_END: DataEnd.read,
    Opcode.FOOTER: Footer.read,
}
_SIZES = {Opcode.DATA_END: 4, Opcode.FOOTER: 20}


class Corrupt(Exception):
    """A complete record whose bytes are wrong (not a cut-off file); kept for callers that catch it."""


class Hole:
    """Bytes of the data section that hold no readable record (a marker among Scan.records())."""

    __slots__ = ("offset", "length", "reason")

    def __init__(self, offset: int, length: int, reason: str) -> None:
        self.offset, self.length, self.reason = offset, length, reason


MAX_RECORD = 256 << 20  # a record claiming more is taken as a damaged length field (ours are a few MB)
_VALID_OPCODES = frozenset(int(op) for op in Opcode)
# where a scan may pick the file up again after damage: records of the data section
_RESYNC_CHUNKED = frozenset({Opcode.CHUNK, Opcode.MESSAGE_INDEX, Opcode.METADATA, Opcode.ATTACHMENT,
                             Opcode.DATA_END, Opcode.FOOTER})
_RESYNC_PLAIN = _RESYNC_CHUNKED | {Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE}
_SCAN_BLOCK = 1 << 16


def _candidates(opcodes) -> re.Pattern[bytes]:
    """Offsets holding one of these opcodes and a length below 2**32 (its high four bytes zero)."""
    cls = b"".join(re.escape(bytes([int(op)])) for op in sorted(opcodes))
    return re.compile(b"(?=[" + cls + b"][\\s\\S]{4}\\x00\\x00\\x00\\x00)")


_CAND_CHUNKED = _candidates(_RESYNC_CHUNKED)
_CAND_PLAIN = _candidates(_RESYNC_PLAIN)


def open_file(path: str | os.PathLike[str]) -> tuple[BinaryIO, int, bool]:
    """Open an MCAP file: (file positioned after the magic, size, ends with the magic).

    Raises CaptureError if the file cannot be read or is not MCAP.
    """
    fh = open_regular(path)
    try:
        size = os.fstat(fh.fileno()).st_size
        head = fh.read(8)
        if not head:
            raise CaptureError(f"{path}: empty file")
        if head != MAGIC:
            raise CaptureError(f"{path}: not an MCAP file (no MCAP magic at the start)")
        tail_ok = False
        if size >= 16:
            fh.seek(size - 8)
            tail_ok = fh.read(8) == MAGIC
            fh.seek(8)
        return fh, size, tail_ok
    except OSError as e:
        fh.close()
        raise CaptureError(f"{path}: {e.strerror or e}") from None
    except CaptureError:
        fh.close()
        raise


class Scan:
    """One pass over the data section of an MCAP file, record by record.

    After (or during) `records()`:
      end       offset just past the last record read (or of the bytes skipped at the end)
      finished  the data section ended properly (DataEnd or Footer reached)
      problem   why the data stopped before its end (a cut-off file), or None
      holes     [(offset, bytes, why)]: damage in the middle, skipped (each also yielded as a Hole)
    A record that cannot be right (a chunk failing its CRC, bytes that do not
    parse, a length past the end of a finished file) does not end the scan:
    it looks for the next offset where a record of the data section parses
    (a chunk's CRC must check; other records must be followed by a plausible
    record header) and goes on from there.  In a file that has chunks, a bare
    message, schema or channel is never taken as that place: those live
    inside chunks.  A file that just stops (killed writer) is read to its last
    complete record: that is `problem`, not a hole.  `salvage` is accepted
    for old callers and changes nothing.
    """

    def __init__(self, fh: BinaryIO, size: int, *, tail_ok: bool, salvage: bool = False,
                 skip_topics: frozenset[str] = frozenset(), keep_topics: frozenset[str] | None = None) -> None:
        self._fh = fh
        # messages of the skip topics (of every topic but the keep topics) are not parsed nor yielded
        # (a replay needs /raw only; /frames and the Foxglove topics hold most of the messages)
        self.skip_topics = skip_topics
        self.keep_topics = keep_topics
        self._skip = keep_topics is not None or bool(skip_topics)
        self._size = size
        self._tail_ok = tail_ok
        self.end = len(MAGIC)
        self.finished = False
        self.problem: str | None = None
        self.holes: list[tuple[int, int, str]] = []
        self.channels: dict[int, Channel] = {}
        self._chunked = False
        self._summary: dict | None = None
        self._skip_ids: frozenset[int] | None = None  # ids of the channels skipped, until `channels` changes

    def skipped(self, topic: str) -> bool:
        """Are this topic's messages left out?"""
        return topic in self.skip_topics or (self.keep_topics is not None and topic not in self.keep_topics)

    def topic(self, msg: Message) -> str | None:
        ch = self.channels.get(msg.channel_id) or self.lost_channel(msg.channel_id)
        return None if ch is None else ch.topic

    def lost_channel(self, cid: int) -> Channel | None:
        """A channel whose definition was in damaged bytes, from the summary of a finished file (or None)."""
        if self._summary is None:
            self._summary = self._read_summary()
        ch = self._summary.get(("channel", cid))
        if isinstance(ch, Channel):
            self.channels[cid] = ch
            self._skip_ids = None
            return ch
        return None

    def lost_schema(self, sid: int) -> Schema | None:
        if self._summary is None:
            self._summary = self._read_summary()
        sc = self._summary.get(("schema", sid))
        return sc if isinstance(sc, Schema) else None

    def _read_summary(self) -> dict:
        """{("channel" | "schema", id): record} of the summary section, found through the footer."""
        fh, size, out = self._fh, self._size, {}
        if not self._tail_ok or size < 8 + 29 + 8:
            return out
        here = fh.tell()
        try:
            fh.seek(size - 8 - 29)
            head = fh.read(29)
            opcode, length = struct.unpack_from("<BQ", head)
            start = struct.unpack_from("<Q", head, 9)[0]
            if opcode != Opcode.FOOTER or length != 20 or not 8 <= start < size - 37:
                return out
            pos = start
            while pos + 9 <= size - 37:
                fh.seek(pos)
                opcode, length = struct.unpack("<BQ", fh.read(9))
                if length > min(MAX_RECORD, size - 37 - pos - 9):
                    break
                if opcode in (Opcode.CHANNEL, Opcode.SCHEMA):
                    try:
                        (rec,) = _parse(opcode, fh.read(length))
                    except Exception:  # noqa: BLE001 - a damaged summary: use what came before
                        break
                    out[("channel" if opcode == Opcode.CHANNEL else "schema", rec.id)] = rec
                pos += 9 + length
        except (OSError, struct.error):
            pass
        finally:
            fh.seek(here)
        return out

    def records(self) -> Iterator[McapRecord | Hole]:
        """Header, Schema, Channel, Message, Metadata, Attachment, DataEnd/Footer records in file order,
        and a Hole where damaged bytes were skipped.

        Chunks are opened (CRC checked); index and summary records are skipped.
        """
        fh, pos, size = self._fh, self.end, self._size
        first = True
        while True:
            fh.seek(pos)
            head = fh.read(9)
            if len(head) < 9:
                self._cut(pos, "the file ends without a footer" if not head else "the last record is cut off")
                return
            opcode, length = struct.unpack("<BQ", head)
            recs: list[McapRecord] = []
            overrun = length > size - pos - 9
            why = "it runs past the end of the file" if overrun else None
            if why is None and length > MAX_RECORD:
                why = f"it claims {length} bytes"
            if why is None:
                try:
                    if first and opcode != Opcode.HEADER:
                        raise ValueError("the file does not start with a header record")
                    if opcode == Opcode.CHUNK and self._skip:
                        recs = _walk_chunk(fh.read(length), self.channels, self.skipped, skip_ids=self._skipped_ids())
                    else:
                        recs = _parse(opcode, fh.read(length))
                except Exception as e:  # parsing foreign bytes: any failure means damage
                    why = (str(e) or type(e).__name__)[:200]
            first = False
            if why is None:
                pos += 9 + length
                if opcode == Opcode.CHUNK:
                    self._chunked = True
                    pos = self._past_indexes(pos)
                self.end = pos
                for r in recs:
                    if isinstance(r, Channel):
                        self.channels[r.id] = r
                        self._skip_ids = None
                    yield r
                if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    self.finished = True
                    return
                continue
            q = self._resync(pos + 1)
            if q is None and overrun and not self._tail_ok:
                self._cut(pos, "the last record is cut off")
                return
            hole_end = size if q is None else q
            what = f"damaged {_name(opcode)} record at byte {pos} ({why})"
            if q is None:
                what += ", no readable record after it"
            self.holes.append((pos, hole_end - pos, what))
            self.end = hole_end
            yield Hole(pos, hole_end - pos, what)
            if q is None:
                return
            pos = q

    def _skipped_ids(self) -> frozenset[int]:
        """The ids of the known channels whose messages are left out: the same for every chunk until a
        channel is added (a file of many channels has hundreds, and thousands of chunks)."""
        ids = self._skip_ids
        if ids is None:
            skip = self.skipped
            ids = self._skip_ids = frozenset(cid for cid, ch in self.channels.items() if skip(ch.topic))
        return ids

    def _past_indexes(self, pos: int) -> int:
        """Past the message index records a chunk is followed by (one per channel in it), read in blocks:
        a file with many channels has hundreds after each chunk.  One that is not well formed is left to
        `records` (which reports it)."""
        fh = self._fh
        while True:
            fh.seek(pos)
            buf = fh.read(_SCAN_BLOCK)
            i = _index_run(buf)
            if i == 0:
                return pos
            pos += i

    def _cut(self, pos: int, why: str) -> None:
        self.problem = f"{why} at byte {pos}"

    def _resync(self, start: int) -> int | None:
        """The next offset >= start where a record of the data section is intact, or None."""
        fh, size = self._fh, self._size
        pattern = _CAND_CHUNKED if self._chunked else _CAND_PLAIN
        q = start
        while q + 9 <= size:
            fh.seek(q)
            buf = fh.read(_SCAN_BLOCK + 8)
            for m in pattern.finditer(buf, 0, _SCAN_BLOCK):
                if self._intact(q + m.start()):
                    return q + m.start()
            q += _SCAN_BLOCK
        return None

    def _intact(self, q: int) -> bool:
        fh, size = self._fh, self._size
        fh.seek(q)
        opcode, length = struct.unpack("<BQ", fh.read(9))
        nxt = q + 9 + length
        if nxt > size or length > MAX_RECORD or not self._header_after(nxt, opcode):
            return False
        fh.seek(q + 9)
        try:
            recs = _parse(opcode, fh.read(length))
        except Exception:  # noqa: BLE001 - not a record
            return False
        if opcode == Opcode.MESSAGE and recs and recs[0].channel_id not in self.channels:
            return False
        return True

    def _header_after(self, nxt: int, opcode: int) -> bool:
        """Does a plausible record (or the end of the file) follow a record ending at nxt?"""
        size = self._size
        if opcode == Opcode.FOOTER:
            return nxt == size - 8
        if size - nxt < 9:
            return True
        self._fh.seek(nxt)
        op, length = struct.unpack("<BQ", self._fh.read(9))
        return op in _VALID_OPCODES and length < 2**32


def _index_run_py(buf: bytes) -> int:
    """How many bytes from the start of `buf` are whole, well-formed message index records (the reference
    of sniffer/_hot.c index_run)."""
    i, n = 0, len(buf)
    while i + 15 <= n:
        opcode, length = _RECORD_HEAD.unpack_from(buf, i)
        end = i + 9 + length
        if (opcode != Opcode.MESSAGE_INDEX or end > n or (length - 6) % 16
                or int.from_bytes(buf[i + 11 : i + 15], "little") != length - 6):
            break
        i = end
    return i


def _name(opcode: int) -> str:
    try:
        return Opcode(opcode).name.lower().replace("_", " ")
    except ValueError:
        return f"opcode 0x{opcode:02x}"


_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time


# the run of plain messages in a chunk, read in C (sniffer/_hot.c chunk_messages); None: in Python
_CHUNK_MESSAGES = None if HOT is None else HOT.chunk_messages
_index_run = _index_run_py if HOT is None else HOT.index_run


def _walk_chunk(body: bytes, channels: dict[int, Channel], skip, messages=_CHUNK_MESSAGES,
                skip_ids: frozenset[int] | None = None) -> list[McapRecord]:
    """breakup_chunk (CRC checked) that does not build the messages of the topics `skip(topic)` leaves out.

    Channels defined in the chunk count from where they stand; a message whose
    channel is not known yet is kept (its reader decides what it is).  `messages` (the compiled loop)
    reads runs of well-formed messages and stops before any other record, which the loop here reads.
    """
    chunk = _chunk(body)
    stream, n = get_chunk_data_stream(chunk, validate_crc=True)
    data = stream.read(n)
    out: list[McapRecord] = []
    known = dict(channels)
    skipped = set(skip_ids) if skip_ids is not None else {cid for cid, ch in known.items() if skip(ch.topic)}
    unpack_head, unpack_msg = _RECORD_HEAD.unpack_from, _MESSAGE_HEAD.unpack_from
    pos = 0
    while pos < n:
        if messages is not None:
            pos = messages(data, pos, skipped, Message, out)
            if pos >= n:
                break
        opcode, length = unpack_head(data, pos)
        start, pos = pos + 9, pos + 9 + length
        if pos > n:
            raise ValueError("a record runs past the end of its chunk")
        if opcode == Opcode.MESSAGE:
            if length < 22:
                raise ValueError("message record too short")
            cid, seq, log_time, publish_time = unpack_msg(data, start)
            if cid not in skipped:
                out.append(Message(channel_id=cid, sequence=seq, log_time=log_time, publish_time=publish_time,
                                   data=data[start + 22 : pos]))
        elif opcode in (Opcode.CHANNEL, Opcode.SCHEMA):
            rec = (Channel if opcode == Opcode.CHANNEL else Schema).read(ReadDataStream(io.BytesIO(data[start:pos])))
            if isinstance(rec, Channel):
                known[rec.id] = rec
                if skip(rec.topic):
                    skipped.add(rec.id)
            out.append(rec)
    return out


_RECORD_HEAD = struct.Struct("<BQ")


def _chunk(body: bytes) -> Chunk:
    chunk = Chunk.read(ReadDataStream(io.BytesIO(body)))
    if chunk.uncompressed_size > MAX_RECORD:
        raise ValueError(f"chunk claims {chunk.uncompressed_size} bytes uncompressed")
    if chunk.compression == "zstd":
        import zstandard

        declared = zstandard.frame_content_size(chunk.data)
        if declared not in (-1, chunk.uncompressed_size):
            raise ValueError("chunk sizes disagree")
    return chunk


def record_reads(opcode: int, body: bytes) -> bool:
    """Does a record's body read as `Scan.records` reads it (where it does not, the scan reports a hole)?"""
    try:
        _parse(opcode, body)
    except Exception:  # noqa: BLE001 - parsing foreign bytes: any failure means damage
        return False
    return True


def _parse(opcode: int, body: bytes) -> list[McapRecord]:
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.CHUNK:
        return breakup_chunk(_chunk(body), validate_crc=True)
    if opcode == Opcode.MESSAGE:
        if len(body) < 22:
            raise ValueError("message record too short")
        return [Message.read(stream, len(body))]
    if opcode == Opcode.MESSAGE_INDEX:  # skipped, but a scan may land on one: check its shape
        if len(body) < 6 or (len(body) - 6) % 16 or int.from_bytes(body[2:6], "little") != len(body) - 6:
            raise ValueError("message index of the wrong size")
        return []
    if opcode in _SIZES and len(body) != _SIZES[opcode]:
        raise ValueError(f"{len(body)} bytes, not {_SIZES[opcode]}")
    read = _READERS.get(opcode)  # type: ignore[call-overload]
    return [] if read is None else [read(stream)]


