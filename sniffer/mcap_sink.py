"""MCAP sink: a capture file that replays exactly and opens in Foxglove.

Channels (JSON messages described by JSON Schema, so Foxglove can plot fields):

* ``/capture`` -- one message, the first in the file: the CaptureInfo (line
  settings, t0, wall anchor, low-latency state, device map).  The same dict is
  MCAP metadata ``sniffer.capture``.  Both are on disk right after start(),
  which flushes at once, so even a file cut a second after start still knows
  its baud, parity and t0 (the metadata index in the summary would be lost).
* ``/raw`` -- one message per source event (Chunk / Tick / Gap): the replay
  input, enough to re-frame and re-decode with other settings.  See
  `encode_event`.
* ``/frames`` -- one message per decoded frame: the JSONL record of
  sniffer.records (schema FRAME_SCHEMA).

log_time = publish_time = wall_anchor_ns + (t_ns - t0_ns), clamped to >= 0.

Durability.  mcap's Writer collects messages in a chunk in memory.  Every
`flush_interval_s` of *wall* time (the sink's monotonic clock, checked on each
raw()/frame() call and on `maybe_flush()`) the chunk is finished and written
to the OS, so a SIGKILL loses at most that much.  Wall time, not event time:
the bound is about how much a crash loses, and a fast file conversion would
otherwise write thousands of tiny chunks per second.  No fsync: the page cache
survives a killed process; power loss is not covered.

Full disk.  Bytes reach the file only through `_AppendFile`, which writes
whole records and, when the OS refuses a write (ENOSPC, EFBIG, EIO), cuts the
file back to the last whole record and never writes again.  The file on disk
is then a clean prefix that `sniffer.sources.mcapsrc` reads and
`sniffer.mcap_repair` finishes.
"""

from __future__ import annotations

import os
import time
from collections import deque
from collections.abc import Callable

import orjson
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

from . import __version__
from .events import CaptureInfo, Chunk, Gap, Tick
from .frame import Frame
from .records import FRAME_SCHEMA, frame_json

CAPTURE_TOPIC = "/capture"
RAW_TOPIC = "/raw"
FRAMES_TOPIC = "/frames"
METADATA_NAME = "sniffer.capture"
RAW_FORMAT = "1"  # channel metadata "sniffer.format": bump when /raw changes incompatibly

RAW_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sniffer.RawEvent",
    "description": "One source event: bytes read, a silence tick, or a gap in the capture",
    "type": "object",
    "properties": {
        "kind": {"type": "string", "enum": ["chunk", "tick", "gap"]},
        "t_ns": {
            "type": "integer",
            "description": "capture monotonic clock, ns (chunk: first byte if per-byte, else when the read returned)",
        },
        "data": {"type": "string", "description": "chunk bytes, hex"},
        "byte_dt_ns": {
            "type": ["array", "null"],
            "items": {"type": "integer"},
            "description": "start time of each byte as an offset from t_ns; null: one time per read",
        },
        "flags": {
            "type": "array",
            "description": "[byte offset, 'framing'|'parity'] UART errors",
            "items": {"type": "array", "prefixItems": [{"type": "integer"}, {"type": "string"}]},
        },
        "channel": {"type": "string"},
        "t_end_ns": {"type": "integer", "description": "gap: end of the interruption"},
        "reason": {"type": "string", "description": "gap: why the source was interrupted"},
    },
    "required": ["kind", "t_ns"],
}

CAPTURE_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sniffer.CaptureInfo",
    "description": "How the capture was taken: serial settings, clocks, devices",
    "type": "object",
    "properties": {
        "source": {"type": "string"},
        "port": {"type": "string"},
        "baud": {"type": ["integer", "null"]},
        "parity": {"type": ["string", "null"]},
        "stopbits": {"type": ["integer", "null"]},
        "databits": {"type": "integer"},
        "time_source": {"type": "string", "enum": ["byte", "read"]},
        "t0_ns": {"type": "integer"},
        "wall_anchor_ns": {"type": "integer"},
        "low_latency": {"type": "object"},
        "devices": {"type": "object"},
        "protocol": {"type": "string"},
        "sniffer_version": {"type": "string"},
        "extra": {"type": "object"},
    },
}


class CaptureStorageError(Exception):
    """The capture file cannot be written (disk full, file too large, I/O error): one line."""


def encode_event(ev: Chunk | Tick | Gap) -> bytes:
    """The /raw message of one event (exactly invertible by `decode_event`)."""
    if type(ev) is Chunk:
        t = ev.t_ns
        return orjson.dumps({
            "kind": "chunk",
            "t_ns": t,
            "data": ev.data.hex(),
            "byte_dt_ns": None if ev.byte_t_ns is None else [b - t for b in ev.byte_t_ns],
            "flags": [[i, f] for i, f in ev.flags],
            "channel": ev.channel,
        })
    if type(ev) is Tick:
        return orjson.dumps({"kind": "tick", "t_ns": ev.t_ns})
    if type(ev) is Gap:
        return orjson.dumps({"kind": "gap", "t_ns": ev.t_ns, "t_end_ns": ev.t_end_ns, "reason": ev.reason})
    raise TypeError(f"not a source event: {ev!r}")


def decode_event(data: bytes) -> Chunk | Tick | Gap | None:
    """Event from a /raw message; None for a kind this version does not know.

    Raises ValueError (or KeyError/TypeError) on a malformed message.
    """
    d = orjson.loads(data)
    kind = d["kind"]
    t = int(d["t_ns"])
    if kind == "chunk":
        raw = bytes.fromhex(d["data"])
        dt = d.get("byte_dt_ns")
        byte_t = None if dt is None else tuple(t + int(x) for x in dt)
        if byte_t is not None and len(byte_t) != len(raw):
            raise ValueError("byte_dt_ns and data differ in length")
        flags = tuple((int(i), str(f)) for i, f in d.get("flags") or ())
        return Chunk(t, raw, byte_t, flags, str(d.get("channel") or ""))
    if kind == "tick":
        return Tick(t)
    if kind == "gap":
        return Gap(t, int(d["t_end_ns"]), str(d["reason"]))
    return None


def info_to_metadata(info: CaptureInfo) -> dict[str, str]:
    """MCAP metadata is a string map: each CaptureInfo field, JSON-encoded."""
    return {k: orjson.dumps(v).decode() for k, v in info.to_dict().items()}


def info_from_metadata(meta: dict[str, str]) -> CaptureInfo:
    return CaptureInfo.from_dict({k: orjson.loads(v) for k, v in meta.items()})


class _AppendFile:
    """The mcap Writer's output stream: never leaves a torn record behind.

    mcap's Writer hands each write() whole records, so the end of every
    write() is a record boundary.  Pieces wait here until flush(), which
    writes them with os.write.  If the OS refuses (disk full, EFBIG), the file
    is cut back to the end of the last whole piece (ftruncate needs no space)
    and nothing is written again.  A BufferedWriter gives no such promise:
    after a failed flush it may keep part of its buffer and write it later,
    after a gap, which would corrupt the file instead of shortening it.
    """

    MAX_PENDING = 8 << 20  # write out early if a flush is long overdue

    def __init__(self, path: str) -> None:
        flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_BINARY", 0) | getattr(os, "O_CLOEXEC", 0)
        self._fd: int | None = os.open(path, flags, 0o666)
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

    def close(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)


class McapSink:
    """Pipeline sink writing /capture, /raw and /frames to one MCAP file.

    Raises CaptureStorageError once, from whichever call first fails to
    write; after that every call is a no-op and close() only releases the
    file (whose complete records stay readable).  `clock` (monotonic ns)
    decides when to flush; tests pass a fake one.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        flush_interval_s: float = 1.0,
        clock: Callable[[], int] = time.monotonic_ns,
        compress: bool = True,
    ) -> None:
        self.path = os.fspath(path)
        self._interval_ns = int(flush_interval_s * 1e9)
        self._clock = clock
        self._compression = CompressionType.ZSTD if compress else CompressionType.NONE
        self._writer: Writer | None = None
        self._t0 = 0
        self._anchor = 0
        self._seq: dict[int, int] = {}
        self._last_flush = 0
        self._closed = False
        self.error: CaptureStorageError | None = None
        try:
            self._file = _AppendFile(self.path)
        except OSError as e:
            raise CaptureStorageError(f"{self.path}: cannot create capture file: {e.strerror or e}") from None

    @property
    def bytes_written(self) -> int:
        """Bytes on disk so far (the flushed, complete part of the file)."""
        return self._file.on_disk

    def start(self, info: CaptureInfo) -> None:
        self._t0 = info.t0_ns
        self._anchor = info.wall_anchor_ns
        w = Writer(self._file, compression=self._compression)  # type: ignore[arg-type]
        self._writer = w
        try:
            w.start(profile="", library=f"sniffer/{__version__}; {LIBRARY_IDENTIFIER}")
            w.add_metadata(METADATA_NAME, info_to_metadata(info))
            meta = {"sniffer.format": RAW_FORMAT}
            ids = {}
            for topic, name, schema in (
                (CAPTURE_TOPIC, "sniffer.CaptureInfo", CAPTURE_SCHEMA),
                (RAW_TOPIC, "sniffer.RawEvent", RAW_SCHEMA),
                (FRAMES_TOPIC, "sniffer.Frame", FRAME_SCHEMA),
            ):
                sid = w.register_schema(name, "jsonschema", orjson.dumps(schema))
                ids[topic] = w.register_channel(topic, "json", sid, meta)
            self._ch_capture, self._ch_raw, self._ch_frames = ids[CAPTURE_TOPIC], ids[RAW_TOPIC], ids[FRAMES_TOPIC]
            self._add(self._ch_capture, info.t0_ns, orjson.dumps(info.to_dict()))
            self._flush_now()
        except OSError as e:
            raise self._fail(e) from None

    def raw(self, event: Chunk | Tick | Gap) -> None:
        if self._usable():
            self._write(self._ch_raw, event.t_ns, encode_event(event))

    def frame(self, frame: Frame) -> None:
        if self._usable():
            self._write(self._ch_frames, frame.t_ns, frame_json(frame, self._t0))

    def maybe_flush(self) -> None:
        """Flush if flush_interval_s has passed: call it from the live loop when idle."""
        if self._usable() and self._clock() - self._last_flush >= self._interval_ns:
            self.flush()

    def flush(self) -> None:
        """Finish the current chunk and hand it to the OS now."""
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
                    self._writer.finish()
                    self._file.flush()
                except OSError as e:
                    raise self._fail(e) from None
        finally:
            self._file.close()

    # -- internals -------------------------------------------------------------------

    def _usable(self) -> bool:
        if self.error is not None:
            return False  # already reported once: the capture goes on without the file
        if self._writer is None or self._closed:
            raise RuntimeError("McapSink used before start() or after close()")
        return True

    def _write(self, channel: int, t_ns: int, data: bytes) -> None:
        try:
            self._add(channel, t_ns, data)
            if self._clock() - self._last_flush >= self._interval_ns:
                self._flush_now()
        except OSError as e:
            raise self._fail(e) from None

    def _add(self, channel: int, t_ns: int, data: bytes) -> None:
        log_time = max(0, self._anchor + (t_ns - self._t0))
        seq = self._seq.get(channel, 0)
        self._seq[channel] = (seq + 1) & 0xFFFFFFFF
        assert self._writer is not None
        self._writer.add_message(channel, log_time, data, log_time, seq)

    def _flush_now(self) -> None:
        w = self._writer
        assert w is not None
        flush = getattr(w, "flush", None)
        if flush is not None:
            flush()  # mcap >= 1.3: finishes the chunk, writes, flushes the stream
        else:
            # Older mcap has no public flush: finish the chunk through the
            # name-mangled private method (the same one finish() uses).
            w._Writer__finalize_chunk()  # type: ignore[attr-defined]
            self._file.flush()
        self._last_flush = self._clock()

    def _fail(self, e: OSError) -> CaptureStorageError:
        what = e.strerror or str(e)
        self.error = CaptureStorageError(
            f"{self.path}: cannot write capture ({what}); stopped with {self._file.on_disk} bytes on disk"
        )
        return self.error
