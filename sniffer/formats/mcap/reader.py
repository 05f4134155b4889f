"""MCAP source: replay a capture written by McapSink, even one cut short or damaged.

sniffer.formats.mcap.scan walks the records: a file that just stops (killed
writer, full disk) is read up to its last complete record and
info.extra["mcap_unfinished"] says so; that is expected, not damage.  A file
cut off before it recorded anything (the header alone: a segment opened just
before a kill) is `EmptyCapture`.  A hole
in the middle (a chunk failing its CRC, a record that does not parse, a
damaged length) is skipped: every readable event is still replayed, a Gap
marks the place and `damage` says what was lost.  A /raw message that does
not decode is skipped the same way.  Fatal (CaptureError): not MCAP, no
sniffer capture info, a /raw format newer than this reader.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import BinaryIO

from mcap.records import Message, Metadata

from sniffer.events import CaptureInfo, Chunk as ChunkEvent, Gap, Tick
from sniffer.formats.mcap.format import (
    CAPTURE_TOPIC, FRAMES_TOPIC, MAGIC, METADATA_NAME, RAW_BATCH_FORMAT, RAW_FORMAT, RAW_FORMATS, RAW_TOPIC,
    decode_batch, decode_event, info_from_metadata,
)
from sniffer.formats.records import loads
from sniffer.events import CaptureError
from sniffer.formats.reading import DamageLog, file_position, gap_before, quote
from sniffer.inputs import open_regular
from sniffer.formats.reading import EmptyCapture
from sniffer.formats.mcap.scan import Corrupt, Hole, Scan, open_file

__all__ = ["Corrupt", "McapSource", "Scan", "open_file", "open_mcap", "read_frames", "sniff"]


def sniff(path: str | os.PathLike[str]) -> bool:
    """True if the file starts with the MCAP magic."""
    try:
        with open_regular(path) as fh:
            return fh.read(8) == MAGIC
    except (CaptureError, OSError):
        return False


def _info(path: str, data: bytes | dict[str, str]) -> CaptureInfo:
    try:
        if isinstance(data, dict):
            return info_from_metadata(data)
        return CaptureInfo.from_dict(loads(data))
    except (ValueError, TypeError, AttributeError) as e:
        raise CaptureError(f"{path}: damaged capture info ({str(e)[:200]})") from None


class McapSource:
    """One MCAP capture: open() reads up to the capture info, events() goes on from there."""

    def __init__(self, path: str | os.PathLike[str], damage: list[str] | None = None) -> None:
        self.path = os.fspath(path)
        self.damage: list[str] = [] if damage is None else damage
        self._log = DamageLog(self.damage)
        self.info: CaptureInfo | None = None
        self._fh: BinaryIO | None = None
        self._size = 0
        self._scan: Scan | None = None
        self._records: Iterator | None = None
        self._early: list = []

    def position(self) -> tuple[int, int] | None:
        return file_position(self._fh, self._size)

    def open(self) -> CaptureInfo:
        if self.info is not None:
            return self.info
        p = self.path
        fh, size, tail_ok = open_file(p)
        self._fh, self._size = fh, size
        scan = self._scan = Scan(fh, size, tail_ok=tail_ok, keep_topics=frozenset({CAPTURE_TOPIC, RAW_TOPIC}))
        records = self._records = scan.records()
        info: CaptureInfo | None = None
        recorded = False  # a message or metadata record read (header, schemas and channels record nothing)
        try:
            for rec in records:
                recorded = recorded or isinstance(rec, (Message, Metadata))
                if isinstance(rec, Metadata) and rec.name == METADATA_NAME:
                    info = _info(p, rec.metadata)
                    break
                if isinstance(rec, Hole):
                    self._early.append(rec)
                elif isinstance(rec, Message):
                    topic = scan.topic(rec)
                    if topic == CAPTURE_TOPIC:
                        info = _info(p, rec.data)
                        break
                    if topic == RAW_TOPIC:
                        self._early.append(rec)
        except (CaptureError, OSError) as e:
            self.close()
            if isinstance(e, OSError):
                raise CaptureError(f"{p}: {e.strerror or e}") from None
            raise
        if info is None:
            self.close()
            if scan.holes:
                raise CaptureError(f"{p}: no readable sniffer capture info ({scan.holes[0][2]})")
            if scan.problem and not scan.finished:
                cls = EmptyCapture if not recorded else CaptureError  # header only: killed as it began
                raise cls(f"{p}: MCAP file cut off before its capture info ({scan.problem}); nothing to replay")
            raise CaptureError(f"{p}: MCAP file has no sniffer capture info (not recorded by sniffer?)")
        if not tail_ok:
            info.extra["mcap_unfinished"] = True
        self.info = info
        return info

    def events(self) -> Iterator[ChunkEvent | Tick | Gap]:
        """The recorded events exactly as McapSink got them, a Gap where damaged bytes were skipped."""
        self.open()
        scan, records = self._scan, self._records
        assert scan is not None and records is not None
        batched: dict[int, bool] = {}  # /raw channel -> its messages hold several events (format 2)
        last: int | None = None
        hole: str | None = None
        early, self._early = self._early, []
        orphans: dict[int, int] = {}
        try:
            for rec in _chain(early, records):
                if isinstance(rec, Hole):
                    self._log.add("holes", f"{self.path}: {rec.reason}: skipped {rec.length} bytes")
                    hole = hole or f"damaged capture file: {rec.length} bytes skipped at byte {rec.offset}"
                    continue
                if not isinstance(rec, Message):
                    continue
                topic = scan.topic(rec)
                if topic is None:
                    orphans[rec.channel_id] = orphans.get(rec.channel_id, 0) + 1
                    continue
                if topic != RAW_TOPIC:
                    continue
                batch = batched.get(rec.channel_id)
                if batch is None:
                    fmt = scan.channels[rec.channel_id].metadata.get("sniffer.format", RAW_FORMAT)
                    if fmt not in RAW_FORMATS:
                        raise CaptureError(f"{self.path}: /raw format {quote(str(fmt), 40)} is newer than this "
                                           f"sniffer reads ({RAW_BATCH_FORMAT})")
                    batch = batched[rec.channel_id] = fmt == RAW_BATCH_FORMAT
                try:
                    evs = decode_batch(rec.data) if batch else (decode_event(rec.data),)
                except (ValueError, KeyError, TypeError) as e:
                    self._log.add("bad messages", f"{self.path}: damaged /raw message #{rec.sequence} skipped "
                                                  f"({str(e)[:200]})")
                    hole = hole or f"damaged /raw message #{rec.sequence} skipped"
                    continue
                for ev in evs:
                    if ev is None:
                        continue
                    if hole is not None:
                        yield gap_before(last, ev, hole)
                        hole = None
                    last = _last_time(ev)
                    yield ev
            if hole is not None and last is not None:
                yield Gap(last, last, hole)
        except OSError as e:
            self._log.add("read errors", f"{self.path}: read error: {e.strerror or e}; the rest was not read")
        finally:
            if orphans:
                self._log.add("orphans", f"{self.path}: {sum(orphans.values())} messages skipped: the definition "
                                         f"of their channel ({', '.join(map(str, sorted(orphans)))}) was lost")
            self._log.finish(self.path)
            self.close()

    def close(self) -> None:
        fh, self._fh = self._fh, None
        if fh is not None:
            fh.close()


def _chain(first: list, rest: Iterator) -> Iterator:
    yield from first
    yield from rest


def _last_time(ev: ChunkEvent | Tick | Gap) -> int:
    if type(ev) is Gap:
        return ev.t_end_ns
    if type(ev) is ChunkEvent and ev.byte_t_ns:
        return ev.byte_t_ns[-1]
    return ev.t_ns


def open_mcap(path: str | os.PathLike[str]) -> tuple[CaptureInfo, Iterator[ChunkEvent | Tick | Gap]]:
    """CaptureInfo and the recorded events, exactly as McapSink got them.

    A file that was not finished (killed writer, full disk) is read up to
    its last complete record; info.extra["mcap_unfinished"] is then True so
    the caller can say so.  Events are read lazily; what damage skipped is
    only in McapSource.damage (use sniffer.sources.files.FileSource).
    """
    src = McapSource(path)
    return src.open(), src.events()


def read_frames(path: str | os.PathLike[str]) -> list[dict]:
    """The /frames records (the JSONL dicts) in file order; unfinished files are read up to their cut,
    damaged records and messages are skipped."""
    p = os.fspath(path)
    fh, size, tail_ok = open_file(p)
    scan = Scan(fh, size, tail_ok=tail_ok)
    out: list[dict] = []
    try:
        for rec in scan.records():
            if isinstance(rec, Message) and scan.topic(rec) == FRAMES_TOPIC:
                try:
                    out.append(loads(rec.data))
                except ValueError:
                    continue
    finally:
        fh.close()
    return out


SOURCE = McapSource  # what sniffer.formats.files makes of a file of this format
