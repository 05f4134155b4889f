"""MCAP sink: a capture file that replays exactly and opens in Foxglove.

What goes in it (topics, schemas, the /raw codec) is sniffer.formats.mcap.format;
what Foxglove's panels read besides (the `foxglove` metadata, /annotations as
foxglove.Log, a /values topic per register, the models' register maps as
attachments) is sniffer.formats.mcap.foxglove, derived here from the frames (a trigger
window's encoded records too).
/capture and the `sniffer.capture` metadata are on disk right after start(),
which flushes at once, so even a file cut a second after start still knows
its baud, parity and t0 (the metadata index in the summary would be lost).

The file is written by sniffer.formats.mcap.writer (plain MCAP, chunked, zstd).

Durability.  The writer collects messages in a chunk in memory.  Every
`flush_interval_s` of *wall* time (the sink's monotonic clock, checked on each
raw()/frame() call and on `maybe_flush()`) the chunk is written to the OS, so a
SIGKILL loses at most that much.  A live capture writes the open chunk each
time over its copy of the time before (McapWriter.flush(seal=False)) and seals
it every `SEAL_S` (or when it holds CHUNK_SIZE): one chunk of many seconds
packs far tighter than a chunk a second and needs one set of index records.
Wall time, not event time: the bound is about how much a crash loses, and a
fast file conversion would otherwise write thousands of tiny chunks per
second.  No fsync: the page cache survives a killed process; power loss is not
covered.  The rewrite is one write() of the open chunk's records; a kill that
lands inside that call (tens of microseconds a second) leaves the copy torn,
and the reader stops there: then the open chunk is lost, at most SEAL_S.

Full disk.  Bytes reach the file only through `_AppendFile`, which writes
whole records and, when the OS refuses a write (ENOSPC, EFBIG, EIO), cuts the
file back to the last whole record and never writes again.  The file on disk
is then a clean prefix that `sniffer.formats.mcap.reader` reads and
`sniffer.formats.mcap.repair` finishes.
"""

from __future__ import annotations

import os
import time
from collections import deque
from collections.abc import Callable

import msgspec

from sniffer import __version__
from sniffer.formats.mcap import foxglove
from sniffer.events import CaptureInfo, Chunk, Gap, Tick
from sniffer.frame import Frame
from sniffer.formats.mcap.format import (
    BATCH_NS, CAPTURE_TOPIC, CHANNELS, FRAMES_TOPIC, METADATA_NAME, RAW_BATCH_FORMAT, RAW_BATCH_SCHEMA, RAW_FORMAT,
    RAW_TOPIC, encode_batch, encode_event, info_to_metadata,
)
from sniffer.formats.mcap.writer import McapWriter
from sniffer.formats.outputs import FILE_MODE
from sniffer.formats.records import frame_json
from sniffer.sinks.base import Sink


# uncompressed bytes per chunk: a damaged byte loses one chunk; 512 KiB files are 1 % larger than with
# 1 MiB chunks (mcap's default), 128 KiB ones 14 % (measured on a 256k-frame export)
CHUNK_SIZE = 512 * 1024
# zstd's level: an export's chunks are full and many (3: fast); a live capture compresses its open chunk
# again every flush interval, at level 9 about 8 ms for a full one (benchmarks/bench_segment_bytes.py); 19
# packs a tenth tighter but takes ~0.2 s a chunk, a stall in the capture's loop
EXPORT_LEVEL, LIVE_LEVEL = 3, 9
# a live capture's open chunk is written every flush interval over its copy and sealed after this long
SEAL_S = 30.0


class CaptureStorageError(Exception):
    """The capture file cannot be written (disk full, file too large, I/O error): one line.

    `reason` is the operating system's word for it (e.g. "No space left on device")."""

    reason = ""


class _AppendFile:
    """The MCAP writer's output stream: never leaves a torn record behind.

    The writer hands each write() whole records, so the end of every
    write() is a record boundary.  Pieces wait here until flush(), which
    writes them with os.write.  If the OS refuses (disk full, EFBIG), the file
    is cut back to the end of the last piece written whole (ftruncate needs no
    space) and nothing is written again.  A BufferedWriter gives no such promise:
    after a failed flush it may keep part of its buffer and write it later,
    after a gap, which would corrupt the file instead of shortening it.
    """

    MAX_PENDING = 8 << 20  # write out early if a flush is long overdue

    def __init__(self, path: str) -> None:
        # read too: a rewrite of the open chunk keeps the copy it replaces, to put it back if the disk is full
        flags = os.O_RDWR | os.O_CREAT | os.O_TRUNC | getattr(os, "O_BINARY", 0) | getattr(os, "O_CLOEXEC", 0)
        self._fd: int | None = os.open(path, flags, FILE_MODE)
        self._pending: deque[bytes] = deque()
        self._pending_len = 0
        self.on_disk = 0
        self.failed: OSError | None = None

    def write(self, data: bytes | bytearray | memoryview) -> int:
        if self.failed is not None:
            raise self.failed
        n = len(data)
        if n:
            self._pending.append(bytes(data))
            self._pending_len += n
            if self._pending_len >= self.MAX_PENDING:
                self.flush()
        return n

    def tell(self) -> int:
        return self.on_disk + self._pending_len

    def flush(self) -> None:
        if self.failed is not None:
            raise self.failed
        assert self._fd is not None, "file is closed"
        # every piece is whole records (a chunk with its message indexes is one piece): the pieces written
        # whole are kept, the file is cut back to the end of the last one
        while self._pending:
            piece = self._pending[0]
            view = memoryview(piece)
            done = 0
            try:
                while done < len(piece):
                    n = os.write(self._fd, view[done:])
                    if n <= 0:
                        raise OSError(5, "write returned 0 bytes")
                    done += n
            except OSError as e:
                self.failed = e
                try:
                    os.ftruncate(self._fd, self.on_disk)
                except OSError:
                    pass  # the reader stops at the torn record anyway
                raise
            self._pending.popleft()
            self._pending_len -= len(piece)
            self.on_disk += len(piece)

    def rewrite(self, offset: int, data: bytes) -> None:
        """Write `data` at `offset`, over the file's last records (the open chunk's copy), and end the file there.

        If the OS refuses (disk full, EFBIG), the copy that was there is put back (its blocks are the file's
        already, so writing them again needs no new space) and the file ends after it: what was captured up to
        the last copy stays.  Only if that fails too is the file cut back to `offset`."""
        self.flush()
        assert self._fd is not None and offset <= self.on_disk, "rewrite past the end"
        previous = os.pread(self._fd, self.on_disk - offset, offset) if offset < self.on_disk else b""
        view = memoryview(data)
        done = 0
        try:
            os.lseek(self._fd, offset, os.SEEK_SET)
            while done < len(data):
                n = os.write(self._fd, view[done:])
                if n <= 0:
                    raise OSError(5, "write returned 0 bytes")
                done += n
            if offset + len(data) < self.on_disk:
                os.ftruncate(self._fd, offset + len(data))
        except OSError as e:
            self.failed = e
            self.on_disk = offset
            try:
                if previous and os.pwrite(self._fd, previous, offset) == len(previous):
                    self.on_disk = offset + len(previous)
                os.ftruncate(self._fd, self.on_disk)
            except OSError:
                try:
                    os.ftruncate(self._fd, offset)
                    self.on_disk = offset
                except OSError:
                    pass
            raise
        self.on_disk = offset + len(data)

    def close(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)


class McapSink(Sink):
    """Pipeline sink writing /capture, /raw and /frames to one MCAP file, and Foxglove's parts.

    Raises CaptureStorageError once, from whichever call first fails to
    write; after that every call is a no-op and close() only releases the
    file (whose complete records stay readable).  `clock` (monotonic ns)
    decides when to flush; tests pass a fake one.  `foxglove=False` writes
    the capture alone (what a benchmark sets beside it).

    `compact=True` (rotated segments, trigger windows: files a live capture writes all day) writes no
    /frames channel and batches /raw (sniffer.format 2: a message holds the events of up to a second,
    until the next flush): per message, a file carries 16 bytes of message index and about as many of
    record head, which with a message per event and per frame took more than the line's bytes three
    times over.  A replay decodes the frames again from /raw, exactly; Foxglove's parts are all there.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        flush_interval_s: float = 1.0,
        clock: Callable[[], int] = time.monotonic_ns,
        compress: bool = True,
        foxglove: bool = True,
        packing: tuple[int, int] = (0, 0),
        seal_interval_s: float = SEAL_S,
        compact: bool = False,
    ) -> None:
        self.compact = compact
        self._batch: list[bytes] = []  # compact: the /raw events not yet in a message
        self._batch_t = 0
        self.path = os.fspath(path)
        self._seal_ns = int(seal_interval_s * 1e9)
        self._last_seal = 0
        self._packing = packing  # how the chunks of the file before (a segment's) compressed
        self._interval_ns = int(flush_interval_s * 1e9) if flush_interval_s < 1e9 else 1 << 62  # inf: when full
        self._clock = clock
        self._compression = "zstd" if compress else ""
        self._writer: McapWriter | None = None
        self._t0 = 0
        self._anchor = 0
        self._seq: dict[int, int] = {}
        self._foxglove_on = foxglove
        self._fox: foxglove.Foxglove | None = None
        self._fox_channels: dict[str, int] = {}
        self._value_schema = 0
        self._maps: tuple = ((), None)  # the capture's --model-file maps, --map-base (decoders.mapfile)
        self._last_flush = 0
        self._closed = False
        self.error: CaptureStorageError | None = None
        try:
            self._file = _AppendFile(self.path)
        except OSError as e:
            raise CaptureStorageError(f"{self.path}: cannot create capture file: {e.strerror or e}") from None

    @property
    def flush_interval_s(self) -> float:
        """How much wall time may pass before the open chunk is written out (inf: only when it is full, so
        the file's chunks depend on its messages alone: an export)."""
        return self._interval_ns / 1e9

    @flush_interval_s.setter
    def flush_interval_s(self, seconds: float) -> None:
        self._interval_ns = int(seconds * 1e9) if seconds < 1e9 else 1 << 62

    @property
    def bytes_written(self) -> int:
        """Bytes on disk so far (the flushed, complete part of the file)."""
        return self._file.on_disk

    @property
    def packing(self) -> tuple[int, int]:
        """How its chunks compressed so far (McapWriter.packing): the next segment's estimates start there."""
        return self._writer.packing if self._writer is not None else self._packing

    @property
    def size(self) -> int:
        """Bytes of the file so far, written or waiting to be, of the open chunk (estimated: mcap_writer
        open_chunk_bytes) and of the summary it will end with (a Foxglove capture has a channel per
        register: the summary repeats them)."""
        w = self._writer
        if w is None:
            return self._file.tell()
        return self._file.tell() - w.copy_bytes + w.summary_bytes + w.open_chunk_bytes()

    @property
    def message_bytes(self) -> int:
        """Of `size`, the messages' own part: their chunks, written or open (estimated), without the
        records every file carries (schemas, channels, metadata, indexes, the summary)."""
        return self._writer.message_bytes() if self._writer is not None else 0

    def start(self, info: CaptureInfo) -> None:
        self._t0 = info.t0_ns
        self._anchor = info.wall_anchor_ns
        # chunks of at most CHUNK_SIZE: a damaged byte loses one chunk (`replay` and `repair` go on after it)
        level = LIVE_LEVEL if self._interval_ns < 1 << 62 else EXPORT_LEVEL
        w = McapWriter(self._file, compression=self._compression, chunk_size=CHUNK_SIZE, packing=self._packing,
                       level=level)
        self._writer = w
        try:
            w.start(profile="", library=f"sniffer/{__version__}")
            w.add_metadata(METADATA_NAME, info_to_metadata(info))
            meta = {"sniffer.format": RAW_FORMAT}
            ids = {}
            for topic, name, schema in CHANNELS:
                if self.compact and topic == FRAMES_TOPIC:
                    continue
                if self.compact and topic == RAW_TOPIC:
                    name, schema, meta = "sniffer.RawEvents", RAW_BATCH_SCHEMA, {"sniffer.format": RAW_BATCH_FORMAT}
                sid = w.register_schema(name, "jsonschema", msgspec.json.encode(schema))
                ids[topic] = w.register_channel(topic, "json", sid, meta)
            self._ch_capture, self._ch_raw, self._ch_frames = ids[CAPTURE_TOPIC], ids[RAW_TOPIC], ids.get(FRAMES_TOPIC)
            if self._foxglove_on:
                self._start_foxglove(info)
            self._add(self._ch_capture, info.t0_ns, msgspec.json.encode(info.to_dict()))
            self._flush_now()
        except OSError as e:
            raise self._fail(e) from None

    def raw(self, event: Chunk | Tick | Gap) -> None:
        if self._usable():
            if self.compact:
                self._batched(event.t_ns, encode_event(event))
            else:
                self._write(self._ch_raw, event.t_ns, encode_event(event))

    def frame(self, frame: Frame) -> None:
        if self._usable():
            if not self.compact:
                self._write(self._ch_frames, frame.t_ns, frame_json(frame, self._t0))
            if self._fox is not None:
                self._foxglove(self._fox.frame(frame, frame.t_ns), frame.t_ns)

    def encoded(self, kind: str, t_ns: int, data: bytes) -> None:
        """A /raw event or /frames record already encoded (`kind` "raw" or "frame"): a trigger's ring."""
        if self._usable():
            if kind == "raw":
                if self.compact:
                    self._batched(t_ns, data)
                else:
                    self._write(self._ch_raw, t_ns, data)
            else:
                if not self.compact:
                    self._write(self._ch_frames, t_ns, data)
                if self._fox is not None:
                    self._foxglove(self._fox.record(data, t_ns), t_ns)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record besides `sniffer.capture` (a trigger window's `sniffer.trigger`)."""
        if self._usable():
            try:
                self._writer.add_metadata(name, data)
            except OSError as e:
                raise self._fail(e) from None

    def maybe_flush(self) -> None:
        """Flush if flush_interval_s has passed: call it from the live loop when idle."""
        if self._usable() and self._clock() - self._last_flush >= self._interval_ns:
            try:
                self._flush_now(seal=False)
            except OSError as e:
                raise self._fail(e) from None

    def flush(self) -> None:
        """Finish (seal) the current chunk and hand it to the OS now."""
        if self._usable():
            try:
                self._flush_now()
            except OSError as e:
                raise self._fail(e) from None

    def close(self) -> None:
        """Finish the file (summary, footer) so any MCAP reader opens it.  Safe to call twice.

        Raises CaptureStorageError if finishing fails and no error was raised before.
        """
        if self._closed:
            return
        self._closed = True
        try:
            if self._writer is not None and self.error is None:
                try:
                    self._end_batch()
                    for topic, t_ns, data in self._fox.finish() if self._fox is not None else ():
                        self._add(self._fox_channels[topic], t_ns, data)  # each register's last sample
                    self._writer.finish()
                    self._file.flush()
                except OSError as e:
                    raise self._fail(e) from None
        finally:
            self._file.close()

    # -- internals -------------------------------------------------------------------

    def _start_foxglove(self, info: CaptureInfo) -> None:
        """The `foxglove` metadata, the /annotations channel and the value schema (sniffer.formats.mcap.foxglove)."""
        w = self._writer
        w.add_metadata(foxglove.METADATA_NAME, foxglove.metadata(info))
        sid = w.register_schema(foxglove.LOG_SCHEMA_NAME, "jsonschema", msgspec.json.encode(foxglove.LOG_SCHEMA))
        self._fox_channels[foxglove.LOG_TOPIC] = w.register_channel(foxglove.LOG_TOPIC, "json", sid)
        self._value_schema = w.register_schema(foxglove.VALUE_SCHEMA_NAME, "jsonschema",
                                               msgspec.json.encode(foxglove.VALUE_SCHEMA))
        self._fox = foxglove.Foxglove(info)
        self._maps = (tuple(info.extra.get("model_files") or ()), info.extra.get("map_base"))

    def _foxglove(self, messages: list, t_ns: int) -> None:
        """A frame's Foxglove messages, after the channels and attachments they are the first to need."""
        fox = self._fox
        try:
            if fox.new_models:
                self._attach(t_ns)
            if fox.new_topics:
                w = self._writer
                for topic in fox.new_topics:
                    self._fox_channels[topic] = w.register_channel(topic, "json", self._value_schema,
                                                                   fox.channel_meta[topic])
                fox.new_topics.clear()
        except OSError as e:
            raise self._fail(e) from None
        channels = self._fox_channels
        for topic, t_ns, data in messages:
            self._write(channels[topic], t_ns, data)

    def _attach(self, t_ns: int) -> None:
        """The register maps of the models first seen (decoders.mapfile)."""
        from decoders.mapfile import map_file

        log_time = max(0, self._anchor + (t_ns - self._t0))
        for model in self._fox.new_models:
            got = map_file(model, *self._maps, version=__version__)
            if got is not None:
                self._writer.add_attachment(got[0], got[1], got[2], log_time, log_time)
        self._fox.new_models.clear()

    def _usable(self) -> bool:
        if self.error is not None:
            return False  # already reported once: the capture goes on without the file
        if self._writer is None or self._closed:
            raise RuntimeError("McapSink used before start() or after close()")
        return True

    def _batched(self, t_ns: int, data: bytes) -> None:
        """A compact file's /raw event: into the open batch, which becomes a message at the next flush or once
        it spans BATCH_NS of capture time."""
        try:
            if self._batch and t_ns - self._batch_t >= BATCH_NS:
                self._end_batch()
            if not self._batch:
                self._batch_t = t_ns
            self._batch.append(data)
            if self._clock() - self._last_flush >= self._interval_ns:
                self._flush_now(seal=False)
        except OSError as e:
            raise self._fail(e) from None

    def _end_batch(self) -> None:
        if self._batch:
            batch, self._batch = self._batch, []
            self._add(self._ch_raw, self._batch_t, encode_batch(batch))

    def _write(self, channel: int, t_ns: int, data: bytes) -> None:
        try:
            self._add(channel, t_ns, data)
            if self._clock() - self._last_flush >= self._interval_ns:
                self._flush_now(seal=False)
        except OSError as e:
            raise self._fail(e) from None

    def _add(self, channel: int, t_ns: int, data: bytes) -> None:
        log_time = max(0, self._anchor + (t_ns - self._t0))
        seq = self._seq.get(channel, 0)
        self._seq[channel] = (seq + 1) & 0xFFFFFFFF
        self._writer.add_message(channel, log_time, data, log_time, seq)

    def _flush_now(self, seal: bool = True) -> None:
        """The open chunk and its message indexes to the OS in one write; sealed when asked, or once it has
        been open SEAL_S (seal=False: a copy, written over by the next flush)."""
        now = self._clock()
        seal = seal or now - self._last_seal >= self._seal_ns
        self._end_batch()
        self._writer.flush(seal=seal)
        self._file.flush()
        self._last_flush = now
        if seal:
            self._last_seal = now

    def _fail(self, e: OSError) -> CaptureStorageError:
        what = e.strerror or str(e)
        self.error = CaptureStorageError(
            f"{self.path}: cannot write capture ({what}); stopped with {self._file.on_disk} bytes on disk"
        )
        self.error.reason = what
        return self.error


def open_sink(fmt: str, path: str, parts: list[str]) -> McapSink:
    """The Mcap sink writing its part files (named in the table of sniffer.formats)."""
    return McapSink(parts[0])
