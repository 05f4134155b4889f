"""MCAP source: replay a capture written by McapSink, even one cut short.

Capture files are often not closed properly: the sniffer was killed, the
laptop lost power, the disk filled.  mcap's seeking reader needs the footer
and rejects such files, so `Scan` walks the records from the start itself and
stops at the first incomplete one, keeping every complete record before it
(McapSink writes whole chunks about once a second, so at most the last second
is lost).  Damage in the middle of a file (a chunk failing its CRC, a record
that does not parse) is a CaptureError pointing at `sniffer repair`, which
keeps what comes before it.
"""

from __future__ import annotations

import io
import os
import struct
from collections.abc import Iterator
from itertools import chain
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
from mcap.stream_reader import breakup_chunk

from ..events import CaptureInfo, Chunk as ChunkEvent, Gap, Tick
from ..mcap_format import (
    CAPTURE_TOPIC,
    FRAMES_TOPIC,
    MAGIC,
    METADATA_NAME,
    RAW_FORMAT,
    RAW_TOPIC,
    decode_event,
    info_from_metadata,
)
from ..records import loads
from . import CaptureError


_READERS = {
    Opcode.HEADER: Header.read,
    Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read,
    Opcode.METADATA: Metadata.read,
    Opcode.ATTACHMENT: Attachment.read,
    Opcode.DATA_END: DataEnd.read,
    Opcode.FOOTER: Footer.read,
}


class Corrupt(Exception):
    """A complete record whose bytes are wrong (not a cut-off file)."""


def sniff(path: str | os.PathLike[str]) -> bool:
    """True if the file starts with the MCAP magic."""
    try:
        with open(path, "rb") as fh:
            return fh.read(8) == MAGIC
    except OSError:
        return False


def open_file(path: str | os.PathLike[str]) -> tuple[BinaryIO, int, bool]:
    """Open an MCAP file: (file positioned after the magic, size, ends with the magic).

    Raises CaptureError if the file cannot be read or is not MCAP.
    """
    try:
        fh = open(path, "rb")
    except OSError as e:
        raise CaptureError(f"{path}: {e.strerror or e}") from None
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
      end       offset just past the last complete record read
      finished  the data section ended properly (DataEnd or Footer reached)
      problem   why it stopped early, or None
    With salvage=False a damaged record raises Corrupt; with salvage=True it
    ends the scan like a truncation would (repair keeps what came before).
    """

    def __init__(self, fh: BinaryIO, size: int, *, tail_ok: bool, salvage: bool = False) -> None:
        self._fh = fh
        self._size = size
        self._tail_ok = tail_ok
        self._salvage = salvage
        self.end = len(MAGIC)
        self.finished = False
        self.problem: str | None = None
        self.channels: dict[int, Channel] = {}

    def topic(self, msg: Message) -> str | None:
        ch = self.channels.get(msg.channel_id)
        return None if ch is None else ch.topic

    def records(self) -> Iterator[McapRecord]:
        """Header, Schema, Channel, Message, Metadata, Attachment, DataEnd/Footer records, in file order.

        Chunks are opened (CRC checked); index and summary records are skipped.
        """
        fh, pos = self._fh, self.end
        first = True
        while True:
            head = fh.read(9)
            if len(head) < 9:
                self._cut(pos, "the file ends without a footer" if not head else "the last record is cut off")
                return
            opcode, length = struct.unpack("<BQ", head)
            if length > self._size - pos - 9:
                self._cut(pos, "the last record is cut off")
                return
            body = fh.read(length)
            if len(body) < length:
                self._cut(pos, "the last record is cut off")
                return
            try:
                if first and opcode != Opcode.HEADER:
                    raise ValueError("the file does not start with a header record")
                recs = _parse(opcode, body)
            except Exception as e:  # parsing foreign bytes: any failure means damage
                self._damaged(pos, opcode, e)  # raises Corrupt unless salvaging
                return
            first = False
            pos += 9 + length
            self.end = pos
            for r in recs:
                if isinstance(r, Channel):
                    self.channels[r.id] = r
                yield r
            if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                self.finished = True
                return

    def _cut(self, pos: int, why: str) -> None:
        if self._tail_ok and not self._salvage:
            # a file that ends properly cannot be cut off in its data section
            raise Corrupt(f"record at byte {pos} runs past the end of the data")
        self.problem = f"{why} at byte {pos}"

    def _damaged(self, pos: int, opcode: int, e: Exception) -> None:
        try:
            name = Opcode(opcode).name.lower().replace("_", " ")
        except ValueError:
            name = f"opcode 0x{opcode:02x}"
        self.problem = f"damaged {name} record at byte {pos} ({str(e) or type(e).__name__})"
        if not self._salvage:
            raise Corrupt(self.problem)


def _parse(opcode: int, body: bytes) -> list[McapRecord]:
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.CHUNK:
        return breakup_chunk(Chunk.read(stream), validate_crc=True)
    if opcode == Opcode.MESSAGE:
        if len(body) < 22:
            raise ValueError("message record too short")
        return [Message.read(stream, len(body))]
    read = _READERS.get(opcode)  # type: ignore[call-overload]
    return [] if read is None else [read(stream)]


def _info(path: str, data: bytes | dict[str, str]) -> CaptureInfo:
    try:
        if isinstance(data, dict):
            return info_from_metadata(data)
        return CaptureInfo.from_dict(loads(data))
    except (ValueError, TypeError, AttributeError) as e:
        raise CaptureError(f"{path}: damaged capture info ({e})") from None


def open_mcap(path: str | os.PathLike[str]) -> tuple[CaptureInfo, Iterator[ChunkEvent | Tick | Gap]]:
    """CaptureInfo and the recorded events, exactly as McapSink got them.

    A file that was not finished (killed writer, full disk) is read up to
    its last complete record; info.extra["mcap_unfinished"] is then True so
    the caller can say so.  Events are read lazily; damage found later in
    the file raises CaptureError from the iterator.
    """
    p = os.fspath(path)
    fh, size, tail_ok = open_file(p)
    scan = Scan(fh, size, tail_ok=tail_ok)
    records = scan.records()
    info: CaptureInfo | None = None
    early: list[Message] = []
    try:
        for rec in records:
            if isinstance(rec, Metadata) and rec.name == METADATA_NAME:
                info = _info(p, rec.metadata)
                break
            if isinstance(rec, Message):
                topic = scan.topic(rec)
                if topic == CAPTURE_TOPIC:
                    info = _info(p, rec.data)
                    break
                if topic == RAW_TOPIC:
                    early.append(rec)
    except Corrupt as e:
        fh.close()
        raise CaptureError(f"{p}: {e}; `sniffer repair` keeps what comes before") from None
    except CaptureError:
        fh.close()
        raise
    if info is None:
        fh.close()
        if scan.problem and not scan.finished:
            raise CaptureError(f"{p}: MCAP file cut off before its capture info ({scan.problem}); nothing to replay")
        raise CaptureError(f"{p}: MCAP file has no sniffer capture info (not recorded by sniffer?)")
    if not tail_ok:
        info.extra["mcap_unfinished"] = True
    return info, _events(p, fh, scan, records, early)


def _events(path: str, fh: BinaryIO, scan: Scan, records: Iterator[McapRecord], early: list[Message]):
    checked: set[int] = set()
    try:
        for msg in chain(early, (r for r in records if isinstance(r, Message))):
            if scan.topic(msg) != RAW_TOPIC:
                continue
            if msg.channel_id not in checked:
                fmt = scan.channels[msg.channel_id].metadata.get("sniffer.format", RAW_FORMAT)
                if fmt != RAW_FORMAT:
                    raise CaptureError(f"{path}: /raw format {fmt!r} is newer than this sniffer reads ({RAW_FORMAT})")
                checked.add(msg.channel_id)
            ev = _event(path, msg)
            if ev is not None:
                yield ev
    except Corrupt as e:
        raise CaptureError(f"{path}: {e}; `sniffer repair` keeps what comes before") from None
    finally:
        fh.close()


def _event(path: str, msg: Message) -> ChunkEvent | Tick | Gap | None:
    try:
        return decode_event(msg.data)
    except (ValueError, KeyError, TypeError) as e:
        raise CaptureError(f"{path}: damaged /raw message #{msg.sequence} ({e})") from None


def read_frames(path: str | os.PathLike[str]) -> list[dict]:
    """The /frames records (the JSONL dicts) in file order; unfinished files are read up to their cut."""
    p = os.fspath(path)
    fh, size, tail_ok = open_file(p)
    scan = Scan(fh, size, tail_ok=tail_ok)
    out: list[dict] = []
    try:
        for rec in scan.records():
            if isinstance(rec, Message) and scan.topic(rec) == FRAMES_TOPIC:
                out.append(loads(rec.data))
    except Corrupt as e:
        raise CaptureError(f"{p}: {e}; `sniffer repair` keeps what comes before") from None
    except ValueError as e:
        raise CaptureError(f"{p}: damaged /frames message ({e})") from None
    finally:
        fh.close()
    return out
