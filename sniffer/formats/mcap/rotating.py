"""A capture written as rotating MCAP segments in one folder (--rotate, --keep): see sniffer.formats.mcap.segments.

    plan = SegmentPlan("cab3", Rotate(span_ns=3600 * 10**9), Keep(age_ns=7 * 86400 * 10**9))  # checks, locks
    sink = plan.open()       # a Sink; the session asks it to rotate between events (`rotate_due`, `rotate_if`)

Each segment is an McapSink of its own (the capture's metadata, its own
summary and index), written as `NAME.part` and renamed when closed, so a kill
at any moment leaves every closed segment complete and the open one a part
file that `replay` reads and `repair` finishes.  The session closes a
segment between events when the pipeline holds nothing (no bytes in the
framer, no request waiting for its answer), so each segment replays alone to
the frames the capture had; on a line that is never quiet it waits at most
FORCE_AFTER_NS of capture time.  After each segment closes the index is
rewritten and --keep applied: the oldest closed segments go first, never the
open one.  One capture writes a folder at a time (a lock file says which).
Each segment's metadata holds what the decoders knew when it opened
(`decoder_state`, decoders/carry.py; the session binds `decoder_state` to its
pipeline's), so a segment replayed alone scales and names its values as the
capture did.
"""

from __future__ import annotations

import os
import shutil
import uuid

from decoders.carry import record

from sniffer.events import WAITING_KEY, CaptureInfo, Gap
from sniffer.frame import Frame
from sniffer.formats.outputs import Output, OutputError, lock_file, make_folders, shown
from sniffer.formats.mcap.segments import (
    INDEX_NAME, LOCK_NAME, STATUS_NAME, Keep, Rotate, Segment, folder_for, limits, read_index, segment_name,
    write_index,
)
from sniffer.sinks.base import Sink
from sniffer.formats.mcap.sink import CaptureStorageError, McapSink

_KNOWN_PACKING = 64 * 1024  # message bytes compressed so far before their ratio is trusted (not /capture's alone)
MESSAGES_AT_LEAST = 4  # a segment closed for its size holds at least 1/4 of it in messages
FORCE_AFTER_NS = (1_000_000_000, 5_000_000_000)  # overdue this long: a request may wait; then: cut anywhere


def _take_lock(folder: str) -> int:
    path = os.path.join(folder, LOCK_NAME)
    fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
    try:
        taken = lock_file(fd)
    except OSError:
        os.close(fd)
        raise
    if not taken:
        try:
            other = os.pread(fd, 32, 0).decode(errors="replace").strip()
        finally:
            os.close(fd)
        raise OutputError(f"{shown(folder)}: another capture writes there (pid {other or '?'})")
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    return fd


def _free(folder: str) -> int | None:
    """Bytes free on the folder's file system (None if it cannot be told)."""
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return None


class SegmentPlan:
    """The capture's folder, checked (and created, and locked) now, before the source opens."""

    outputs: tuple = ()  # segments are renamed into place as they close, not by the session

    def __init__(self, out: str, rotate: Rotate, keep: Keep | None = None, *, inputs=(),
                 timed_flush: bool = True) -> None:
        self.folder = folder_for(out)
        self.rotate, self.keep = rotate, keep
        # a capture's segments are flushed every second of wall time (what a kill loses); segments made from a
        # file (replay, simulate) as their writer fills them, so their chunks, sizes and the size rotations and
        # retention that follow depend on the messages alone, not on how loaded the machine was
        self.flush_interval_s = 1.0 if timed_flush else float("inf")
        f = shown(self.folder)
        parent = os.path.dirname(os.path.abspath(self.folder))
        if os.path.exists(self.folder) and not os.path.isdir(self.folder):
            raise OutputError(f"{f}: exists and is not a folder (with --rotate, --out names the capture's folder)")
        if not os.path.isdir(parent):
            raise OutputError(f"{f}: folder {shown(parent)} does not exist")
        for src in inputs:
            if src and os.path.abspath(os.path.dirname(os.fspath(src)) or ".") == os.path.abspath(self.folder):
                raise OutputError(f"{f}: holds an input of this command; write the segments to another folder")
        try:
            make_folders(self.folder)
            self.lock_fd = _take_lock(self.folder)
        except OutputError:
            raise
        except OSError as e:
            raise OutputError(f"{f}: cannot write there: {e.strerror or e}") from None
        self.sink: SegmentSink | None = None

    def open(self) -> SegmentSink:
        self.sink = SegmentSink(self.folder, self.rotate, self.keep, lock_fd=self.lock_fd,
                                flush_interval_s=self.flush_interval_s)
        return self.sink


class SegmentSink(Sink):
    """Writes the capture as segments; `rotate_due` / `rotate_if(settled)` are driven by the session."""

    def __init__(self, folder: str, rotate: Rotate, keep: Keep | None = None, *, lock_fd: int | None = None,
                 flush_interval_s: float = 1.0) -> None:
        self.folder = folder
        self.prefix = os.path.basename(os.path.abspath(folder)) or "capture"
        self.rotate, self.keep = rotate, keep
        self.lock_fd = lock_fd
        self.flush_interval_s = flush_interval_s
        self.segments: list[Segment] = []  # closed (and killed) ones, oldest first, then the open one
        self.deleted = 0
        self.written = 0  # bytes of the segments this capture closed (deleted ones too): with the open one, its rate
        self.delete_errors: list[str] = []
        self.kept_parts: list[str] = []  # segments cut short (a full disk), left as their part files
        self.rotate_due = False
        self._packing = (0, 0)  # how the segments so far compressed (McapSink.packing)
        self._info: CaptureInfo | None = None
        self._cur: McapSink | None = None
        self._out: Output | None = None
        self._seg: Segment | None = None
        self._due_t = 0
        self._t_last = 0
        self._boundary = 0
        self._first_seq = 1
        self._closed = False
        self.decoder_state = None  # the session binds its pipeline's (Pipeline.decoder_state)
        self.waiting = None  # ... and the requests waiting for their answers (Pipeline.waiting)

    # ------------------------------------------------------------ the sink
    def start(self, info: CaptureInfo) -> None:
        self._info = info
        info.extra.setdefault("capture_id", uuid.uuid4().hex[:12])
        self.segments = read_index(self.folder)
        for name in os.listdir(self.folder):  # a capture killed while it rewrote the index or the status
            if name.startswith((INDEX_NAME + ".tmp", STATUS_NAME + ".tmp")):
                try:
                    os.remove(os.path.join(self.folder, name))
                except OSError:
                    pass
        for s in self.segments:
            if s.state == "open":
                s.state = "killed"  # the lock is ours: whoever wrote it is gone
        self._t_last = info.t0_ns
        self._first_seq = max((s.seq for s in self.segments), default=0) + 1
        self._open_segment(info.t0_ns)

    def raw(self, event) -> None:
        t = event.t_end_ns if type(event) is Gap else event.t_ns
        if self._cur is None:  # the next segment opens with the first event after a rotation, where the last ended
            self._open_segment(self._t_last)
        self._cur.raw(event)
        if t > self._t_last:
            self._t_last = t
        if not self.rotate_due and ((self.rotate.span_ns and t >= self._boundary) or self._full()):
            self.rotate_due, self._due_t = True, t

    def _full(self) -> bool:
        """The open segment holds --rotate's size, a quarter of it at least in messages: a capture whose
        channels and index alone take most of that size (thousands of registers) gets larger segments,
        never one per event."""
        size = self.rotate.max_bytes
        cur = self._cur
        if not size or cur.size < size:
            return False
        if cur.packing[0] < _KNOWN_PACKING:
            cur.flush()  # the capture's first chunk: written now, how its messages compress is known
        return cur.message_bytes >= size // MESSAGES_AT_LEAST

    def frame(self, frame: Frame) -> None:
        if self._cur is None:
            self._open_segment(self._t_last)
        self._cur.frame(frame)
        self._seg.frames += 1

    def bind(self, pipeline) -> None:
        self.decoder_state = pipeline.decoder_state
        self.waiting = pipeline.waiting

    def maybe_flush(self) -> None:
        if self._cur is not None:
            self._cur.maybe_flush()

    def rotate_if(self, settled: int) -> None:
        """Between events, once due: close the segment if the pipeline is settled enough (see FORCE_AFTER_NS).

        `settled`: 2 nothing pending, 1 a request waits for its answer, 0 bytes wait in the framer."""
        overdue = self._t_last - self._due_t
        if settled == 2 or (settled == 1 and overdue >= FORCE_AFTER_NS[0]) or overdue >= FORCE_AFTER_NS[1]:
            self._close_segment()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            if self._cur is not None:
                self._close_segment()
            else:
                self._apply_keep()
                self._write_index()
        finally:
            if self.lock_fd is not None:
                os.close(self.lock_fd)
                self.lock_fd = None

    def status(self) -> dict:
        """The `segments` section of the capture's status file (`written` and `limits`: sniffer.commands.status
        works out from them how much capture time --keep holds at the rate the segments grow)."""
        writing = self._cur is not None
        closed = [s for s in self.segments if not (writing and s is self._seg)]
        open_bytes = self._cur.size if writing else 0
        return {"segments": {
            "folder": os.path.abspath(self.folder), "count": len(self.segments),
            "closed": sum(s.state == "closed" for s in closed), "killed": sum(s.state == "killed" for s in closed),
            "open": self._seg.file if writing else None,
            "bytes": sum(s.bytes for s in closed) + open_bytes, "disk_free": _free(self.folder),
            "deleted": self.deleted,
            "rotate": self.rotate.describe(), "keep": self.keep.describe() if self.keep else None,
            "written": self.written + open_bytes,  # by this capture: `sniffer status` works out what --keep holds
            "limits": limits(self.rotate, self.keep),
            **({"delete_errors": self.delete_errors[-3:]} if self.delete_errors else {}),
        }}

    # ------------------------------------------------------------ segments
    def _wall(self, t_ns: int) -> int:
        return self._info.wall_anchor_ns + (t_ns - self._info.t0_ns)

    def _open_segment(self, t_ns: int) -> None:
        info = self._info
        seq = max((s.seq for s in self.segments), default=0) + 1
        name = segment_name(self.prefix, self._wall(t_ns), seq)
        self._out = Output(os.path.join(self.folder, name), what="segment")
        self._out.claim()
        seg_info = CaptureInfo.from_dict(info.to_dict())
        seg_info.extra = {**info.extra, "segment": seq, "segment_t_ns": t_ns}
        if self.decoder_state is not None:
            record(seg_info, self.decoder_state())
        seg_info.extra.pop(WAITING_KEY, None)
        waiting = self.waiting() if self.waiting is not None else None
        if waiting:  # cut while a request waited (busy links are seldom all quiet): read alone, it pairs its answer
            seg_info.extra[WAITING_KEY] = waiting
        self._cur = McapSink(self._out.part, flush_interval_s=self.flush_interval_s, packing=self._packing,
                             compact=True)
        self._cur.start(seg_info)
        span = self.rotate.span_ns
        if span:  # on the clock: 1h segments change on the hour
            wall = self._wall(t_ns)
            self._boundary = t_ns + (span - wall % span if wall % span else span)
        self._seg = Segment(name, seq, info.extra["capture_id"], self._wall(t_ns), self._wall(t_ns),
                            (t_ns - info.t0_ns) / 1e9, (t_ns - info.t0_ns) / 1e9, state="open")
        self.segments.append(self._seg)
        self.rotate_due = False
        self._apply_keep()
        self._write_index()

    def _close_segment(self) -> None:
        cur, seg, out = self._cur, self._seg, self._out
        self._cur = None
        self.rotate_due = False
        try:
            cur.close()
        finally:
            self._packing = cur.packing
            seg.end_ns = self._wall(self._t_last)
            seg.t_end = (self._t_last - self._info.t0_ns) / 1e9
            if cur.error is not None:  # cut short (a full disk): left as its part file, never under its name
                if out.keep_part():
                    seg.state = "killed"
                    seg.extra["part"] = os.path.basename(out.part)
                    self.kept_parts.append(out.part)
                else:
                    self.segments.remove(seg)
            elif self._closed and seg.frames == 0 and seg.seq > self._first_seq:
                out.discard()  # the capture ended just after a rotation (silence)
                self.segments.remove(seg)
            else:
                out.commit()
                seg.state = "closed"
            try:
                seg.bytes = os.path.getsize(out.path if seg.state == "closed" else out.part) \
                    if seg in self.segments else 0
            except OSError:
                seg.bytes = 0
            self.written += seg.bytes
            self._apply_keep()
            self._write_index()

    def _apply_keep(self) -> None:
        if self.keep is None:
            return
        writing = self._cur is not None
        closed = [s for s in self.segments if not (writing and s is self._seg)]
        gone = self.keep.to_delete(closed, self._wall(self._t_last), self._cur.size if writing else 0, int(writing))
        for s in gone:
            path = os.path.join(self.folder, s.extra.get("part") or s.file)
            try:
                os.remove(path)
            except FileNotFoundError:
                pass
            except OSError as e:
                self.delete_errors.append(f"{s.file}: {e.strerror or e}")
                continue
            self.segments.remove(s)
            self.deleted += 1

    def _write_index(self) -> None:
        try:
            write_index(self.folder, self.segments)
        except OSError as e:
            raise CaptureStorageError(f"{self.folder}: cannot write the index ({e.strerror or e})") from None

    @property
    def written_text(self) -> str:
        """'3 segments in cab3 (123456 bytes)' for the end-of-run line."""
        n = sum(1 for s in self.segments if s.state == "closed")
        total = sum(s.bytes for s in self.segments)
        return f"{n} segments in {self.folder} ({total} bytes)"
